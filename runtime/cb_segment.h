// The exact test of a segment from a point to a point light against one triangle, the instance transforms
// queries apply, and what a query counts. Header-only C++17, no dependencies, no exceptions, no
// allocation. MIT licensed (runtime/LICENSE).
//
// Semantics, exact for every input (all predicates are exact, cb_exact.h):
// - Two-sided occluders (the default): every triangle with an area blocks, whichever way it faces.
//   One-sided (an option, for closed models): a triangle blocks only when the light is strictly behind it
//   (on the side its counter-clockwise winding faces away from), unless the asset marks it double-sided
//   (glTF doubleSided primitives stay two-sided). For points outside a closed mesh both modes agree.
// - The query segment runs from the point p to the light L. A triangle blocks when the segment meets the
//   closed triangle at a parameter t (p + t (L - p)) of at least 2^-13. So a point on a surface does not
//   shadow itself, nor is it shadowed by anything closer than 2^-13 of its distance to the light
//   (self-shadowing policy); the light itself lying on a triangle counts as blocked.
// - A triangle whose plane contains the whole segment (seen exactly edge-on), or that has no area,
//   never blocks.
// - "Touching": the segment meets the triangle only on its boundary (an edge or vertex), or an end of the
//   segment lies on the triangle's plane. Touching contacts block (so light never leaks through the shared
//   edge of two triangles); queries that involved one are counted separately in the statistics.
// - Instances: the light and the point are taken into each instanced mesh's frame with the inverse of its
//   affine transform, in double; the exact tests run there.
// - A point or light with a coordinate that is not finite is never in shadow. Exactness holds in the
//   domain of cb_exact.h (magnitudes up to about 1e90); beyond it answers are unspecified but every
//   access stays in bounds.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "cb_asset.h"
#include "detail/cb_exact.h"
#include "detail/cb_simd.h"

namespace cb {
inline namespace CB_LANES {

// Hits closer to the query point than this fraction of the way to the light are ignored. A power of two,
// so the exact test scales by it without rounding.
constexpr double self_shadow_fraction = 1.0 / 8192.0;

// Where the filters start the segment (as a fraction of the way from the point): half of
// self_shadow_fraction, far beyond their rounding, so that a point lying on a flat cluster, whose segment
// leaves that cluster's thin box well before any contact could count, does not test its triangles.
constexpr double blocking_from = self_shadow_fraction / 2;

struct SegmentTest {
    bool blocks = false;
    bool touching = false;  // boundary contact (see above), whether or not it blocks
};

// The segment p -> q against the closed triangle a, b, c, exactly. With `two_sided` false the triangle only
// blocks when q (the light) is strictly behind it.
inline SegmentTest segment_triangle(const double* p, const double* q, const double* a, const double* b, const double* c,
                                    bool two_sided = true) {
    SegmentTest r;
    double bp, bq, ep = exact::orient3d_estimate(a, b, c, p, bp), eq = exact::orient3d_estimate(a, b, c, q, bq);
    int sp = ep > bp ? 1 : -ep > bp ? -1 : exact::sign(exact::orient3d_exact(a, b, c, p));
    int sq = eq > bq ? 1 : -eq > bq ? -1 : exact::sign(exact::orient3d_exact(a, b, c, q));
    if (!two_sided && sq != 1) return r;  // one-sided: the light sees its front, or lies in its plane
    if (sp == 0 && sq == 0) return r;     // coplanar (or no area): edge-on, never blocks
    if (sp == sq) return r;               // both ends strictly on one side
    // The line through p and q must pass through the closed triangle: no two edge orientations of
    // opposite strict signs.
    int e0 = exact::orient3d(p, q, a, b), e1 = exact::orient3d(p, q, b, c), e2 = exact::orient3d(p, q, c, a);
    if ((e0 > 0 || e1 > 0 || e2 > 0) && (e0 < 0 || e1 < 0 || e2 < 0)) return r;
    r.touching = sp == 0 || sq == 0 || e0 == 0 || e1 == 0 || e2 == 0;
    // The crossing is at t = Dp / (Dp - Dq) with D the plane determinants; it counts when t >= f, that is
    // when (1 - f) Dp + f Dq has Dp's sign or is zero (Dp and Dq have opposite signs or Dq is zero).
    if (sp == 0) return r;                   // at the query point itself: t = 0 < f
    if (sq == 0) return r.blocks = true, r;  // at the light: t = 1
    // In double first: the estimate of (1 - f) Dp + f Dq is off by at most the bounds' blend and its own
    // rounding; only when that cannot decide, exactly.
    double mix_estimate = (1 - self_shadow_fraction) * ep + self_shadow_fraction * eq;
    double mix_bound =
        (1 - self_shadow_fraction) * bp + self_shadow_fraction * bq + 4e-16 * (std::fabs(ep) + std::fabs(eq));
    if (std::fabs(mix_estimate) > mix_bound) {
        r.blocks = (mix_estimate > 0 ? 1 : -1) == sp;
        return r;
    }
    exact::Expansion dp = exact::orient3d_exact(a, b, c, p), dq = exact::orient3d_exact(a, b, c, q);
    exact::Expansion mix = exact::scaled_by_power_of_two(dq, self_shadow_fraction);
    exact::add(mix, dp);
    exact::add(mix, exact::negated(exact::scaled_by_power_of_two(dp, self_shadow_fraction)));
    int s = exact::sign(mix);
    r.blocks = s == 0 || s == sp;
    return r;
}

// Where one instance of a mesh stands: the mesh's index in the asset and its world transform (affine,
// column-major 3x4 doubles: the x, y, z axes, then the translation). An asset's InstanceRecord gives one
// (placement_of); a level (cb_level.h) gives its own. Read only while a traversal is built.
struct Placement {
    uint32_t mesh;
    const double* transform;
};

inline Placement placement_of(const AssetView& view, uint32_t instance) {
    return {view.instances[instance].mesh, view.instances[instance].transform};
}

// The affine inverse of an instance transform (column-major 3x4: x, y, z axes, translation). False when
// the transform is singular: such an instance is flat and blocks nothing.
inline bool invert_instance(const double* m, double* inv) {
    const double a = m[0], b = m[3], c = m[6], d = m[1], e = m[4], f = m[7], g = m[2], h = m[5], i = m[8];
    double det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
    if (!(std::fabs(det) > 0) || !std::isfinite(det)) return false;
    double r[9] = {(e * i - f * h) / det, (c * h - b * i) / det, (b * f - c * e) / det,
                   (f * g - d * i) / det, (a * i - c * g) / det, (c * d - a * f) / det,
                   (d * h - e * g) / det, (b * g - a * h) / det, (a * e - b * d) / det};  // row-major
    for (int row = 0; row < 3; ++row)
        for (int col = 0; col < 3; ++col) inv[col * 3 + row] = r[row * 3 + col];
    for (int row = 0; row < 3; ++row)
        inv[9 + row] = -(r[row * 3] * m[9] + r[row * 3 + 1] * m[10] + r[row * 3 + 2] * m[11]);
    return true;
}

inline bool finite3(const double* p) { return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]); }

