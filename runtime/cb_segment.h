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
//   closed triangle at a parameter t (p + t (L - p)) of at least `from` = shadow_from(p, L, bias), the
//   self-shadowing rule: contacts nearer to p than the world-space distance `bias` do not count, whatever
//   the light's distance (so a point on a surface does not shadow itself). `from` is computed in double
//   exactly as shadow_from writes it, and the comparison t >= from is then exact. The light itself lying on
//   a triangle counts as blocked; a point within `bias` of the light is never in shadow.
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

// The self-shadowing bias a scene gets unless the caller gives one: this fraction of the largest side of its
// world box (Level::shadow_bias, default_shadow_bias), 128 to 256 float steps of the scene's size. Meshes are
// stored about origins of their own (FORMAT.md), so their float precision follows their size, not their
// distance from the world's origin.
constexpr double default_bias_fraction = 1.0 / 65536.0;

inline double default_shadow_bias(double world_size) {
    return world_size > 0 && world_size < INFINITY ? world_size * default_bias_fraction : 0.0;
}

// Where a query's contacts start to count, as a fraction of the way from p to the light: bias / |light - p|.
// Evaluated as written (differences, then the squares summed with explicit fused multiply-adds, so that
// every compiler and instruction set gives the same bits), each step rounded to nearest (IEEE 754); infinite
// when p is the light, NaN when something is not finite. Every traversal and the reference use this value.
inline double shadow_from(const double* p, const double* light, double bias) {
    const double dx = light[0] - p[0], dy = light[1] - p[1], dz = light[2] - p[2];
    return bias / std::sqrt(std::fma(dz, dz, std::fma(dy, dy, dx * dx)));
}

// A query can be blocked at all: its `from` is at most 1 (a NaN is not). The filters start the segment at
// half of `from` (blocking_start), far beyond their rounding, so that a point lying on a flat cluster, whose
// segment leaves that cluster's thin box before any contact could count, does not test its triangles.
inline bool may_block(double from) { return from <= 1; }
inline double blocking_start(double from) { return 0.5 * from; }

struct SegmentTest {
    bool blocks = false;
    bool touching = false;  // boundary contact (see above), whether or not it blocks
};

// The segment p -> q against the closed triangle a, b, c, exactly, contacts counting from parameter `from`
// on (shadow_from, at most 1). With `two_sided` false the triangle only blocks when q (the light) is
// strictly behind it.
inline SegmentTest segment_triangle(const double* p, const double* q, const double* a, const double* b, const double* c,
                                    double from, bool two_sided = true) {
    SegmentTest r;
    double bp, bq, ep = exact::orient3d_estimate(a, b, c, p, bp), eq = exact::orient3d_estimate(a, b, c, q, bq);
    int sq = exact::settled_sign(eq, bq);
    if (sq == exact::unsettled) sq = exact::sign(exact::orient3d_exact(a, b, c, q));
    if (!two_sided && sq != 1) return r;  // one-sided: the light sees its front, or lies in its plane
    // The line through p and q must pass through the closed triangle: no two edge orientations of
    // opposite strict signs.
    int e0 = 0, e1 = 0, e2 = 0;
    auto line_misses = [&] {
        e0 = exact::orient3d(p, q, a, b);
        e1 = exact::orient3d(p, q, b, c);
        e2 = exact::orient3d(p, q, c, a);
        return (e0 > 0 || e1 > 0 || e2 > 0) && (e0 < 0 || e1 < 0 || e2 < 0);
    };
    // p's side of the plane, when the double estimate settles it. When it does not (p on or next to the
    // plane: a point on a flat surface against the triangles around it), the line test comes first: the
    // tests that return nothing commute, and it needs no side, so the exact side is evaluated only for a
    // line through the triangle.
    int sp = exact::settled_sign(ep, bp);
    const bool p_settled = sp != exact::unsettled;
    if (!p_settled) {
        if (line_misses()) return r;
        sp = exact::sign(exact::orient3d_exact(a, b, c, p));
    }
    if (sp == 0 && sq == 0) return r;  // coplanar (or no area): edge-on, never blocks
    if (sp == sq) return r;            // both ends strictly on one side
    if (p_settled && line_misses()) return r;
    r.touching = sp == 0 || sq == 0 || e0 == 0 || e1 == 0 || e2 == 0;
    // The crossing is at t = Dp / (Dp - Dq) with D the plane determinants; it counts when t >= f (f = from),
    // that is when Dp + f (Dq - Dp) = (1 - f) Dp + f Dq has Dp's sign or is zero (Dp and Dq have opposite
    // signs or Dq is zero).
    if (!may_block(from)) return r;  // every contact is nearer than `from` (or `from` is not a number)
    if (sp == 0) {                   // at the query point itself: t = 0
        r.blocks = from <= 0;
        return r;
    }
    if (sq == 0) {  // at the light: t = 1
        r.blocks = true;
        return r;
    }
    // In double first: the estimate of (1 - f) Dp + f Dq is off by at most the bounds' blend and its own
    // rounding (1 - f's included); only when that cannot decide, exactly.
    const double f = from;
    double mix_estimate = (1 - f) * ep + f * eq;
    double mix_bound = (1 - f) * bp + f * bq + 8e-16 * (std::fabs(ep) + std::fabs(eq));
    if (std::fabs(mix_estimate) > mix_bound) {
        r.blocks = (mix_estimate > 0 ? 1 : -1) == sp;
        return r;
    }
    exact::Expansion dp = exact::orient3d_exact(a, b, c, p), dq = exact::orient3d_exact(a, b, c, q);
    exact::add(dq, exact::negated(dp));
    exact::Expansion mix = exact::scaled(exact::compressed(dq), f);
    exact::add(mix, dp);
    int s = exact::sign(mix);
    r.blocks = s == 0 || s == sp;
    return r;
}

