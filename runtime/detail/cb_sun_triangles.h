// The test of one fine cluster's triangles against many points' rays toward a sun (cb_segment.h, "A sun"), as
// SunTraversal runs it (cluster_blocks_sun_points). Every ray runs along one direction d, so the test of the
// line through p against triangle edge u -> v, orient3d(p, p + d, u, v) = (p - v) . (d x (u - v)), is one
// dot product per point with a normal that the whole tile shares: set up once per group of up to 16
// triangles, in float, and settled against an error bound a vector of triangles an instruction. So is the
// side of the triangle's plane where the ray starts to count. A line that surely misses a triangle (two edge
// signs settled and opposite), or a ray that surely starts beyond its plane heading away from it, needs
// nothing else; nor does one that surely blocks (all three edge signs settled and alike, the start settled
// before the plane); the rest go to the exact ray_triangle. The answers are those of ray_triangle on each
// triangle. Header-only C++17, no dependencies, no exceptions, no allocation. MIT licensed (runtime/LICENSE).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "../cb_asset.h"
#include "../cb_segment.h"
#include "cb_exact.h"
#include "cb_lit_triangles.h"
#include "cb_math.h"
#include "cb_simd.h"

namespace cb {
inline namespace CB_LANES {
namespace sun_lit {

constexpr uint32_t capacity = lit::capacity;

// Up to 16 triangles of a cluster seen along a sun's direction. Triangle t's edge k runs from corner k (u) to
// corner j = k + 1 mod 3 (v), as in ray_triangle: with r = v - origin and q = p - origin, its edge sign for a
// point p is that of m . (q - r), m = d x (u - v).
//
// Error bound: m is computed in float from the unit direction rounded to float and the edge a float
// difference of float corners; q and r are rounded to float from their double values. With A = |d| x |u - v|
// (component x: |d_y e_z| + |d_z e_y|, at least |m_x|), each component of m is within 4.001 2^-24 A of the
// exact d x (u - v)'s (rounding d, the edge, the products and their difference), rounding q and r adds
// 2^-24 max(A) (|q|_1 + |r|_1), the two dot products at most 3 roundings of each term, and their difference
// one more: in all under 9.01 2^-24 max(A) (|q|_1 + |r|_1) = 5.4e-7 max(A) (|q|_1 + |r|_1). The bound takes
// 7e-7 (the float evaluation of the bound itself and of A stay within that room), plus 1e-30 for products
// that fall to float's subnormals (each off by at most 2^-149). An edge is usable (a finite bound) when
// 1e-18 <= max(A) <= 1e30 and |u - v|_1, |r|_1 <= 1e20; a point when |q|_1 <= 1e20 and |q|_1 max(A) <= 1e30
// for every usable edge: nothing overflows. The sign is that of the exact orientation for the direction d
// scaled by any positive factor, so the unit direction stands for the caller's.
//
// The plane test: with n = (b - a) x (c - a) and s the ray's start (p + from d, from the origin as q), the ray
// meets the plane at or after its start only if n . (s - r0) (r0: corner a from the origin) is 0 or has the
// sign opposite to n . d's. n is computed in float from float corners, within 5.01 2^-24 N of the exact one
// componentwise (N = |b - a| x |c - a| as A above); rounding s and r0 to float, the two dot products and their
// difference add 5.02 2^-24 max(N) (|s|_1 + |r0|_1): in all under 10.03 2^-24 = 6e-7 of that, taken as 8e-7
// (plus 1e-30 as above), with |s|_1 bounded by |q|_1 + |from d|_1 (the double sum's rounding is far below).
// Usable as an edge is, with N for A. The sign of n . d is the exact one.
struct SunTriangles {
    uint32_t count = 0;
    uint32_t may_block = 0;  // bit t: triangle t can block at all (not along the sun; one-sided, not facing it)
    uint32_t two_sided = 0;  // bit t: triangle t blocks from both sides
    const float* corner[capacity][3];
    double origin[3];  // corner 0 of the first triangle
    alignas(64) float mx[3][capacity], my[3][capacity], mz[3][capacity], w[3][capacity];  // w = m . r
    alignas(64) float slope[3][capacity], rest[3][capacity];  // bound = |q|_1 slope + rest (infinite: never settled)
    alignas(64) float nx[capacity], ny[capacity], nz[capacity], nw[capacity];  // the plane's n and n . r0
    alignas(64) float nslope[capacity], nrest[capacity];  // its bound = |s|_1 nslope + nrest (infinite: unusable)
    alignas(64) float heading[capacity];                  // the sign of n . d (+1, -1, 0), exactly
    float scale = 0;                                      // the largest usable max(A) or max(N)
};

// Triangles [first, first + count) of fine cluster c (count <= capacity), for the sun toward `toward` (the
// exact direction, in the mesh's frame) whose unit vector is `unit`.
inline void sun_triangles(const AssetView& v, const MeshRecord& mesh, const FineCluster& c, uint32_t first,
                          uint32_t count, const double* toward, const double* unit, bool one_sided, SunTriangles& out) {
    out.count = count;
    lit::cluster_corners(v, mesh, c, first, count, one_sided, out.corner, out.two_sided);
    for (int k = 0; k < 3; ++k) out.origin[k] = out.corner[0][0][k];
    // Corner k of each triangle from the origin, in float (zero past `count`: unusable edges, below).
    alignas(64) float rx[3][capacity] = {}, ry[3][capacity] = {}, rz[3][capacity] = {};
    alignas(64) float px[3][capacity] = {}, py[3][capacity] = {}, pz[3][capacity] = {}, r1[3][capacity] = {};
    out.may_block = 0;
    for (uint32_t t = 0; t < count; ++t) {
        double x[3][3];
        for (int k = 0; k < 3; ++k) {
            const float* at = out.corner[t][k];
            px[k][t] = at[0];
            py[k][t] = at[1];
            pz[k][t] = at[2];
            for (int j = 0; j < 3; ++j) x[k][j] = at[j];
            const double ox = x[k][0] - out.origin[0], oy = x[k][1] - out.origin[1], oz = x[k][2] - out.origin[2];
            rx[k][t] = float(ox);
            ry[k][t] = float(oy);
            rz[k][t] = float(oz);
            r1[k][t] = float((std::fabs(ox) + std::fabs(oy) + std::fabs(oz)) * 1.000001);
        }
        // The side of the plane the ray heads for, ray_triangle's det(-d, b - a, c - a) = -(n . d), exactly
        // (once per triangle: for a sun along a face, it is zero for every point). The ray runs along the plane
        // when it is zero, and never blocks; one-sided, a triangle whose front the sun sees never blocks.
        const double minus_d[3] = {-toward[0], -toward[1], -toward[2]};
        const exact::Row rows[3] = {{minus_d, nullptr}, {x[1], x[0]}, {x[2], x[0]}};
        const int sign = exact::det3_sign(rows);
        const bool blocks = sign == 1 || (sign == -1 && (out.two_sided >> t & 1));
        out.may_block |= uint32_t(blocks) << t;
        out.heading[t] = float(-sign);
    }
    const float dx = float(unit[0]), dy = float(unit[1]), dz = float(unit[2]);
    alignas(64) float widest[capacity] = {};
    for (int k = 0; k < 3; ++k) {
        const int j = (k + 1) % 3;
        for (uint32_t t = 0; t < capacity; ++t) {
            const float ex = px[k][t] - px[j][t], ey = py[k][t] - py[j][t], ez = pz[k][t] - pz[j][t];
            const float ax = std::fabs(dy * ez) + std::fabs(dz * ey), ay = std::fabs(dz * ex) + std::fabs(dx * ez),
                        az = std::fabs(dx * ey) + std::fabs(dy * ex);
            const float amax = std::max(std::max(ax, ay), az);
            const bool usable = t < count && amax >= 1e-18f && amax <= 1e30f &&
                std::fabs(ex) + std::fabs(ey) + std::fabs(ez) <= 1e20f && r1[j][t] <= 1e20f;
            const float mx = dy * ez - dz * ey, my = dz * ex - dx * ez, mz = dx * ey - dy * ex;
            out.mx[k][t] = mx;
            out.my[k][t] = my;
            out.mz[k][t] = mz;
            out.w[k][t] = mx * rx[j][t] + my * ry[j][t] + mz * rz[j][t];
            out.slope[k][t] = usable ? 7e-7f * amax : INFINITY;
            out.rest[k][t] = usable ? 7e-7f * amax * r1[j][t] + 1e-30f : INFINITY;
            widest[t] = std::max(widest[t], usable ? amax : 0.0f);
        }
    }
    for (uint32_t t = 0; t < capacity; ++t) {  // the planes
        const float ax = px[1][t] - px[0][t], ay = py[1][t] - py[0][t], az = pz[1][t] - pz[0][t];
        const float bx = px[2][t] - px[0][t], by = py[2][t] - py[0][t], bz = pz[2][t] - pz[0][t];
        const float nmax =
            std::max(std::max(std::fabs(ay * bz) + std::fabs(az * by), std::fabs(az * bx) + std::fabs(ax * bz)),
                     std::fabs(ax * by) + std::fabs(ay * bx));
        const bool usable = t < count && out.heading[t] != 0 && nmax >= 1e-18f && nmax <= 1e30f && r1[0][t] <= 1e20f;
        out.nx[t] = ay * bz - az * by;
        out.ny[t] = az * bx - ax * bz;
        out.nz[t] = ax * by - ay * bx;
        out.nw[t] = out.nx[t] * rx[0][t] + out.ny[t] * ry[0][t] + out.nz[t] * rz[0][t];
        out.nslope[t] = usable ? 8e-7f * nmax : INFINITY;
        out.nrest[t] = usable ? 8e-7f * nmax * r1[0][t] + 1e-30f : INFINITY;
        widest[t] = std::max(widest[t], usable ? nmax : 0.0f);
    }
    for (uint32_t half = capacity / 2; half > 0; half /= 2)
        for (uint32_t t = 0; t < half; ++t) widest[t] = std::max(widest[t], widest[t + half]);
    out.scale = widest[0];
}

// The triangles of `lit` that the float tests cannot rule out for the ray from p (bits; not the padding),
// which starts to count at p + lift (lift = from times the direction, from >= 0): a triangle is ruled out
// when two edge signs of the line are settled beyond their bounds and opposite, or when the ray's start lies
// beyond the triangle's plane (settled) on the side the ray heads to. `blocks` gets those of them that surely
// block: all three edge signs settled and alike (the line crosses the triangle's inside) and the start
// settled on the near side of the plane (the crossing comes after it), which is ray_triangle's block without
// a touching contact.
inline uint32_t sun_line_tests(const SunTriangles& lit, const double* p, const double* lift, uint32_t& blocks) {
    const uint32_t all = (1u << lit.count) - 1;  // (capacity < 32)
    blocks = 0;
    const double q0 = p[0] - lit.origin[0], q1 = p[1] - lit.origin[1], q2 = p[2] - lit.origin[2];
    const double q_l1 = std::fabs(q0) + std::fabs(q1) + std::fabs(q2);
    const double s_l1 = q_l1 + std::fabs(lift[0]) + std::fabs(lift[1]) + std::fabs(lift[2]);
    if (!(s_l1 <= 1e20 && s_l1 * lit.scale <= 1e30)) return all & lit.may_block;
    using simd::Floats;
    const Floats x = simd::splat(float(q0)), y = simd::splat(float(q1)), z = simd::splat(float(q2));
    const Floats sx = simd::splat(float(q0 + lift[0])), sy = simd::splat(float(q1 + lift[1])),
                 sz = simd::splat(float(q2 + lift[2]));
    const Floats l1 = simd::splat(float(q_l1 * 1.000001)), sl1 = simd::splat(float(s_l1 * 1.000001)),
                 zero = simd::splat(0.0f);
    uint32_t missed = 0, crossed = 0;
    for (uint32_t t = 0; t < lit.count; t += simd::width) {
        uint32_t positive = 0, negative = 0, all_positive = ~0u, all_negative = ~0u;
        for (int k = 0; k < 3; ++k) {
            const Floats o =
                simd::dot(x, y, z, simd::load(lit.mx[k] + t), simd::load(lit.my[k] + t), simd::load(lit.mz[k] + t)) -
                simd::load(lit.w[k] + t);
            const Floats bound = simd::fma(l1, simd::load(lit.slope[k] + t), simd::load(lit.rest[k] + t));
            const uint32_t above = simd::bits(o > bound), below = simd::bits(zero - o > bound);
            positive |= above;
            negative |= below;
            all_positive &= above;
            all_negative &= below;
        }
        const Floats side =
            simd::dot(sx, sy, sz, simd::load(lit.nx + t), simd::load(lit.ny + t), simd::load(lit.nz + t)) -
            simd::load(lit.nw + t);
        const Floats bound = simd::fma(sl1, simd::load(lit.nslope + t), simd::load(lit.nrest + t));
        const Floats heading = simd::load(lit.heading + t);
        const uint32_t ahead = simd::bits(side > bound), behind = simd::bits(zero - side > bound),
                       up = simd::bits(heading > zero), down = simd::bits(heading < zero);
        missed |= ((positive & negative) | (ahead & up) | (behind & down)) << t;
        crossed |= ((all_positive | all_negative) & ((behind & up) | (ahead & down))) << t;
    }
    blocks = all & lit.may_block & crossed;
    return all & lit.may_block & ~missed;
}

// sun_line_tests turned across: for the points p[i], i in `which`, a vector of points an instruction, one
// triangle at a time (lit::tile_points_line_tests does the same for a point light). Each point's floats are
// rounded from the same doubles as sun_line_tests rounds them, and each lane makes its operations, so the same
// answers: kept[i] for every point of `which` not surely blocked, and the points surely blocked (some
// triangle in sun_line_tests' `blocks`) returned.
inline uint64_t sun_points_line_tests(const SunTriangles& lit, const double (*p)[3], uint64_t which, const double* lift,
                                      uint32_t* kept) {
    const uint32_t all = ((1u << lit.count) - 1) & lit.may_block;
    alignas(64) float x[3][64], s[3][64], l1[64], sl1[64];
    uint32_t begin, end;
    simd::lane_span(which, begin, end);
    // Each point's floats as sun_line_tests makes them, the same double operations in double lanes (a point
    // not asked for stands at the origin).
    alignas(64) double at[3][64];
    for (uint32_t i = begin; i < end; ++i)
        for (int k = 0; k < 3; ++k) at[k][i] = which >> i & 1 ? p[i][k] : lit.origin[k];
    using simd::Doubles;
    const Doubles grow = simd::dsplat(1.000001), lift0 = simd::dsplat(std::fabs(lift[0])),
                  lift1 = simd::dsplat(std::fabs(lift[1])), lift2 = simd::dsplat(std::fabs(lift[2]));
    uint64_t usable = 0;
    for (uint32_t i = begin; i < end; i += simd::dwidth) {
        Doubles q[3];
        for (int k = 0; k < 3; ++k) {
            q[k] = simd::load(at[k] + i) - simd::dsplat(lit.origin[k]);
            simd::store_floats(x[k] + i, q[k]);
            simd::store_floats(s[k] + i, q[k] + simd::dsplat(lift[k]));
        }
        const Doubles q_l1 = simd::abs(q[0]) + simd::abs(q[1]) + simd::abs(q[2]);
        const Doubles s_l1 = q_l1 + lift0 + lift1 + lift2;
        simd::store_floats(l1 + i, q_l1 * grow);
        simd::store_floats(sl1 + i, s_l1 * grow);
        usable |=
            uint64_t(simd::bits((s_l1 <= simd::dsplat(1e20)) & (s_l1 * simd::dsplat(lit.scale) <= simd::dsplat(1e30))))
            << i;
    }
    usable &= which;
    using simd::Floats;
    const Floats zero = simd::splat(0.0f);
    uint64_t missed[capacity], crossed = 0, maybe = 0;
    for (uint32_t t = 0; t < lit.count; ++t) {
        missed[t] = ~uint64_t(0);
        if (!(all >> t & 1)) continue;
        const float heading = lit.heading[t];
        const bool up = heading > 0.0f, down = heading < 0.0f;
        uint64_t miss = 0;
        for (uint32_t i = begin; i < end; i += simd::width) {
            if (!simd::group(usable, i)) continue;
            const Floats qx = simd::load(x[0] + i), qy = simd::load(x[1] + i), qz = simd::load(x[2] + i),
                         ql1 = simd::load(l1 + i);
            uint32_t positive = 0, negative = 0, all_positive = ~0u, all_negative = ~0u;
            for (int k = 0; k < 3; ++k) {
                const Floats o = simd::dot(qx, qy, qz, simd::splat(lit.mx[k][t]), simd::splat(lit.my[k][t]),
                                           simd::splat(lit.mz[k][t])) -
                    simd::splat(lit.w[k][t]);
                const Floats bound = simd::fma(ql1, simd::splat(lit.slope[k][t]), simd::splat(lit.rest[k][t]));
                const uint32_t above = simd::bits(o > bound), below = simd::bits(zero - o > bound);
                positive |= above;
                negative |= below;
                all_positive &= above;
                all_negative &= below;
            }
            const Floats side = simd::dot(simd::load(s[0] + i), simd::load(s[1] + i), simd::load(s[2] + i),
                                          simd::splat(lit.nx[t]), simd::splat(lit.ny[t]), simd::splat(lit.nz[t])) -
                simd::splat(lit.nw[t]);
            const Floats bound = simd::fma(simd::load(sl1 + i), simd::splat(lit.nslope[t]), simd::splat(lit.nrest[t]));
            const uint32_t ahead = simd::bits(side > bound), behind = simd::bits(zero - side > bound);
            const uint32_t m = (positive & negative) | (up ? ahead : 0u) | (down ? behind : 0u);
            miss |= uint64_t(m) << i;
            crossed |= uint64_t((all_positive | all_negative) & ((up ? behind : 0u) | (down ? ahead : 0u))) << i;
        }
        missed[t] = miss | ~usable;
        maybe |= ~missed[t];
    }
    const uint64_t sure = crossed & usable;
    for (uint64_t w = which & ~sure; w; w &= w - 1) {
        const uint32_t i = math::lowest_bit(w);
        uint32_t k = all;
        if (maybe >> i & 1) {
            for (uint32_t t = 0; t < lit.count; ++t) k &= ~(uint32_t(missed[t] >> i & 1) << t);
        } else if (usable >> i & 1) {
            k = 0;
        }
        kept[i] = k;
    }
    return sure;
}

}  // namespace sun_lit

// Which of the points p[i], i in `which` (bits of a mask), the triangles of fine cluster `f` (mesh-local) of
// `mesh` shadow from the sun toward `toward` (in the mesh's frame; `unit` its unit vector), contacts counting
// from `from` on (sun_from): the same answers as ray_triangle on each triangle. The sun's terms are set up
// once for all the points, 16 triangles at a time.
inline uint64_t cluster_blocks_sun_points(const AssetView& v, const MeshRecord& mesh, uint32_t f, const double (*p)[3],
                                          uint64_t which, const double* toward, const double* unit, double from,
                                          bool one_sided, QueryStats* stats) {
    using namespace sun_lit;
    const FineCluster& c = v.fine[mesh.first_fine + f];
    const uint32_t points = math::bit_count(uint32_t(which)) + math::bit_count(uint32_t(which >> 32));
    if (stats) stats->clusters_tested += points;
    uint64_t blocked = 0;
    const double lift[3] = {from * toward[0], from * toward[1], from * toward[2]};
    SunTriangles lit;
    for (uint32_t first = 0; first < c.triangle_count && which; first += capacity) {
        const uint32_t count = std::min<uint32_t>(capacity, c.triangle_count - first);
        sun_triangles(v, mesh, c, first, count, toward, unit, one_sided, lit);
        if (stats) stats->triangles_tested += uint64_t(count) * points;
        // Across the points where that takes fewer vector steps (as lit::tile_points_line_tests).
        uint32_t kept[64];
        const uint32_t left = math::bit_count(uint32_t(which)) + math::bit_count(uint32_t(which >> 32));
        const bool across = left * lit::triangle_steps(count) >= count * lit::lane_groups(which);
        const uint64_t sure = across ? sun_points_line_tests(lit, p, which, lift, kept) : 0;
        blocked |= sure;
        for (uint64_t b = which & ~sure; b; b &= b - 1) {
            const uint32_t i = math::lowest_bit(b);
            uint32_t blocks = 0;
            const uint32_t candidates = across ? kept[i] : sun_line_tests(lit, p[i], lift, blocks);
            if (blocks) {
                blocked |= uint64_t(1) << i;
                continue;
            }
            for (uint32_t m = candidates; m; m &= m - 1) {
                const uint32_t t = math::lowest_bit(m);
                double x[3][3];
                for (int k = 0; k < 3; ++k)
                    for (int j = 0; j < 3; ++j) x[k][j] = lit.corner[t][k][j];
                if (ray_triangle(p[i], toward, x[0], x[1], x[2], from, lit.two_sided >> t & 1).blocks) {
                    blocked |= uint64_t(1) << i;
                    break;
                }
            }
        }
        which &= ~blocked;
    }
    return blocked;
}

}  // namespace CB_LANES
}  // namespace cb
