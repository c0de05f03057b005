// The triangulation of large simple polygons in O(n log n), behind polygon_triangulate.h: CGAL's constrained
// Delaunay triangulation of the polygon's projected vertices with its edges as constraints, whose
// predicates are exact. Internal to io/.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace cb {

// Appends the triangles of the polygon whose vertex i is `ring[i]` at the projected point (uv[2i],
// uv[2i+1]), i < m, to `out`, each with the polygon's `winding` (+1 counterclockwise in the projection, -1
// clockwise). The polygon must have no spikes and no zero-length edges; it may touch itself at vertices
// (an edge walked there and back, a vertex visited twice). Every triangle has non-zero area and together
// they cover the polygon exactly once. False, with `out` unchanged, when the polygon is not simple after
// all: edges cross or overlap, a vertex lies inside an edge, or some region is wound round twice.
bool triangulate_constrained(const double* uv, const uint32_t* ring, size_t m, int winding, std::vector<uint32_t>& out);

}  // namespace cb