// A sun: a light at infinity, given by `toward`, the direction from the scene toward it (any length above
// zero). The query ray runs from p along it, p + t toward for t >= 0; contacts count from t >= from on, with
// from = sun_from(toward, bias) = bias / |toward| computed as shadow_from computes it for L - p: the same
// world-space bias. Every other rule is the point light's, the light taken as lying past every triangle:
// a triangle blocks one-sided only when the sun is strictly behind it (toward points to the side its
// counter-clockwise winding faces away from), a triangle parallel to the ray never blocks, touching
// contacts block.
inline double sun_from(const double* toward, double bias) {
    const double dx = toward[0], dy = toward[1], dz = toward[2];
    return bias / std::sqrt(std::fma(dz, dz, std::fma(dy, dy, dx * dx)));
}

// The ray p + t d (t >= from) against the closed triangle a, b, c, exactly (the sun's rules above; from is
// sun_from's). `touching` is set for a boundary contact that blocks (one at t >= from): contacts nearer than
// `from` are not examined where the ray is already past the triangle's plane there. With D(x) = orient3d(a,
// b, c, x) = N . (a - x), N = (b - a) x (c - a): D(p + t d) = D(p) + t D_d with D_d = det(-d, b - a, c - a) =
// -N . d, the side the ray heads for.
inline SegmentTest ray_triangle(const double* p, const double* d, const double* a, const double* b, const double* c,
                                double from, bool two_sided = true) {
    SegmentTest r;
    const double minus_d[3] = {-d[0], -d[1], -d[2]};
    const exact::Row side_rows[3] = {{minus_d, nullptr}, {b, a}, {c, a}};
    double bp, bd, ep = exact::orient3d_estimate(a, b, c, p, bp), ed = exact::det3_estimate(side_rows, bd);
    // At `from` the ray is strictly past the plane and heading away (D(p) + from D_d has D_d's sign, both
    // settled in double): no contact can count. Most often p lies on this triangle (or its plane), where
    // D(p)'s own sign would need the exact path; such a contact is not examined, nor reported as touching.
    const double f0 = from, ahead = ep + f0 * ed,
                 ahead_bound = bp + f0 * bd + 4e-16 * (std::fabs(ep) + f0 * std::fabs(ed));
    if (f0 >= 0 && ((ed > bd && ahead > ahead_bound) || (-ed > bd && -ahead > ahead_bound))) return r;
    int sp = exact::settled_sign(ep, bp), sd = exact::settled_sign(ed, bd);
    if (sp == exact::unsettled) sp = exact::sign(exact::orient3d_exact(a, b, c, p));
    if (sd == exact::unsettled) sd = exact::sign(exact::det3_exact(side_rows));
    if (!two_sided && sd != 1) return r;  // one-sided: the sun sees its front, or grazes its plane
    if (sd == 0) return r;                // parallel to the plane: in it (edge-on) or never meeting it
    if (sp == sd) return r;               // heading away from the plane
    // The line must pass through the closed triangle: orient3d(p, p + d, u, v) = det(p - v, d, u - v) per
    // edge u-v, no two of opposite strict signs.
    auto edge = [&](const double* u, const double* v) {
        const exact::Row rows[3] = {{p, v}, {d, nullptr}, {u, v}};
        return exact::det3_sign(rows);
    };
    const int e0 = edge(a, b), e1 = edge(b, c);
    if (e0 * e1 < 0) return r;  // two edges of opposite strict signs: a miss, whatever the third
    const int e2 = edge(c, a);
    if ((e0 > 0 || e1 > 0 || e2 > 0) && (e0 < 0 || e1 < 0 || e2 < 0)) return r;
    const bool touching = sp == 0 || e0 == 0 || e1 == 0 || e2 == 0;
    auto answer = [&](bool blocks) {
        r.blocks = blocks;
        r.touching = touching && blocks;
        return r;
    };
    if (!(std::fabs(from) < INFINITY)) return r;  // not a number
    if (sp == 0) return answer(from <= 0);        // at the query point itself: t = 0
    // The crossing is at t = -D(p) / D_d; it counts when t >= f, that is when D(p) + f D_d has D(p)'s sign or
    // is zero. In double first, then exactly.
    const double f = from;
    const double mix_estimate = ep + f * ed, mix_bound = bp + f * bd + 4e-16 * (std::fabs(ep) + f * std::fabs(ed));
    if (std::fabs(mix_estimate) > mix_bound) return answer((mix_estimate > 0 ? 1 : -1) == sp);
    exact::Expansion mix = exact::scaled(exact::compressed(exact::det3_exact(side_rows)), f);
    exact::add(mix, exact::orient3d_exact(a, b, c, p));
    const int s = exact::sign(mix);
    return answer(s == 0 || s == sp);
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

// The linear part of an instance transform applied to a direction (no translation).
inline void apply_linear(const double* m, const double* d, double* out) {
    for (int k = 0; k < 3; ++k) out[k] = m[k] * d[0] + m[3 + k] * d[1] + m[6 + k] * d[2];
}

// The instance transform a x b (both column-major 3x4): b applied first. Levels place baked instances with
// it (Level::add_baked, level files); an engine that moves them composes the same way to get the same bits.
inline void compose_instance(const double* a, const double* b, double* out) {
    for (int col = 0; col < 4; ++col)
        for (int k = 0; k < 3; ++k)
            out[col * 3 + k] =
                a[k] * b[col * 3] + a[3 + k] * b[col * 3 + 1] + a[6 + k] * b[col * 3 + 2] + (col == 3 ? a[9 + k] : 0.0);
}

// Grows lo, hi (world space) by the box [box_lo, box_hi] of a mesh's frame placed by m (column-major 3x4): its
// centre moved, its half extents through |M|. Singular or non-finite placements add nothing (they block
// nothing). The scene's size for default_shadow_bias (asset_world_size, Level::shadow_bias).
inline void add_placed_box(const double* box_lo, const double* box_hi, const double* m, double* lo, double* hi) {
    double inverse[12];
    if (!(box_lo[0] <= box_hi[0] && box_lo[1] <= box_hi[1] && box_lo[2] <= box_hi[2]) || !invert_instance(m, inverse))
        return;
    double c[3], h[3], wc[3], wh[3];
    for (int k = 0; k < 3; ++k) {
        c[k] = 0.5 * (box_lo[k] + box_hi[k]);
        h[k] = 0.5 * (box_hi[k] - box_lo[k]);
    }
    apply_instance(m, c, wc);
    for (int k = 0; k < 3; ++k) {
        wh[k] = std::fabs(m[k]) * h[0] + std::fabs(m[3 + k]) * h[1] + std::fabs(m[6 + k]) * h[2];
        if (!std::isfinite(wc[k] - wh[k]) || !std::isfinite(wc[k] + wh[k])) return;
    }
    for (int k = 0; k < 3; ++k) {
        lo[k] = std::min(lo[k], wc[k] - wh[k]);
        hi[k] = std::max(hi[k], wc[k] + wh[k]);
    }
}

// The largest side of a world box (0 when empty).
inline double box_size(const double* lo, const double* hi) {
    double size = 0;
    for (int k = 0; k < 3; ++k) size = std::max(size, hi[k] - lo[k]);
    return size;
}

// The mesh's box in its own frame, from its vertices (empty, lo > hi, without any).
inline void mesh_box(const AssetView& v, const MeshRecord& mesh, double* lo, double* hi) {
    for (int k = 0; k < 3; ++k) {
        lo[k] = INFINITY;
        hi[k] = -INFINITY;
    }
    for (uint32_t i = 0; i < mesh.vertex_count; ++i) {
        const float* p = v.position(mesh, i);
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], double(p[k]));
            hi[k] = std::max(hi[k], double(p[k]));
        }
    }
}

