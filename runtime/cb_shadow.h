// Point-light shadow queries over a clusterbake asset: is the segment from a point to the light blocked by
// a triangle? Header-only C++17, no dependencies, no exceptions, no allocation. MIT licensed.
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
//
// This file holds the exact segment test and the reference query, which tests every cluster whose box
// the segment may touch. The clustered shadow volume structure (per light) builds on both.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "cb_asset.h"
#include "cb_exact.h"

namespace cb {

// Hits closer to the query point than this fraction of the way to the light are ignored. A power of two,
// so the exact test scales by it without rounding.
constexpr double self_shadow_fraction = 1.0 / 8192.0;

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
    if (!two_sided && sq != 1) return r;        // one-sided: the light sees its front, or lies in its plane
    if (sp == 0 && sq == 0) return r;           // coplanar (or no area): edge-on, never blocks
    if (sp == sq) return r;                     // both ends strictly on one side
    // The line through p and q must pass through the closed triangle: no two edge orientations of
    // opposite strict signs.
    int e0 = exact::orient3d(p, q, a, b), e1 = exact::orient3d(p, q, b, c), e2 = exact::orient3d(p, q, c, a);
    if ((e0 > 0 || e1 > 0 || e2 > 0) && (e0 < 0 || e1 < 0 || e2 < 0)) return r;
    r.touching = sp == 0 || sq == 0 || e0 == 0 || e1 == 0 || e2 == 0;
    // The crossing is at t = Dp / (Dp - Dq) with D the plane determinants; it counts when t >= f, that is
    // when (1 - f) Dp + f Dq has Dp's sign or is zero (Dp and Dq have opposite signs or Dq is zero).
    if (sp == 0) return r;                      // at the query point itself: t = 0 < f
    if (sq == 0) return r.blocks = true, r;     // at the light: t = 1
    // In double first: the estimate of (1 - f) Dp + f Dq is off by at most the bounds' blend and its own
    // rounding; only when that cannot decide, exactly.
    double mix_estimate = (1 - self_shadow_fraction) * ep + self_shadow_fraction * eq;
    double mix_bound = (1 - self_shadow_fraction) * bp + self_shadow_fraction * bq + 4e-16 * (std::fabs(ep) + std::fabs(eq));
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
    for (int row = 0; row < 3; ++row) inv[9 + row] = -(r[row * 3] * m[9] + r[row * 3 + 1] * m[10] + r[row * 3 + 2] * m[11]);
    return true;
}

inline void apply_instance(const double* m, const double* p, double* out) {
    for (int k = 0; k < 3; ++k) out[k] = m[k] * p[0] + m[3 + k] * p[1] + m[6 + k] * p[2] + m[9 + k];
}

// Conservative: false only when the segment certainly misses the box (both ends beyond one face pair,
// with a margin far above the rounding of these dot products).
inline bool segment_may_touch_box(const Obb& box, const double* p, const double* q) {
    for (int i = 0; i < 3; ++i) {
        const double ax = box.axis[i][0], ay = box.axis[i][1], az = box.axis[i][2];
        double dp = (p[0] - box.center[0]) * ax + (p[1] - box.center[1]) * ay + (p[2] - box.center[2]) * az;
        double dq = (q[0] - box.center[0]) * ax + (q[1] - box.center[1]) * ay + (q[2] - box.center[2]) * az;
        double reach = box.half[i] + 1e-9 * (std::fabs(dp) + std::fabs(dq) + box.half[i]);
        if ((dp > reach && dq > reach) || (dp < -reach && dq < -reach)) return false;
    }
    return true;
}

// The shadow volume of a box seen from a point light, the building block of the clustered structure
// (the thesis's figure 2.7): four planes through the light that enclose every ray from the light through
// the box, closed by the box's distance from the light. Any point a triangle in the box can shadow lies
// inside: the blocking point X is in the box and p lies on the ray from the light through X, beyond X.
struct ShadowVolume {
    double normal[4][3];  // inside: dot(normal[k], p - light) >= 0 for every k (with a margin, see below)
    double near;          // no point closer than this to the light can be shadowed by the box
    bool valid;           // false: the light is inside or level with the box; test its cluster for every point
};

