// Point-light shadow queries over a clusterbake asset: is the segment from a point to the light blocked by
// a triangle? This header gives the reference query, which tests every cluster whose box the segment may
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
// may touch (all its clusters when the asset has no fine boxes), every triangle of those, exactly. Sets
// `touched` when a test met a touching contact.
inline bool instance_occludes_reference(const AssetView& v, Placement at, const double* p, const double* light,
                                        bool one_sided, QueryStats* stats, bool* touched) {
    double inv[12], lp[3], ll[3];
    if (!invert_instance(at.transform, inv)) return false;
    apply_instance(inv, p, lp);
    apply_instance(inv, light, ll);
    const MeshRecord& mesh = v.meshes[at.mesh];
    for (uint32_t f = 0; f < mesh.fine_count; ++f) {
        if (v.fine_bounds.obbs && !segment_may_touch_box(v.fine_bounds.obb(mesh.first_fine + f), lp, ll, blocking_from))
            continue;
        if (cluster_blocks(v, mesh, f, lp, ll, one_sided, stats, touched)) return true;
    }
    return false;
}

// Reference query: every instance of the asset as instance_occludes_reference tests it. Returns true when p
// is in shadow; one-sided occluders as cb_segment.h says.
inline bool occluded_reference(const AssetView& v, const double* p, const double* light, bool one_sided = false,
                               QueryStats* stats = nullptr) {
    bool touched = false, blocked = false;
    if (!finite3(p) || !finite3(light)) return false;  // nothing is in shadow of, or from, a point at infinity
    for (uint32_t i = 0; i < v.instance_count && !blocked; ++i)
        blocked = instance_occludes_reference(v, placement_of(v, i), p, light, one_sided, stats, &touched);
    if (stats && touched) ++stats->touching;
    return blocked;
}

}  // namespace CB_LANES
}  // namespace cb
