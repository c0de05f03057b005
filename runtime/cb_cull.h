// Cluster culling for a camera: the fine clusters whose box meets the view frustum, coarse clusters first,
// and (optionally) not those the eye sees only from the back. Conservative: a cluster with any triangle
// the camera could see is always listed. Header-only C++17, no exceptions, no allocation. MIT licensed.
#pragma once

#include <cmath>
#include <cstdint>

#include "cb_asset.h"
#include "cb_shadow.h"
#include "detail/cb_simd.h"

namespace cb {
inline namespace CB_LANES {

// Convex view volume in world space: a point p is inside when dot(plane[k].xyz, p) + plane[k].w >= 0 for
// every k < count (the usual 6 planes; any convex set of up to 8 works). `eye` is the camera position.
struct Frustum {
    double plane[8][4];
    int count = 0;
    double eye[3] = {0, 0, 0};
};

struct VisibleCluster {
    uint32_t instance;
    uint32_t fine;  // index into the asset's fine clusters (the mesh's first_fine + local index)
};

struct CullStats {
    uint64_t coarse_culled = 0, fine_tested = 0, frustum_culled = 0, backface_culled = 0;
};

namespace cull_detail {

// False only when the box is certainly outside the plane (padded halves cover the axes' rounding, see
// cb_asset.h; a margin covers the rounding of these sums).
inline bool box_touches_plane_side(const Obb& b, const double* n, double d) {
    double centre = n[0] * b.center[0] + n[1] * b.center[1] + n[2] * b.center[2] + d, reach = 0, scale = std::fabs(d);
    double half[3];
    padded_halves(b, half);
    for (int i = 0; i < 3; ++i) {
        reach += half[i] * std::fabs(n[0] * b.axis[i][0] + n[1] * b.axis[i][1] + n[2] * b.axis[i][2]);
        scale += std::fabs(n[i] * b.center[i]);
    }
    return centre >= -reach - 1e-9 * (scale + reach);
}

inline bool box_in_frustum(const Obb& b, const double (*planes)[4], int count) {
    for (int k = 0; k < count; ++k)
        if (!box_touches_plane_side(b, planes[k], planes[k][3])) return false;
    return true;
}

// The eye sees every triangle with an area from the back when it is clearly inside the back cone.
inline bool eye_in_back_cone(const Cone& c, const double* eye) {
    if (!c.valid) return false;
    double v[3] = {c.back_apex[0] - eye[0], c.back_apex[1] - eye[1], c.back_apex[2] - eye[2]};
    double a[3] = {c.axis[0], c.axis[1], c.axis[2]};
    double vl = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]),
           al = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    if (!(vl > 0) || !(al > 0)) return false;
    return v[0] * a[0] + v[1] * a[1] + v[2] * a[2] > al * vl * (double(c.cos_half_angle) + 1e-9);
}

inline bool any_double_sided(const AssetView& v, const MeshRecord& m, uint32_t first, uint32_t count) {
    for (uint32_t t = first; t < first + count; ++t)
        if (v.double_sided(size_t(m.first_triangle) + t)) return true;
    return false;
}

}  // namespace cull_detail

// One instance's part of cull_clusters: the visible fine clusters of mesh `at.mesh` of `v` placed by
// `at.transform`, written from out[count] as {id, fine} (while below `capacity`); returns count plus how
// many there are.
inline size_t cull_instance(const AssetView& v, Placement at, uint32_t id, const Frustum& f, bool backface,
                            VisibleCluster* out, size_t capacity, size_t count, CullStats* stats = nullptr) {
    if (!v.fine_bounds.obbs) return count;
    const MeshRecord& mesh = v.meshes[at.mesh];
    const double* m = at.transform;
    double inv[12], eye[3], planes[8][4];
    if (!invert_instance(m, inv)) return count;
    apply_instance(inv, f.eye, eye);
    // A world plane n.p + d >= 0 with p = M l + t becomes (M^T n).l + (n.t + d) >= 0 in the mesh frame.
    for (int k = 0; k < f.count; ++k) {
        const double* n = f.plane[k];
        for (int j = 0; j < 3; ++j) planes[k][j] = m[j * 3] * n[0] + m[j * 3 + 1] * n[1] + m[j * 3 + 2] * n[2];
        planes[k][3] = n[0] * m[9] + n[1] * m[10] + n[2] * m[11] + n[3];
    }
    for (uint32_t c = 0; c < mesh.coarse_count; ++c) {
        const ClusterRange& range = v.coarse[mesh.first_coarse + c];
        if (v.coarse_bounds.obbs &&
            !cull_detail::box_in_frustum(v.coarse_bounds.obb(mesh.first_coarse + c), planes, f.count)) {
            if (stats) ++stats->coarse_culled;
            continue;
        }
        for (uint32_t k = range.first; k < range.first + range.count; ++k) {
            uint32_t fine = mesh.first_fine + k;
            if (stats) ++stats->fine_tested;
            if (!cull_detail::box_in_frustum(v.fine_bounds.obb(fine), planes, f.count)) {
                if (stats) ++stats->frustum_culled;
                continue;
            }
            if (backface && v.fine_bounds.cones && cull_detail::eye_in_back_cone(v.fine_bounds.cone(fine), eye) &&
                !cull_detail::any_double_sided(v, mesh, v.fine[fine].first_triangle, v.fine[fine].triangle_count)) {
                if (stats) ++stats->backface_culled;
                continue;
            }
            if (count < capacity) out[count] = {id, fine};
            ++count;
        }
    }
    return count;
}

// Writes the visible fine clusters of every instance to `out` (at most `capacity`) and returns how many
// there are (which may exceed capacity: call again with more room). Needs the fine boxes; coarse boxes
// and cones are used when present. With `backface` true, clusters whose single-sided triangles all face
// away from the eye are left out. A level (cb_level.h) culls its instances through its hierarchy
// first.
inline size_t cull_clusters(const AssetView& v, const Frustum& f, bool backface, VisibleCluster* out, size_t capacity,
                            CullStats* stats = nullptr) {
    size_t count = 0;
    for (uint32_t i = 0; i < v.instance_count; ++i)
        count = cull_instance(v, placement_of(v, i), i, f, backface, out, capacity, count, stats);
    return count;
}

}  // namespace CB_LANES
}  // namespace cb