// Builds the volume; the light is in the box's frame. The planes come from the central projection of the
// box's 8 corners onto the plane across the direction to the box, bounded by a rectangle whose sides follow
// the box axis that looks longest from the light.
inline ShadowVolume make_shadow_volume(const Obb& box, const double* light) {
    ShadowVolume v{};
    double c[3] = {box.center[0], box.center[1], box.center[2]}, d[3], len = 0;
    for (int k = 0; k < 3; ++k) d[k] = c[k] - light[k], len += d[k] * d[k];
    len = std::sqrt(len);
    if (!(len > 0)) return v;
    for (double& x : d) x /= len;
    double corner[8][3];
    for (int i = 0; i < 8; ++i)
        for (int k = 0; k < 3; ++k)
            corner[i][k] = c[k] + (i & 1 ? 1 : -1) * double(box.half[0]) * box.axis[0][k] +
                           (i & 2 ? 1 : -1) * double(box.half[1]) * box.axis[1][k] +
                           (i & 4 ? 1 : -1) * double(box.half[2]) * box.axis[2][k] - light[k];
    // Every corner must be clearly in front of the light; otherwise no pyramid through the light holds the
    // box (the light is inside it or level with it): never build a wrong plane.
    double depth[8], reach = 0;
    for (int i = 0; i < 8; ++i) {
        depth[i] = corner[i][0] * d[0] + corner[i][1] * d[1] + corner[i][2] * d[2];
        reach = std::max(reach, std::sqrt(corner[i][0] * corner[i][0] + corner[i][1] * corner[i][1] + corner[i][2] * corner[i][2]));
    }
    for (double z : depth)
        if (!(z > 1e-6 * reach)) return v;
    // u: the box axis with the longest extent across the view direction, made perpendicular to it.
    double u[3] = {0, 0, 0}, best = -1;
    for (int i = 0; i < 3; ++i) {
        double a[3] = {box.axis[i][0], box.axis[i][1], box.axis[i][2]};
        double along = a[0] * d[0] + a[1] * d[1] + a[2] * d[2], w[3], wl = 0;
        for (int k = 0; k < 3; ++k) w[k] = a[k] - along * d[k], wl += w[k] * w[k];
        wl = std::sqrt(wl);
        if (wl * box.half[i] > best && wl > 1e-6) {
            best = wl * box.half[i];
            for (int k = 0; k < 3; ++k) u[k] = w[k] / wl;
        }
    }
    if (best < 0) {  // every axis along the view direction: any perpendicular will do
        double h[3] = {std::fabs(d[0]) < 0.6 ? 1.0 : 0.0, std::fabs(d[0]) < 0.6 ? 0.0 : 1.0, 0.0};
        double along = h[0] * d[0] + h[1] * d[1] + h[2] * d[2], wl = 0;
        for (int k = 0; k < 3; ++k) u[k] = h[k] - along * d[k], wl += u[k] * u[k];
        for (double& x : u) x /= std::sqrt(wl);
    }
    double w[3] = {d[1] * u[2] - d[2] * u[1], d[2] * u[0] - d[0] * u[2], d[0] * u[1] - d[1] * u[0]};
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (int i = 0; i < 8; ++i) {
        double x = (corner[i][0] * u[0] + corner[i][1] * u[1] + corner[i][2] * u[2]) / depth[i];
        double y = (corner[i][0] * w[0] + corner[i][1] * w[1] + corner[i][2] * w[2]) / depth[i];
        lo[0] = std::min(lo[0], x), hi[0] = std::max(hi[0], x), lo[1] = std::min(lo[1], y), hi[1] = std::max(hi[1], y);
    }
    // Widen the rectangle a little: the projections above round, and a plane must never cut the box.
    double slack = 1e-9 * (1 + std::max({std::fabs(lo[0]), std::fabs(hi[0]), std::fabs(lo[1]), std::fabs(hi[1])}));
    lo[0] -= slack, lo[1] -= slack, hi[0] += slack, hi[1] += slack;
    for (int k = 0; k < 3; ++k) {
        v.normal[0][k] = u[k] - lo[0] * d[k];   // x >= lo
        v.normal[1][k] = -u[k] + hi[0] * d[k];  // x <= hi
        v.normal[2][k] = w[k] - lo[1] * d[k];
        v.normal[3][k] = -w[k] + hi[1] * d[k];
    }
    // Closing distance: from the light to the nearest point of the box, shortened for rounding.
    double q[3] = {0, 0, 0}, dist2 = 0;
    for (int i = 0; i < 3; ++i) {
        double t = -(d[0] * box.axis[i][0] + d[1] * box.axis[i][1] + d[2] * box.axis[i][2]) * len;  // (light - c) . axis
        t = std::max(-double(box.half[i]), std::min(double(box.half[i]), t));
        for (int k = 0; k < 3; ++k) q[k] += t * box.axis[i][k];
    }
    for (int k = 0; k < 3; ++k) dist2 += (c[k] + q[k] - light[k]) * (c[k] + q[k] - light[k]);
    v.near = std::sqrt(dist2) * (1 - 1e-7);
    v.valid = true;
    return v;
}