// The largest side of the world box of every instance of the asset (add_placed_box of each mesh's box): the
// size default_shadow_bias takes for the asset's own scene. A pass over the vertices, and one over the
// instances per mesh (no allocation).
inline double asset_world_size(const AssetView& v) {
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t m = 0; m < v.mesh_count; ++m) {
        double mlo[3], mhi[3];
        mesh_box(v, v.meshes[m], mlo, mhi);
        for (uint32_t i = 0; i < v.instance_count; ++i)
            if (v.instances[i].mesh == m) add_placed_box(mlo, mhi, v.instances[i].transform, lo, hi);
    }
    return box_size(lo, hi);
}

// Conservative: false only when the part of the segment p-q from parameter `from` to q (p + t (q - p),
// from <= t <= 1) certainly misses the box. Clips that parameter range against each of the box's three
// slabs (the box is their intersection), each slab widened by a margin far above the rounding of the dot
// products and divisions, relative to the inputs' size. Shadow queries pass blocking_start(from).
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
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
        if (t0 > t1) return false;
    }
    return true;
}

// The same for the ray p + t d, from <= t (a sun's query): false only when it certainly misses the box. Past
// t = T = 2 (|p - centre|_1 + the half extents' sum) / |d| the ray is outside the box's bounding sphere, so
// the segment from p to p + T d, from from / T of its way on, stands for it (the rounding of its far end,
// 1e-16 of its size, is far inside segment_may_touch_box's margin).
inline bool ray_may_touch_box(const Obb& box, const double* p, const double* d, double from = 0) {
    const double reach = std::fabs(p[0] - box.center[0]) + std::fabs(p[1] - box.center[1]) +
        std::fabs(p[2] - box.center[2]) + double(box.half[0]) + box.half[1] + box.half[2];
    const double length = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), far = 2 * reach / length;
    if (!(far > 0 && far < INFINITY)) return true;  // no direction, no size or not finite: kept
    const double q[3] = {p[0] + far * d[0], p[1] + far * d[1], p[2] + far * d[2]};
    return segment_may_touch_box(box, p, q, from / far);
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

// The same for a sun toward `toward`: the direction clearly inside the front cone's angle. Every point
// front_apex + s toward (s > 0) is then in the cone, so each triangle's normal n has n . toward >= 0 (the
// limit as s grows): the sun is never strictly behind a triangle, and none blocks one-sided.
inline bool sun_in_front_cone(const Cone& c, const double* toward) {
    if (!c.valid) return false;
    const double a[3] = {c.axis[0], c.axis[1], c.axis[2]};
    const double tl = std::sqrt(toward[0] * toward[0] + toward[1] * toward[1] + toward[2] * toward[2]),
                 al = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    if (!(tl > 0 && tl < INFINITY) || !(al > 0)) return false;
    return toward[0] * a[0] + toward[1] * a[1] + toward[2] * a[2] > al * tl * (double(c.cos_half_angle) + 1e-9);
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
