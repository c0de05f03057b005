// Triangles from the polygon faces of OBJ, OFF and PLY files.
//
// A polygon is triangulated in a projection onto the coordinate plane its Newell normal (the best-fit
// plane's normal) points at most along; dropping a coordinate leaves the stored floats unchanged, so every
// orientation test below is exact on the file's own numbers. Then:
//   - convex (every turn the same way, the fan from the first vertex without zero-area triangles): the fan
//     from the first vertex, exactly as written;
//   - simple but not convex (reflex turns, collinear or repeated vertices): ear clipping below
//     `large_polygon` vertices, CGAL's constrained Delaunay triangulation from there on (polygon_cdt.h: the
//     same exact predicates in O(n log n), where ear clipping's O(n^2) would let one face of a million
//     vertices take minutes); either gives triangles that cover the polygon and nothing else, none of zero
//     area. Repeated consecutive vertices
//     (by index or by position) are dropped first, so such a polygon gives fewer than n - 2 triangles.
//     A polygon that touches itself only at vertices (a ring cut open along a bridge edge to its hole) is
//     ear-clipped as well;
//   - not simple (its projection crosses or overlaps itself, as a bow-tie or a non-planar polygon seen
//     edge-on does, or winds round twice): the fan, as written, and counted;
//   - degenerate (all vertices on one line or one point, no area at all): the fan, as written, and counted.
// Every triangle keeps the polygon's winding.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "scene.h"

namespace cb {

enum class PolygonShape : uint8_t { triangle, convex, concave, not_simple, degenerate };

// The vertex count from which a polygon that is not convex is triangulated in O(n log n). Below it ear
// clipping costs no more and keeps the triangles it has always given.
constexpr size_t large_polygon = 128;

// Holds the scratch space one polygon needs, so a loader's many polygons allocate once, and counts the
// polygons (faces of 4 or more vertices) by shape.
class PolygonTriangulator {
public:
    // `large` replaces large_polygon (tests run the O(n log n) path on small polygons with it).
    explicit PolygonTriangulator(size_t large = large_polygon) : large_(large) {}

    // Appends the triangles of the polygon `poly[0..n)` (indices into `xyz`, 3 floats per vertex, every one
    // in range) to `out`. n < 3 appends nothing.
    PolygonShape add(const float* xyz, const uint32_t* poly, size_t n, std::vector<uint32_t>& out) {
        if (n == 3) {
            out.push_back(poly[0]);
            out.push_back(poly[1]);
            out.push_back(poly[2]);
            return PolygonShape::triangle;
        }
        if (n < 3) return PolygonShape::degenerate;
        PolygonShape shape = add_polygon(xyz, poly, n, out);
        ++counts_.total;
        counts_.concave += shape == PolygonShape::concave;
        counts_.not_simple += shape == PolygonShape::not_simple;
        counts_.degenerate += shape == PolygonShape::degenerate;
        return shape;
    }

    const PolygonCounts& counts() const { return counts_; }

private:
    PolygonShape add_polygon(const float* xyz, const uint32_t* poly, size_t n, std::vector<uint32_t>& out);

    // The steps of add_polygon, in its order; each reads what the ones before it left in the members.
    bool make_ring(const float* xyz, const uint32_t* poly, size_t n);  // false: fewer than 3 distinct vertices
    void project(const float* xyz);                                    // the ring onto its plane, into uv_
    void find_turns(size_t& left, size_t& right);                      // turn_, and the count of each way
    bool is_convex(size_t n, size_t left, size_t right) const;
    bool has_spike() const;
    bool crosses_itself(bool& touching);  // also says whether it touches itself at vertices
    PolygonShape add_large(const uint32_t* poly, size_t n, std::vector<uint32_t>& out);
    int ring_winding() const;  // +1 or -1 from the lowest vertex's turn, 0 when its passes disagree
    bool clip_ears(int winding, bool touching, std::vector<uint32_t>& out);
    bool is_ear(uint32_t a, uint32_t b, uint32_t c, int winding, bool touching);
    bool any_overlap(size_t from, const std::vector<uint32_t>& tris, int winding) const;

    // The ring's projected vertex i, and the ring positions before and after i.
    const double* uv(size_t i) const { return &uv_[2 * i]; }
    size_t before(size_t i) const { return i == 0 ? ring_.size() - 1 : i - 1; }
    size_t after(size_t i) const { return i + 1 == ring_.size() ? 0 : i + 1; }
    bool straight_on(size_t i) const;

    size_t large_;
    PolygonCounts counts_;
    std::vector<uint32_t> ring_;  // the polygon without repeated consecutive vertices
    std::vector<double> uv_;      // its projection, 2 per vertex
    std::vector<int> turn_;       // orientation sign at each vertex
    std::vector<uint32_t> prev_, next_;
    std::vector<uint32_t> order_;  // edges by least u, then the vertices an ear test looks at
};

// One polygon, without counting: the shape it was found to have.
PolygonShape triangulate_polygon(const float* xyz, const uint32_t* poly, size_t n, std::vector<uint32_t>& out,
                                 size_t large = large_polygon);

}  // namespace cb