inline void apply_instance(const double* m, const double* p, double* out) {
    for (int k = 0; k < 3; ++k) out[k] = m[k] * p[0] + m[3 + k] * p[1] + m[6 + k] * p[2] + m[9 + k];
}

// The instance transform a x b (both column-major 3x4): b applied first. Levels place baked instances with
// it (Level::add_baked, level files); an engine that moves them composes the same way to get the same bits.
inline void compose_instance(const double* a, const double* b, double* out) {
    for (int col = 0; col < 4; ++col)
        for (int k = 0; k < 3; ++k)
            out[col * 3 + k] =
                a[k] * b[col * 3] + a[3 + k] * b[col * 3 + 1] + a[6 + k] * b[col * 3 + 2] + (col == 3 ? a[9 + k] : 0.0);
}

// Conservative: false only when the part of the segment p-q from parameter `from` to q (p + t (q - p),
// from <= t <= 1) certainly misses the box. Clips that parameter range against each of the box's three
// slabs (the box is their intersection), each slab widened by a margin far above the rounding of the dot
// products and divisions, relative to the inputs' size. Shadow queries pass blocking_from.
inline bool segment_may_touch_box(const Obb& box, const double* p, const double* q, double from = 0) {
    double t0 = from, t1 = 1;
    double pc[3] = {p[0] - box.center[0], p[1] - box.center[1], p[2] - box.center[2]};
    double qc[3] = {q[0] - box.center[0], q[1] - box.center[1], q[2] - box.center[2]};
    double size =
        std::fabs(pc[0]) + std::fabs(pc[1]) + std::fabs(pc[2]) + std::fabs(qc[0]) + std::fabs(qc[1]) + std::fabs(qc[2]);
    for (int i = 0; i < 3; ++i) {
        const float* a = box.axis[i];
        double dp = pc[0] * a[0] + pc[1] * a[1] + pc[2] * a[2], dq = qc[0] * a[0] + qc[1] * a[1] + qc[2] * a[2];
        double margin = 1e-9 * (size + box.half[i]), reach = box.half[i] + margin, d = dq - dp;
        if (std::fabs(d) <= margin) {  // along the slab: in it everywhere or nowhere
            if (std::fabs(dp) > reach + margin) return false;
            continue;
        }
        double ta = (-reach - dp) / d, tb = (reach - dp) / d;
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta), t1 = std::min(t1, tb);
        if (t0 > t1) return false;
    }
    return true;
}

// True only when the light is clearly inside the cluster's front cone (the stored cone's cosine rounded up,
// plus a margin): then it sees every triangle of the cluster from the front.
inline bool light_in_front_cone(const Cone& c, const double* light) {
    if (!c.valid) return false;
    double v[3] = {light[0] - c.front_apex[0], light[1] - c.front_apex[1], light[2] - c.front_apex[2]};
    double a[3] = {c.axis[0], c.axis[1], c.axis[2]};
    double vl = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]),
           al = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    if (!(vl > 0) || !(al > 0)) return false;
    return v[0] * a[0] + v[1] * a[1] + v[2] * a[2] > al * vl * (double(c.cos_half_angle) + 1e-9);
}

}  // namespace CB_LANES

// What queries counted (every traversal, any lanes; outside the lanes' namespace, see cb_simd.h).
struct QueryStats {
    uint64_t nodes_visited = 0;    // tree nodes (TopTreeTraversal only)
    uint64_t clusters_tested = 0;  // fine clusters whose triangles were tested
    uint64_t triangles_tested = 0;
    uint64_t touching = 0;  // queries whose answer involved a touching contact
};

}  // namespace cb
