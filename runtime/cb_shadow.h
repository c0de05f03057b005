// Point-light shadow queries over a clusterbake asset: is the segment from a point to the light blocked by
// a triangle? This header gives the reference query, which tests every cluster whose box the segment may
// touch, and the same for suns (a light at infinity, given by a direction); it includes the parts every
// query is made of: the exact segment test and its semantics
// (cb_segment.h), the test of a cluster's triangles (cb_lit_triangles.h) and the shadow volume of a box
// (cb_shadow_volume.h). The clustered structures, per light, are in cb_instance_shadow.h. Header-only C++17, no
// dependencies, no exceptions, no allocation. MIT licensed (runtime/LICENSE).
#pragma once

#include <cstdint>

#include "cb_asset.h"
#include "detail/cb_lit_triangles.h"
#include "cb_segment.h"
#include "detail/cb_shadow_volume.h"

namespace cb {
inline namespace CB_LANES {

// Suns (cb_segment.h: a light at infinity in direction `toward`): the test of a cluster's triangles, each by
// ray_triangle. A sun's clustered traversal is SunTraversal (cb_sun.h).
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

// The reference walk of one mesh, in its own frame: every fine cluster whose box the query may touch (all
// its clusters when the asset has no fine boxes), every triangle of those, exactly, contacts counting from
// `from` on. The query is p's segment to the point `light`, or with `sun` its ray along `light`, the
// direction toward the sun. Sets `touched` when a test met a touching contact.
inline bool mesh_occludes_reference(const AssetView& v, const MeshRecord& mesh, const double* p, const double* light,
                                    bool sun, double from, bool one_sided, QueryStats* stats, bool* touched) {
    const double start = blocking_start(from);
    for (uint32_t f = 0; f < mesh.fine_count; ++f) {
        if (v.fine_bounds.obbs) {
            const Obb box = v.fine_bounds.obb(mesh.first_fine + f);
            if (!(sun ? ray_may_touch_box(box, p, light, start) : segment_may_touch_box(box, p, light, start)))
                continue;
        }
        if (sun ? cluster_blocks_sun(v, mesh, f, p, light, from, one_sided, stats, touched)
                : cluster_blocks(v, mesh, f, p, from, light, one_sided, stats, touched))
            return true;
    }
    return false;
}

// One instance's part of the reference query: p and the light (a point, or with `sun` a direction) moved
// into the placed mesh's frame, then mesh_occludes_reference. `from` is shadow_from of the world point and
// light (at most 1), or sun_from.
inline bool instance_occludes_reference(const AssetView& v, Placement at, const double* p, const double* light,
                                        double from, bool one_sided, QueryStats* stats, bool* touched,
                                        bool sun = false) {
    double inv[12], lp[3], ll[3];
    if (!invert_instance(at.transform, inv)) return false;
    apply_instance(inv, p, lp);
    if (sun)
        apply_linear(inv, light, ll);
    else
        apply_instance(inv, light, ll);
    return mesh_occludes_reference(v, v.meshes[at.mesh], lp, ll, sun, from, one_sided, stats, touched);
}

// The reference query over the placements `each(visit)` hands to visit(view, placement) (which returns
// whether to go on), with the self-shadowing `bias` already chosen. Nothing is in shadow of, or from, a point
// at infinity; a sun of no length lights everything.
template <class EachPlacement>
bool reference_query(EachPlacement each, const double* p, const double* light, double bias, bool sun, bool one_sided,
                     QueryStats* stats) {
    if (!finite3(p) || !finite3(light)) return false;
    const double from = sun ? sun_from(light, bias) : shadow_from(p, light, bias);
    if (!(sun ? from < INFINITY : may_block(from))) return false;
    bool touched = false, blocked = false;
    each([&](const AssetView& v, Placement at) {
        blocked = instance_occludes_reference(v, at, p, light, from, one_sided, stats, &touched, sun);
        return !blocked;
    });
    if (stats && touched) ++stats->touching;
    return blocked;
}

// The asset's instances, in order, for reference_query.
inline auto asset_placements(const AssetView& v) {
    return [&v](auto visit) {
        for (uint32_t i = 0; i < v.instance_count; ++i)
            if (!visit(v, placement_of(v, i))) return;
    };
}

// Reference query: every instance of the asset as instance_occludes_reference tests it, with the
// self-shadowing `bias` (cb_segment.h; zero or less: default_shadow_bias(asset_world_size(v)), a pass over
// the asset). Returns true when p is in shadow; one-sided occluders as cb_segment.h says.
inline bool occluded_reference(const AssetView& v, const double* p, const double* light, double bias,
                               bool one_sided = false, QueryStats* stats = nullptr) {
    if (!finite3(p) || !finite3(light)) return false;  // answered before a default bias's pass over the asset
    const double b = bias > 0 ? bias : default_shadow_bias(asset_world_size(v));
    return reference_query(asset_placements(v), p, light, b, false, one_sided, stats);
}

// Is p in the shadow of the sun in direction `toward` (from the scene toward the sun)? The same reference
// along the ray. A direction of no length, or anything not finite, lights everything.
inline bool occluded_sun_reference(const AssetView& v, const double* p, const double* toward, double bias,
                                   bool one_sided = false, QueryStats* stats = nullptr) {
    if (!finite3(p) || !finite3(toward)) return false;
    const double b = bias > 0 ? bias : default_shadow_bias(asset_world_size(v));
    return reference_query(asset_placements(v), p, toward, b, true, one_sided, stats);
}

}  // namespace CB_LANES
}  // namespace cb