// Conservative membership: true for every point a triangle in the box can shadow.
inline bool inside_shadow_volume(const ShadowVolume& v, const double* light, const double* p) {
    if (!v.valid) return true;
    double e[3] = {p[0] - light[0], p[1] - light[1], p[2] - light[2]};
    double dist = std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
    if (dist < v.near) return false;
    for (const double* n : v.normal) {
        double nl = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (n[0] * e[0] + n[1] * e[1] + n[2] * e[2] < -1e-9 * nl * dist) return false;
    }
    return true;
}

// True only when the light is clearly inside the cluster's front cone (the stored cone's cosine rounded up,
// plus a margin): then it sees every triangle of the cluster from the front.
inline bool light_in_front_cone(const Cone& c, const double* light) {
    if (!c.valid) return false;
    double v[3] = {light[0] - c.front_apex[0], light[1] - c.front_apex[1], light[2] - c.front_apex[2]};
    double a[3] = {c.axis[0], c.axis[1], c.axis[2]};
    double vl = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]), al = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    if (!(vl > 0) || !(al > 0)) return false;
    return v[0] * a[0] + v[1] * a[1] + v[2] * a[2] > al * vl * (double(c.cos_half_angle) + 1e-9);
}

struct QueryStats {
    uint64_t nodes_visited = 0;     // tree nodes (ClusterShadowTree only)
    uint64_t clusters_tested = 0;   // fine clusters whose triangles were tested
    uint64_t triangles_tested = 0;
    uint64_t touching = 0;          // queries whose answer involved a touching contact
};

// Reference query: every instance, every fine cluster whose box the segment may touch (all clusters when
// the asset has no fine boxes), every triangle of those, exactly. Returns true when p is in shadow.
// The triangles of fine cluster `f` (mesh-local) of `mesh`, in the mesh's frame, exactly; true at the first
// that blocks. Sets *touched when a tested triangle was touched.
inline bool cluster_blocks(const AssetView& v, const MeshRecord& mesh, uint32_t f, const double* p, const double* light,
                           bool one_sided, QueryStats* stats, bool* touched = nullptr) {
    const FineCluster& range = v.fine[mesh.first_fine + f];
    if (stats) ++stats->clusters_tested;
    for (uint32_t t = range.first_triangle; t < range.first_triangle + range.triangle_count; ++t) {
        uint32_t id[3];
        v.triangle(mesh, f, t, id);
        double corner[3][3];
        for (int k = 0; k < 3; ++k)
            for (int j = 0; j < 3; ++j) corner[k][j] = v.position(mesh, id[k])[j];
        if (stats) ++stats->triangles_tested;
        bool two_sided = !one_sided || v.double_sided(size_t(mesh.first_triangle) + t);
        SegmentTest s = segment_triangle(p, light, corner[0], corner[1], corner[2], two_sided);
        if (touched) *touched |= s.touching;
        if (s.blocks) return true;
    }
    return false;
}

inline bool occluded_reference(const AssetView& v, const double* p, const double* light, QueryStats* stats = nullptr,
                               bool one_sided = false) {
    bool touched = false, blocked = false;
    for (uint32_t i = 0; i < v.instance_count && !blocked; ++i) {
        const InstanceRecord& inst = v.instances[i];
        double inv[12], lp[3], ll[3];
        if (!invert_instance(inst.transform, inv)) continue;
        apply_instance(inv, p, lp);
        apply_instance(inv, light, ll);
        const MeshRecord& mesh = v.meshes[inst.mesh];
        for (uint32_t f = 0; f < mesh.fine_count && !blocked; ++f) {
            if (v.fine_bounds.obbs && !segment_may_touch_box(v.fine_bounds.obb(mesh.first_fine + f), lp, ll)) continue;
            blocked = cluster_blocks(v, mesh, f, lp, ll, one_sided, stats, &touched);
        }
    }
    if (stats && touched) ++stats->touching;
    return blocked;
}

}  // namespace cb
