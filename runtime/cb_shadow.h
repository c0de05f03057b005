// Point-light shadow queries over a clusterbake asset: is the segment from a point to the light blocked by
// a triangle? This header gives the reference query, and the same for suns (a light at infinity, given by a
// direction), which tests every cluster whose box the segment may
// touch, and includes the parts every query is made of: the exact segment test and its semantics
// (cb_segment.h), the test of a cluster's triangles (cb_lit_triangles.h) and the shadow volume of a box
// (cb_shadow_volume.h). The clustered structures, per light, are in cb_cpsv.h. Header-only C++17, no
// dependencies, no exceptions, no allocation. MIT licensed (runtime/LICENSE).
#pragma once

#include <cstdint>

#include "cb_asset.h"
#include "detail/cb_lit_triangles.h"
#include "cb_segment.h"
#include "detail/cb_shadow_volume.h"

namespace cb {
inline namespace CB_LANES {

// One instance's part of the reference query: every fine cluster of the placed mesh whose box the segment
// may touch (all its clusters when the asset has no fine boxes), every triangle of those, exactly, contacts
// counting from `from` on (shadow_from of the world point and light, at most 1). Sets `touched` when a test
// met a touching contact.
inline bool instance_occludes_reference(const AssetView& v, Placement at, const double* p, const double* light,
                                        double from, bool one_sided, QueryStats* stats, bool* touched) {
    double inv[12], lp[3], ll[3];
    if (!invert_instance(at.transform, inv)) return false;
    apply_instance(inv, p, lp);
    apply_instance(inv, light, ll);
    const MeshRecord& mesh = v.meshes[at.mesh];
    for (uint32_t f = 0; f < mesh.fine_count; ++f) {
        if (v.fine_bounds.obbs &&
            !segment_may_touch_box(v.fine_bounds.obb(mesh.first_fine + f), lp, ll, blocking_start(from)))
            continue;
        if (cluster_blocks(v, mesh, f, lp, from, ll, one_sided, stats, touched)) return true;
    }
    return false;
}

// Reference query: every instance of the asset as instance_occludes_reference tests it, with the
// self-shadowing `bias` (cb_segment.h; zero or less: default_shadow_bias(asset_world_size(v)), a pass over
// the asset). Returns true when p is in shadow; one-sided occluders as cb_segment.h says.
inline bool occluded_reference(const AssetView& v, const double* p, const double* light, double bias,
                               bool one_sided = false, QueryStats* stats = nullptr) {
    bool touched = false, blocked = false;
    if (!finite3(p) || !finite3(light)) return false;  // nothing is in shadow of, or from, a point at infinity
    const double from = shadow_from(p, light, bias > 0 ? bias : default_shadow_bias(asset_world_size(v)));
    if (!may_block(from)) return false;
    for (uint32_t i = 0; i < v.instance_count && !blocked; ++i)
        blocked = instance_occludes_reference(v, placement_of(v, i), p, light, from, one_sided, stats, &touched);
    if (stats && touched) ++stats->touching;
    return blocked;
}

// Suns (cb_segment.h: a light at infinity in direction `toward`): the same reference, each triangle of the
// clusters whose box the ray may touch by ray_triangle. A sun's clustered traversal is SunTraversal (cb_sun.h).
inline bool cluster_blocks_sun(const AssetView& v, const MeshRecord& mesh, uint32_t f, const double* p,
                               const double* toward, double from, bool one_sided, QueryStats* stats, bool* touched) {
    const FineCluster& c = v.fine[mesh.first_fine + f];
    if (stats) ++stats->clusters_tested;
    for (uint32_t t = c.first_triangle; t < c.first_triangle + c.triangle_count; ++t) {
        uint32_t id[3];
        v.triangle(mesh, f, t, id);
        double x[3][3];
        for (int k = 0; k < 3; ++k)
            for (int j = 0; j < 3; ++j) x[k][j] = v.position(mesh, id[k])[j];
        if (stats) ++stats->triangles_tested;
        const bool two_sided = !one_sided || v.double_sided(size_t(mesh.first_triangle) + t);
        const SegmentTest s = ray_triangle(p, toward, x[0], x[1], x[2], from, two_sided);
        if (touched) *touched |= s.touching;
        if (s.blocks) return true;
    }
    return false;
}

inline bool instance_occludes_sun_reference(const AssetView& v, Placement at, const double* p, const double* toward,
                                            double from, bool one_sided, QueryStats* stats, bool* touched) {
    double inv[12], lp[3], ld[3];
    if (!invert_instance(at.transform, inv)) return false;
    apply_instance(inv, p, lp);
    apply_linear(inv, toward, ld);
    const MeshRecord& mesh = v.meshes[at.mesh];
    for (uint32_t f = 0; f < mesh.fine_count; ++f) {
        if (v.fine_bounds.obbs &&
            !ray_may_touch_box(v.fine_bounds.obb(mesh.first_fine + f), lp, ld, blocking_start(from)))
            continue;
        if (cluster_blocks_sun(v, mesh, f, lp, ld, from, one_sided, stats, touched)) return true;
    }
    return false;
}

// Is p in the shadow of the sun in direction `toward` (from the scene toward the sun)? Every instance as
// instance_occludes_sun_reference tests it, with the self-shadowing `bias` (zero or less: as
// occluded_reference takes it). A direction of no length, or anything not finite, lights everything.
inline bool occluded_sun_reference(const AssetView& v, const double* p, const double* toward, double bias,
                                   bool one_sided = false, QueryStats* stats = nullptr) {
    bool touched = false, blocked = false;
    if (!finite3(p) || !finite3(toward)) return false;
    const double from = sun_from(toward, bias > 0 ? bias : default_shadow_bias(asset_world_size(v)));
    if (!(from < INFINITY)) return false;
    for (uint32_t i = 0; i < v.instance_count && !blocked; ++i)
        blocked = instance_occludes_sun_reference(v, placement_of(v, i), p, toward, from, one_sided, stats, &touched);
    if (stats && touched) ++stats->touching;
    return blocked;
}

}  // namespace CB_LANES
}  // namespace cb
