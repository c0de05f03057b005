// The test of one fine cluster's triangles against many points' segments to one light, as every query
// runs it (cluster_blocks_points), and the parts it is made of (namespace cb::lit): a group of up to 16
// triangles set up once for the light (light_triangles), float filters whose error bounds settle most signs
// a vector an instruction, double filters for the rest, and the exact test (cb_segment.h) for what neither
// settles. The answers are those of cb::segment_triangle on each triangle; the bounds each filter keeps are
// its contract (tests check them against exact predicates). Header-only C++17, no dependencies, no
// exceptions, no allocation. MIT licensed (runtime/LICENSE).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "../cb_asset.h"
#include "cb_exact.h"
#include "cb_math.h"
#include "../cb_segment.h"
#include "cb_simd.h"

namespace cb {
inline namespace CB_LANES {
namespace lit {

// Each determinant below is a sum of products of three differences of doubles, computed with 8 roundings
// per product: its error is at most 8 eps times the sum of the absolute products, itself at most the
// product of the three L1 norms. 2e-15 is 18 eps (eps = 2^-53): double that, with room for the norms' own
// rounding.
constexpr double det_error = 2e-15;

// The exact answer for one triangle (cb::segment_triangle) when the double filter cannot decide.
inline SegmentTest exact_triangle(const double* p, const double* light, const float* const* corner, bool two_sided,
                                  double from) {
    double c[3][3];
    for (int k = 0; k < 3; ++k)
        for (int j = 0; j < 3; ++j) c[k][j] = corner[k][j];
    return segment_triangle(p, light, c[0], c[1], c[2], from, two_sided);
}

// Up to 16 triangles of a cluster seen from the light: the terms every segment test from that light shares.
// Triangle t's edge k runs from corner k to corner k + 1 (mod 3); with u and v its corners relative to the
// light, the plane through the light and the edge has normal u x v, and for a point p (e = p - light)
// orient3d(p, light, corner k, corner k + 1) = e . (u x v): one dot product per edge and point. Edge-major
// arrays, so that the line test runs over several triangles per instruction.
constexpr uint32_t capacity = 16;  // a fine cluster of the default size (larger ones take several)
static_assert(capacity < 32 && capacity % simd::width == 0 && (capacity & (capacity - 1)) == 0,
              "triangles are bits of a uint32_t, in whole lane groups; a power of two (light_triangles halves it)");

// The rest of a triangle's terms from the light, in double, for the points whose line the float test cannot
// rule out: per edge k, the normal n[k] = u x v and scale[k] = |u|_1 |v|_1 (times det_error |e|_1, it bounds
// the double dot product's error); the triangle's plane about corner a, N = (b - a) x (c - a), with
// orient3d(a, b, c, x) = N . (a - x) within plane_bound |a - x|_1 (the same products of three differences
// as about x, taken about a instead); the light's side dq and its bound bq.
struct TriangleTerms {
    double n[3][3], scale[3];
    double plane[3], plane_bound, a[3], dq, bq;
};

struct Triangles {
    uint32_t count = 0;
    const float* corner[capacity][3];
    uint32_t two_sided;  // bit t: triangle t blocks from both sides (always, unless one-sided and not double-sided)
    // The edge plane normals in float, for a first line test a vector of triangles an instruction; times |e|_1,
    // fbound bounds the float dot product's distance from the exact value (infinite: never settled in float).
    alignas(64) float fx[3][capacity], fy[3][capacity], fz[3][capacity], fbound[3][capacity];
    double max_scale = 0;  // the largest max(A) of the usable edges (light_triangles): |e|_1 times it bounds
                           // their float dot products
    // The triangle planes in float, for a first test of the segment's crossing a vector of triangles an
    // instruction (light_triangles): the normal N, the light's side dq = N . (a - light), and bounds (infinite:
    // never settled in float): dq is within qbound of the exact value, and the crossing test's value within
    // qbound + |e|_1 pbound. plane_scale: the largest max(A) of the usable planes.
    alignas(64) float nx[capacity], ny[capacity], nz[capacity], dq[capacity], qbound[capacity], pbound[capacity];
    double plane_scale = 0;
    // A triangle's double terms, made when a point first needs them: most points' lines miss every triangle in
    // float, and on large meshes a group is often set up for one or two points. The plane's (plane_terms)
    // whenever the line may meet it; the edges' (edge_terms) only when the float test left an edge's sign
    // unsettled (a line through the interior needs none).
    uint32_t has_plane = 0, has_edges = 0;  // bit t: terms[t]'s plane, edges are made
    TriangleTerms terms[capacity];
    // Whether the group is flat (a floor's, a CAD face's): every corner v within flat_thick of the plane
    // n . v = flat_d, in double with its rounding bounded (group_plane, made when a point first needs double
    // work). Points lying on such a group leave it too closely for the float tests to settle under a grazing
    // light; one plane test each then settles the whole group (beside_flat).
    bool flat_known = false, flat = false;
    double flat_n[3] = {0, 0, 0}, flat_d = 0, flat_thick = 0;
};

// 1e-15 times the sum of the terms' magnitudes bounds the rounding of n . x - d (3 products and 3 sums: under
// 4 2^-53 of it).
constexpr double plane_error = 1e-15;

// x's offset n . x - d from a plane, in double, and in `bound` a bound on its rounding (group_plane, beside_flat).
template <class T>
inline double plane_offset(const double* n, double d, const T* x, double& bound) {
    bound = plane_error * (std::fabs(n[0] * x[0]) + std::fabs(n[1] * x[1]) + std::fabs(n[2] * x[2]) + std::fabs(d));
    return n[0] * x[0] + n[1] * x[1] + n[2] * x[2] - d;
}

// Whether the group lies in one plane to within a millionth of its size, and which: the normal of its largest
// triangle (a cross product of the float corners' differences, in double) and every corner's offset from it,
// each widened by its rounding. Only a group whose float normals all lie within about a thousandth of a
// radian of the first triangle's is looked at (a gate, never an answer): a curved mesh's groups stop there.
inline void group_plane(Triangles& out) {
    out.flat_known = true;
    out.flat = false;
    using simd::Floats;
    const Floats n0x = simd::splat(out.nx[0]), n0y = simd::splat(out.ny[0]), n0z = simd::splat(out.nz[0]);
    const Floats n0 = simd::abs(n0x) + simd::abs(n0y) + simd::abs(n0z);
    uint32_t aligned = 0;
    for (uint32_t t = 0; t < capacity; t += simd::width) {
        const Floats x = simd::load(out.nx + t), y = simd::load(out.ny + t), z = simd::load(out.nz + t);
        const Floats off = simd::abs(y * n0z - z * n0y) + simd::abs(z * n0x - x * n0z) + simd::abs(x * n0y - y * n0x);
        const Floats size = simd::abs(x) + simd::abs(y) + simd::abs(z);
        aligned |= simd::bits(off <= simd::splat(1e-3f) * size * n0) << t;
    }
    if ((aligned | ~((1u << out.count) - 1)) != ~0u) return;
    double best = 0, n[3] = {0, 0, 0};
    const float* base = nullptr;
    for (uint32_t t = 0; t < out.count; ++t) {
        const float *a = out.corner[t][0], *b = out.corner[t][1], *c = out.corner[t][2];
        const double b0 = double(b[0]) - a[0], b1 = double(b[1]) - a[1], b2 = double(b[2]) - a[2];
        const double c0 = double(c[0]) - a[0], c1 = double(c[1]) - a[1], c2 = double(c[2]) - a[2];
        const double m[3] = {b1 * c2 - b2 * c1, b2 * c0 - b0 * c2, b0 * c1 - b1 * c0};
        const double area2 = m[0] * m[0] + m[1] * m[1] + m[2] * m[2];  // (twice the area) squared
        if (area2 > best) {
            best = area2;
            std::copy(m, m + 3, n);
            base = a;
        }
    }
    if (!(best > 0 && best < INFINITY)) return;  // no triangle with an area (or not finite)
    const double d = n[0] * base[0] + n[1] * base[1] + n[2] * base[2];
    double thick = 0, size = 0;
    for (uint32_t t = 0; t < out.count; ++t)
        for (int k = 0; k < 3; ++k) {
            const float* v = out.corner[t][k];
            double bound;
            const double r = plane_offset(n, d, v, bound);
            thick = std::max(thick, std::fabs(r) + bound);
            size = std::max(size,
                            std::fabs(double(v[0]) - base[0]) + std::fabs(double(v[1]) - base[1]) +
                                std::fabs(double(v[2]) - base[2]));
        }
    out.flat = thick < 1e-6 * (std::fabs(n[0]) + std::fabs(n[1]) + std::fabs(n[2])) * size;  // NaN: not flat
    std::copy(n, n + 3, out.flat_n);
    out.flat_d = d;
    out.flat_thick = thick;
}

// The points p[i], i in `which`, whose segment stays beyond flat group `lit`'s plane on the light's side from
// where contacts start to count (from[i]) to the light: they meet none of its triangles. The segment's offset
// from the plane is linear along it, (1 - f) s_p + f s_q at fraction f, so its two ends decide; each offset
// is bounded with its rounding, and has to clear the corners' flat_thick.
inline uint64_t beside_flat(const Triangles& lit, const double (*p)[3], const double* from, uint64_t which,
                            const double* light) {
    const double *n = lit.flat_n, d = lit.flat_d, thick = lit.flat_thick;
    double bq;
    const double sq = plane_offset(n, d, light, bq);
    if (!(std::fabs(sq) - bq > thick)) return 0;  // the light by the plane (or not finite)
    uint64_t beside = 0;
    for (uint64_t w = which; w; w &= w - 1) {
        const uint32_t i = math::lowest_bit(w);
        const double f = from[i];
        if (!(f >= 0 && f <= 1)) continue;
        double bp;
        const double sp = plane_offset(n, d, p[i], bp);
        const double s = (1 - f) * sp + f * sq,
                     bound = (1 - f) * bp + f * bq + plane_error * (std::fabs(sp) + std::fabs(sq));
        beside |= uint64_t(std::fabs(s) - bound > thick && (s > 0) == (sq > 0)) << i;
    }
    return beside;
}

// Triangle t's corners, and their offsets from the light.
inline void triangle_corners(const Triangles& lit, uint32_t t, const double* light, double (&p)[3][3],
                             double (&u)[3][3]) {
    for (int k = 0; k < 3; ++k)
        for (int j = 0; j < 3; ++j) {
            p[k][j] = lit.corner[t][k][j];
            u[k][j] = p[k][j] - light[j];
        }
}

// Triangle t's plane terms, from its corners.
inline void plane_terms(const Triangles& lit, uint32_t t, const double* light, TriangleTerms& out) {
    double p[3][3], u[3][3];
    triangle_corners(lit, t, light, p, u);
    const double e1x = p[1][0] - p[0][0], e1y = p[1][1] - p[0][1], e1z = p[1][2] - p[0][2];
    const double e2x = p[2][0] - p[0][0], e2y = p[2][1] - p[0][1], e2z = p[2][2] - p[0][2];
    out.plane[0] = e1y * e2z - e1z * e2y;
    out.plane[1] = e1z * e2x - e1x * e2z;
    out.plane[2] = e1x * e2y - e1y * e2x;
    out.plane_bound = det_error * (std::fabs(e1x) + std::fabs(e1y) + std::fabs(e1z)) *
        (std::fabs(e2x) + std::fabs(e2y) + std::fabs(e2z));
    for (int j = 0; j < 3; ++j) out.a[j] = p[0][j];
    // orient3d(a, b, c, light) = N . (a - light), a - light being corner 0's offset from the light.
    out.dq = out.plane[0] * u[0][0] + out.plane[1] * u[0][1] + out.plane[2] * u[0][2];
    out.bq = out.plane_bound * (std::fabs(u[0][0]) + std::fabs(u[0][1]) + std::fabs(u[0][2]));
}

// Triangle t's edge terms, from its corners.
inline void edge_terms(const Triangles& lit, uint32_t t, const double* light, TriangleTerms& out) {
    double p[3][3], u[3][3], u1[3];
    triangle_corners(lit, t, light, p, u);
    for (int k = 0; k < 3; ++k) u1[k] = std::fabs(u[k][0]) + std::fabs(u[k][1]) + std::fabs(u[k][2]);
    for (int k = 0; k < 3; ++k) {
        const int j = (k + 1) % 3;
        out.n[k][0] = u[k][1] * u[j][2] - u[k][2] * u[j][1];
        out.n[k][1] = u[k][2] * u[j][0] - u[k][0] * u[j][2];
        out.n[k][2] = u[k][0] * u[j][1] - u[k][1] * u[j][0];
        out.scale[k] = u1[k] * u1[j];
    }
}

// Asks for the memory light_triangles reads for fine cluster c, in two steps a few cluster tests apart
// (each needs what the previous one asked for): step 0 its local triangles, new vertices and references
// (from its record), step 1 the vertices it reuses (from its references). On meshes far larger than the
// cache these reads otherwise miss one after another, each waiting on the last.
inline void prefetch(const AssetView& v, const MeshRecord& mesh, const FineCluster& c, int step) {
    if (step == 0) {
        const uint8_t* local = v.triangles + (size_t(mesh.first_triangle) + c.first_triangle) * 3;
        simd::prefetch(local);
        simd::prefetch(local + std::min<uint32_t>(c.triangle_count, capacity) * 3 - 1);
        const char* from = reinterpret_cast<const char*>(v.position(mesh, c.first_vertex));
        for (uint32_t b = 0; b < uint32_t(c.vertex_count) * 12; b += 64) simd::prefetch(from + b);
        if (c.vertex_count) simd::prefetch(from + uint32_t(c.vertex_count) * 12 - 1);
        if (c.ref_count) simd::prefetch(v.vertex_refs + size_t(mesh.first_ref) + c.first_ref);
    } else {
        const uint16_t* back = v.vertex_refs + size_t(mesh.first_ref) + c.first_ref;
        for (uint32_t r = 0; r < c.ref_count; ++r) simd::prefetch(v.position(mesh, c.first_vertex - back[r]));
    }
}

// The corners of triangles [first, first + count) of fine cluster c (count <= capacity), and in bit t of
// `two_sided` whether triangle t blocks from both sides (always, unless one-sided and not double-sided).
inline void cluster_corners(const AssetView& v, const MeshRecord& mesh, const FineCluster& c, uint32_t first,
                            uint32_t count, bool one_sided, const float* (*corner)[3], uint32_t& two_sided) {
    const uint8_t* local = v.triangles + (size_t(mesh.first_triangle) + c.first_triangle + first) * 3;
    // The cluster's vertex list (its new vertices, then those it reuses), resolved once rather than per corner.
    const float* list[max_cluster_vertices];
    const float* fresh = v.position(mesh, c.first_vertex);
    for (uint32_t i = 0; i < c.vertex_count; ++i) list[i] = fresh + size_t(i) * 3;
    const uint16_t* back = v.vertex_refs + size_t(mesh.first_ref) + c.first_ref;
    for (uint32_t r = 0; r < c.ref_count; ++r) list[c.vertex_count + r] = v.position(mesh, c.first_vertex - back[r]);
    two_sided = 0;
    for (uint32_t t = 0; t < count; ++t) {
        for (int k = 0; k < 3; ++k) corner[t][k] = list[local[t * 3 + k]];
        two_sided |= uint32_t(!one_sided || v.double_sided(size_t(mesh.first_triangle) + c.first_triangle + first + t))
            << t;
    }
}

// The terms of out.count triangles (out.corner) from the light, in loops over the triangles that the compiler
// runs several to an instruction.
inline void light_terms(const double* light, Triangles& out) {
    const uint32_t count = out.count;
    // Corner k of each triangle (zero past `count`: such edges are unusable, below).
    alignas(64) float px[3][capacity] = {}, py[3][capacity] = {}, pz[3][capacity] = {};
    for (uint32_t t = 0; t < count; ++t)
        for (int k = 0; k < 3; ++k) {
            px[k][t] = out.corner[t][k][0];
            py[k][t] = out.corner[t][k][1];
            pz[k][t] = out.corner[t][k][2];
        }
    // Edge k runs from corner k to corner j = k + 1; with u = corner k - light, the plane through the light and
    // the edge has normal u x (corner j - corner k), equal to u x v. In float, a vector of triangles an
    // instruction: u rounded from its double value, the edge a float difference of two floats (each within
    // 2^-24 of itself, past float's subnormals), the cross product N with 2 roundings per component. With
    // A = |u| x |edge| (component x: |u_y edge_z| + |u_z edge_y|; N's components are at most A's), each
    // component of N is within 4 2^-24 A of the exact normal's, and the point test's dot product with e in
    // float adds 4 2^-24 |e|_1 max(N) at most (rounding e, and its own 3 roundings): in all under
    // 8 2^-24 |e|_1 max(A) = 4.8e-7 |e|_1 max(A), and fbound = 6e-7 max(A). An edge is unusable (an infinite
    // bound: never settled in float) unless 1e-18 <= max(A) <= 1e30 and |edge|_1 <= 1e20: then products and
    // results that fall to float's subnormals (each off by at most 2^-150) stay far within the bound, and
    // nothing overflows.
    // Each corner's offset from the light, rounded from its double value (the edges' u, and the plane's below).
    alignas(64) float ox[3][capacity], oy[3][capacity], oz[3][capacity];
    for (int k = 0; k < 3; ++k)
        for (uint32_t t = 0; t < capacity; ++t) {
            ox[k][t] = float(double(px[k][t]) - light[0]);
            oy[k][t] = float(double(py[k][t]) - light[1]);
            oz[k][t] = float(double(pz[k][t]) - light[2]);
        }
    // In lanes of triangles, written out: the compiler leaves this loop's selects as branches, one triangle at a
    // time. max(b, a) of the lanes is std::max(a, b), NaN included (the second operand when unordered).
    alignas(64) float widest[capacity];  // per triangle, its usable edges' largest max(A)
    using simd::Floats;
    const Floats zero = simd::splat(0.0f);
    for (uint32_t t = 0; t < capacity; t += simd::width) {
        Floats wide = zero;
        for (int k = 0; k < 3; ++k) {
            const int j = (k + 1) % 3;
            const Floats ux = simd::load(ox[k] + t), uy = simd::load(oy[k] + t), uz = simd::load(oz[k] + t);
            const Floats ex = simd::load(px[j] + t) - simd::load(px[k] + t),
                         ey = simd::load(py[j] + t) - simd::load(py[k] + t),
                         ez = simd::load(pz[j] + t) - simd::load(pz[k] + t);
            const Floats ax = simd::abs(uy * ez) + simd::abs(uz * ey), ay = simd::abs(uz * ex) + simd::abs(ux * ez),
                         az = simd::abs(ux * ey) + simd::abs(uy * ex);
            const Floats amax = simd::max(az, simd::max(ay, ax));
            const simd::Mask usable = (amax >= simd::splat(1e-18f)) & (amax <= simd::splat(1e30f)) &
                (simd::abs(ex) + simd::abs(ey) + simd::abs(ez) <= simd::splat(1e20f));
            simd::store(out.fx[k] + t, uy * ez - uz * ey);
            simd::store(out.fy[k] + t, uz * ex - ux * ez);
            simd::store(out.fz[k] + t, ux * ey - uy * ex);
            simd::store(out.fbound[k] + t, simd::select(usable, simd::splat(6e-7f) * amax, simd::splat(INFINITY)));
            wide = simd::max(simd::select(usable, amax, zero), wide);
        }
        simd::store(widest + t, wide);
    }
    // The plane about corner a, N = (b - a) x (c - a), in float from float differences of the float corners:
    // with A = |b - a| x |c - a|, each component of N is within 4 2^-24 A of the exact normal's (two rounded
    // differences, two rounded products and a rounded difference), as for the edges above. So dq = N . u
    // (u = a - light rounded from double) is within 8 2^-24 |u|_1 max(A) of the exact value, and a point's
    // N . e within 8 2^-24 |e|_1 max(A); the crossing test's value dq - (1 - f) N . e (f the point's `from`,
    // 1 - f rounded to float: within 2^-25 of its value in [0, 1]) adds that and two roundings, under
    // 2.5 2^-24 max(A) (|u|_1 + |e|_1). In all under 6.3e-7 max(A) (|u|_1 + |e|_1): the bounds take 9e-7, plus
    // 1e-30 for products that fall to
    // float's subnormals. Usable as the edges are, and when qbound <= 1e30 (nothing overflows).
    alignas(64) float flat[capacity] = {};  // per triangle, its plane's max(A) if usable
    for (uint32_t t = 0; t < capacity; ++t) {
        const float ux = ox[0][t], uy = oy[0][t], uz = oz[0][t];
        const float bx = px[1][t] - px[0][t], by = py[1][t] - py[0][t], bz = pz[1][t] - pz[0][t];
        const float cx = px[2][t] - px[0][t], cy = py[2][t] - py[0][t], cz = pz[2][t] - pz[0][t];
        const float ax = std::fabs(by * cz) + std::fabs(bz * cy), ay = std::fabs(bz * cx) + std::fabs(bx * cz),
                    az = std::fabs(bx * cy) + std::fabs(by * cx);
        const float amax = std::max(std::max(ax, ay), az), u_l1 = std::fabs(ux) + std::fabs(uy) + std::fabs(uz);
        const float qbound = 9e-7f * amax * (u_l1 * 1.000001f) + 1e-30f, pbound = 9e-7f * amax;
        const bool usable = (amax >= 1e-18f) & (amax <= 1e30f) & (u_l1 <= 1e20f) & (qbound <= 1e30f);
        const float nx = by * cz - bz * cy, ny = bz * cx - bx * cz, nz = bx * cy - by * cx;
        out.nx[t] = nx;
        out.ny[t] = ny;
        out.nz[t] = nz;
        out.dq[t] = nx * ux + ny * uy + nz * uz;
        out.qbound[t] = usable ? qbound : INFINITY;
        out.pbound[t] = usable ? pbound : INFINITY;
        flat[t] = usable ? amax : 0.0f;
    }
    // The largest, halving the arrays each step (a loop carrying one maximum would not run as vectors).
    for (uint32_t half = capacity / 2; half > 0; half /= 2)
        for (uint32_t t = 0; t < half; ++t) {
            widest[t] = std::max(widest[t], widest[t + half]);
            flat[t] = std::max(flat[t], flat[t + half]);
        }
    out.max_scale = widest[0];
    out.plane_scale = flat[0];
    out.has_plane = out.has_edges = 0;
    out.flat_known = out.flat = false;
}

// The triangles of `lit` that no segment ending at the light can meet: the light lies exactly in the
// triangle's plane, outside the closed triangle, or the triangle has no area. A segment from a point off that
// plane meets it only at the light, outside the triangle; one from a point in it is edge-on, which never
// blocks (segment_triangle), nor does a triangle with no area. A light in the plane of a floor or of a CAD
// face, with points on that face, otherwise leaves every line within rounding of those triangles' edges, and
// every such pair goes to the exact test. Only the triangles of `unsettled`, whose light side the float plane
// test leaves unsettled, are looked at, with exact signs: x, the light moved along an axis, is off the plane unless the
// normal's component along that axis is zero; and the line through a point off the plane and the light passes
// outside the closed triangle for every such point when it does for x.
inline uint32_t edge_on_triangles(const Triangles& lit, const double* light, uint32_t unsettled) {
    uint32_t edge_on = 0;
    const double reach = std::max({std::fabs(light[0]), std::fabs(light[1]), std::fabs(light[2])});
    if (!(reach < 1e30)) return 0;  // the exact products stay far from overflow
    for (uint32_t m = unsettled; m; m &= m - 1) {
        const uint32_t t = math::lowest_bit(m);
        double p[3][3];
        for (int k = 0; k < 3; ++k)
            for (int j = 0; j < 3; ++j) p[k][j] = lit.corner[t][k][j];
        if (!(std::isfinite(p[0][0] + p[0][1] + p[0][2] + p[1][0] + p[1][1] + p[1][2] + p[2][0] + p[2][1] + p[2][2])) ||
            exact::orient3d(p[0], p[1], p[2], light) != 0)
            continue;
        // The axes in the order of the float normal's components, largest first (usually the first is off).
        const float n[3] = {std::fabs(lit.nx[t]), std::fabs(lit.ny[t]), std::fabs(lit.nz[t])};
        const int first = n[0] >= n[1] && n[0] >= n[2] ? 0 : n[1] >= n[2] ? 1 : 2;
        double x[3];
        bool off = false;
        for (int a = 0; a < 3 && !off; ++a) {
            const int k = (first + a) % 3;
            std::copy(light, light + 3, x);
            x[k] += std::max(1.0, std::fabs(x[k]));
            off = exact::orient3d(p[0], p[1], p[2], x) != 0;
        }
        if (!off) {  // no area
            edge_on |= 1u << t;
            continue;
        }
        const int e0 = exact::orient3d(x, light, p[0], p[1]), e1 = exact::orient3d(x, light, p[1], p[2]),
                  e2 = exact::orient3d(x, light, p[2], p[0]);
        edge_on |= uint32_t((e0 > 0 || e1 > 0 || e2 > 0) && (e0 < 0 || e1 < 0 || e2 < 0)) << t;
    }
    return edge_on;
}

// Leaves out of `lit` its triangles edge-on to the light (edge_on_triangles, over `unsettled`), if any, and
// makes the terms of the others again. Rare, and kept out of the inlined set-up.
[[gnu::noinline]] inline void leave_out_edge_on(const double* light, uint32_t unsettled, Triangles& lit) {
    const uint32_t edge_on = edge_on_triangles(lit, light, unsettled);
    if (!edge_on) return;
    uint32_t kept = 0, two_sided = 0;
    for (uint32_t t = 0; t < lit.count; ++t) {
        if (edge_on >> t & 1) continue;
        std::copy(lit.corner[t], lit.corner[t] + 3, lit.corner[kept]);
        two_sided |= (lit.two_sided >> t & 1) << kept;
        ++kept;
    }
    lit.count = kept;
    lit.two_sided = two_sided;
    light_terms(light, lit);
}

// Triangles [first, first + count) of fine cluster c (count <= capacity), from the light: the corners
// gathered first, then their terms; triangles edge-on to the light are left out (leave_out_edge_on), looked at
// only when the float plane test leaves the light's side of some triangle unsettled.
inline void light_triangles(const AssetView& v, const MeshRecord& mesh, const FineCluster& c, uint32_t first,
                            uint32_t count, const double* light, bool one_sided, Triangles& out) {
    out.count = count;
    cluster_corners(v, mesh, c, first, count, one_sided, out.corner, out.two_sided);
    light_terms(light, out);
    uint32_t unsettled = 0;  // the triangles whose light side the float plane test leaves open
    for (uint32_t t = 0; t < capacity; ++t) unsettled |= uint32_t(!(std::fabs(out.dq[t]) > out.qbound[t])) << t;
    unsettled &= (1u << count) - 1;
    if (unsettled) leave_out_edge_on(light, unsettled, out);
}

// orient3d(a, b, c, x) for a triangle with `terms`, in double, and a bound on its error in `bound`.
inline double plane_side(const TriangleTerms& terms, const double* x, double& bound) {
    const double d0 = terms.a[0] - x[0], d1 = terms.a[1] - x[1], d2 = terms.a[2] - x[2];
    bound = terms.plane_bound * (std::fabs(d0) + std::fabs(d1) + std::fabs(d2));
    return terms.plane[0] * d0 + terms.plane[1] * d1 + terms.plane[2] * d2;
}

// Whether the float line test (light_triangles' bounds) holds for a point with |e|_1 = l1: nothing overflows,
// and e is far above float's subnormals.
inline bool line_test_usable(double l1, double max_scale) {
    return l1 * max_scale < 1e30 && l1 * max_scale > 1e-20 && l1 > 1e-30;
}

// The float plane test (light_triangles' bounds): whether a point with |e|_1 = l1 keeps its products in
// range, and its crossing value mix = dq - (1 - f) N . e (keep = 1 - f in float, f its `from`) settled above
// (up) or below (down) its bound qbound + |e|_1 pbound, a vector an instruction (of triangles, or of points).
inline bool plane_test_usable(double l1, double plane_scale) {
    return l1 > 1e-30 && l1 * plane_scale < 1e30 && l1 * plane_scale > 1e-20;
}
inline void crossing_signs(simd::Floats ex, simd::Floats ey, simd::Floats ez, simd::Floats vl, simd::Floats nx,
                           simd::Floats ny, simd::Floats nz, simd::Floats dq, simd::Floats qbound, simd::Floats pbound,
                           simd::Floats keep, simd::Mask& up, simd::Mask& down) {
    const simd::Floats mix = simd::fma(simd::splat(0.0f) - keep, simd::dot(ex, ey, ez, nx, ny, nz), dq);
    const simd::Floats bound = simd::fma(vl, pbound, qbound);
    up = mix > bound;
    down = -mix > bound;
}

// The first step of triangles_block, for the points p[i], i in `which` (bits of a mask): in may_meet[i],
// the triangles of `lit` whose line through p[i] and the light it cannot rule out (bit t: not every edge
// sign settled beyond its bound, or all alike); in through[i], those the line surely passes through the
// interior of (every edge sign settled and alike). In float, a vector of triangles an instruction, and only
// when nothing can overflow and e = p - light is far above float's subnormals (products that fall there are
// covered by the 1e-30 absolute term); otherwise every triangle may meet the line, and the double loop
// decides. One pass over all the points, apart from the double work: its loads stay in registers. Returns
// the points whose segment surely crosses a triangle that blocks (the line through its interior, the plane
// crossed from f on, and the triangle two-sided or the light behind it): their answer is known. The others
// with some triangle left in may_meet go in *candidates.
inline uint64_t line_tests(const Triangles& lit, const double (*p)[3], const double* from, uint64_t which,
                           const double* light, uint32_t* may_meet, uint32_t* through, uint64_t* candidates) {
    const uint32_t all = (1u << lit.count) - 1;  // (capacity < 32)
    const simd::Floats tiny = simd::splat(1e-30f), zero = simd::splat(0.0f);
    uint64_t blocked = 0, left = 0;
    for (; which; which &= which - 1) {
        const uint32_t i = math::lowest_bit(which);
        const double e0 = p[i][0] - light[0], e1 = p[i][1] - light[1], e2 = p[i][2] - light[2];
        const double e_l1 = std::fabs(e0) + std::fabs(e1) + std::fabs(e2);
        may_meet[i] = all;
        through[i] = 0;
        if (!line_test_usable(e_l1, lit.max_scale)) {
            left |= uint64_t(1) << i;
            continue;
        }
        const simd::Floats v0 = simd::splat(float(e0)), v1 = simd::splat(float(e1)), v2 = simd::splat(float(e2));
        const simd::Floats vl = simd::splat(float(e_l1 * 1.000001)), keep = simd::splat(float(1 - from[i]));
        const bool planes = plane_test_usable(e_l1, lit.plane_scale);
        uint32_t missed = 0, inside = 0, crossed = 0;
        for (uint32_t t = 0; t < lit.count; t += simd::width) {  // the last group padded (light_triangles)
            simd::Floats lo = simd::splat(INFINITY), hi = simd::splat(-INFINITY);
            simd::Mask settled = simd::all_lanes();
            for (int k = 0; k < 3; ++k) {
                simd::Floats o = simd::dot(v0, v1, v2, simd::load(lit.fx[k] + t), simd::load(lit.fy[k] + t),
                                           simd::load(lit.fz[k] + t));
                settled = settled & (simd::abs(o) > simd::fma(vl, simd::load(lit.fbound[k] + t), tiny));
                lo = simd::min(lo, o);
                hi = simd::max(hi, o);
            }
            simd::Mask mixed = (lo < zero) & (hi > zero);
            missed |= simd::bits(settled & mixed) << t;
            inside |= simd::bits(simd::and_not(settled, mixed)) << t;
            if (!planes) continue;
            // The segment crosses the plane at a fraction dp / (dp - dq) of the way from p (dp = dq - N . e,
            // p's side); it can block only from f on, where mix = (1 - f) dp + f dq = dq - (1 - f) N . e is
            // zero or of dp's sign. A mix settled with dq's sign, dq's sign settled too, rules it out; settled
            // against dq's sign, dp has that sign too ((1 - f) dp = mix - f dq): the plane is crossed from f on.
            const simd::Floats dq = simd::load(lit.dq + t), qb = simd::load(lit.qbound + t);
            simd::Mask mix_up, mix_down;
            crossing_signs(v0, v1, v2, vl, simd::load(lit.nx + t), simd::load(lit.ny + t), simd::load(lit.nz + t), dq,
                           qb, simd::load(lit.pbound + t), keep, mix_up, mix_down);
            const simd::Mask light_up = dq > qb, light_down = -dq > qb;
            missed |= (simd::bits(light_up & mix_up) | simd::bits(light_down & mix_down)) << t;
            crossed |= (simd::bits(light_up & mix_down) | (simd::bits(light_down & mix_up) & (lit.two_sided >> t)))
                << t;
        }
        may_meet[i] = all & ~missed;
        through[i] = inside & all & ~missed;  // not the padding
        const bool sure = (crossed & inside & all) != 0;
        blocked |= uint64_t(sure) << i;
        left |= uint64_t(!sure && may_meet[i] != 0) << i;
    }
    *candidates = left;
    return blocked;
}

// A tile of points as the clustered structure holds them (cb_tile.h), for tile_line_tests and
// tile_points_line_tests: for point i, e = p[i] - light in float (ex, ey, ez), |e|_1 in double (l1) and in
// float a little above it (vl), 1 - its `from` in float (keep); and four float rays from the light (rx, ry,
// rz) of which every point's e is a positive mix.
struct TileView {
    const float *ex, *ey, *ez, *vl, *keep;
    const double* l1;
    double l1_lo, l1_hi;  // the smallest and largest l1 of the tile's points
    const float *rx, *ry, *rz;
};

// line_tests for a whole tile at once, when it can: the line test decided for every point by the 4
// rays that hold their directions. With e = sum of l_j r_j (l_j >= 0), e . f = sum of l_j (r_j . f), so an
// edge normal f whose dot products with the 4 rays all clear 4 fbound with one sign gives every point's
// float dot product that sign, and the exact orientation too: the rays' float dot products are within
// 3.1e-7 max(A) of their exact values, f's components within 2.4e-7 max(A) of the exact normal's and
// |e|_1 <= sqrt(3) sum of l_j, in all under 7.2e-7 max(A) sum of l_j, a third of the 2.4e-6 max(A) cleared
// (fbound = 6e-7 max(A), light_triangles). False when some triangle is left undecided; otherwise, as
// line_tests gives them, the points surely blocked (*blocked) and those left to test (*candidates, with
// their may_meet and through), the plane test in float run for the triangles every line goes through, a
// vector of points an instruction. Near the light a cluster spans a wide angle and most tiles' rays fall
// inside one of its triangles or outside all (a light inside a mesh's bounds often lies by a cluster that
// every point reaches).
inline bool tile_line_tests(const Triangles& lit, const TileView& tile, uint64_t which, uint32_t* may_meet,
                            uint32_t* through, uint64_t* blocked, uint64_t* candidates) {
    const uint32_t all = (1u << lit.count) - 1;
    uint32_t inside = 0;
    for (uint32_t t = 0; t < lit.count; t += simd::width) {
        const uint32_t lanes = uint32_t(all >> t) & ((1u << simd::width) - 1);
        uint32_t settled = ~0u, positive = ~0u, negative = ~0u;
        for (int k = 0; k < 3; ++k) {
            const simd::Floats fx = simd::load(lit.fx[k] + t), fy = simd::load(lit.fy[k] + t),
                               fz = simd::load(lit.fz[k] + t);
            const simd::Floats clear = simd::splat(4.0f) * simd::load(lit.fbound[k] + t);
            uint32_t above = ~0u, below = ~0u;
            for (int j = 0; j < 4; ++j) {
                const simd::Floats g =
                    simd::dot(simd::splat(tile.rx[j]), simd::splat(tile.ry[j]), simd::splat(tile.rz[j]), fx, fy, fz);
                above &= simd::bits(g > clear);
                below &= simd::bits(-g > clear);
            }
            settled &= above | below;
            positive &= above;
            negative &= below;
            if ((settled & lanes) != lanes) return false;  // some triangle undecided: the points are tested one by one
        }
        inside |= (positive | negative) << t;
    }
    inside &= all;
    // The plane test (line_tests') for the triangles every line goes through, where the points' |e|_1
    // keeps the float products in range (all of them, when the tile's extremes do).
    uint64_t planes = 0;
    if (plane_test_usable(tile.l1_lo, lit.plane_scale) && plane_test_usable(tile.l1_hi, lit.plane_scale)) {
        planes = which;
    } else {
        for (uint64_t w = which; w; w &= w - 1)
            planes |= uint64_t(plane_test_usable(tile.l1[math::lowest_bit(w)], lit.plane_scale)) << math::lowest_bit(w);
    }
    uint32_t begin, end;
    simd::lane_span(which, begin, end);
    uint64_t crossed = 0, left = 0, kept[capacity];  // kept[t]: the points whose segment may still meet triangle t
    for (uint32_t m = inside; m; m &= m - 1) {
        const uint32_t t = math::lowest_bit(m);
        const float dq = lit.dq[t], qb = lit.qbound[t];
        kept[t] = which;
        if (std::fabs(dq) > qb) {  // the light's side settled (and the plane usable)
            const simd::Floats nx = simd::splat(lit.nx[t]), ny = simd::splat(lit.ny[t]), nz = simd::splat(lit.nz[t]);
            const simd::Floats sdq = simd::splat(dq), sqb = simd::splat(qb), spb = simd::splat(lit.pbound[t]);
            const bool blocks = dq > 0 || (lit.two_sided >> t & 1);  // one-sided: only with the light behind
            uint64_t ruled = 0, across = 0;
            for (uint32_t i = begin; i < end; i += simd::width) {
                if (!simd::group(which, i)) continue;
                simd::Mask up, down;
                crossing_signs(simd::load(tile.ex + i), simd::load(tile.ey + i), simd::load(tile.ez + i),
                               simd::load(tile.vl + i), nx, ny, nz, sdq, sqb, spb, simd::load(tile.keep + i), up, down);
                ruled |= uint64_t(simd::bits(dq > 0 ? up : down)) << i;
                across |= uint64_t(simd::bits(dq > 0 ? down : up)) << i;
            }
            kept[t] &= ~(ruled & planes);
            if (blocks) crossed |= across & planes & which;
        }
        left |= kept[t];
    }
    *blocked = crossed;
    *candidates = left & ~crossed;
    for (uint64_t w = *candidates; w; w &= w - 1) {
        const uint32_t i = math::lowest_bit(w);
        uint32_t meet = 0;
        for (uint32_t m = inside; m; m &= m - 1)
            meet |= uint32_t(kept[math::lowest_bit(m)] >> i & 1) << math::lowest_bit(m);
        may_meet[i] = through[i] = meet;
    }
    return true;
}

// Vector steps over `count` triangles, and the groups of lanes of a tile that hold a point of `which`.
inline uint32_t triangle_steps(uint32_t count) { return (count + simd::width - 1) / simd::width; }
inline uint32_t lane_groups(uint64_t which) {
    uint32_t groups = 0;
    for (uint32_t g = 0; g < 64; g += simd::width) groups += simd::group(which, g) != 0;
    return groups;
}

// line_tests turned across: a vector of the tile's points an instruction, one triangle at a time, where
// line_tests takes a point at a time and a vector of triangles. The same float operations on the same values
// in each lane (the tile's e, |e|_1 and 1 - from are those line_tests rounds from the point), so the same
// answers: the points surely blocked, *candidates, and their may_meet and through. A tile's points by one
// cluster share its triangles, and a point's mask work across triangles is a chain of dependent
// instructions, where each triangle here gives every point's bits at once. False, with nothing written, when
// some point's |e|_1 is outside the range where line_tests runs the float tests (the tile's extremes decide:
// each range is an interval of |e|_1).
inline bool tile_points_line_tests(const Triangles& lit, const TileView& tile, uint64_t which, uint32_t* may_meet,
                                   uint32_t* through, uint64_t* blocked, uint64_t* candidates) {
    if (!line_test_usable(tile.l1_lo, lit.max_scale) || !line_test_usable(tile.l1_hi, lit.max_scale)) return false;
    const bool planes = plane_test_usable(tile.l1_lo, lit.plane_scale);
    if (planes != plane_test_usable(tile.l1_hi, lit.plane_scale)) return false;  // some points only
    const simd::Floats tiny = simd::splat(1e-30f), zero = simd::splat(0.0f);
    uint32_t begin, end;
    simd::lane_span(which, begin, end);
    // Per triangle, the points whose line it surely misses (missed) and surely passes inside (inside).
    uint64_t missed[capacity], inside[capacity], crossed = 0, all_missed = ~uint64_t(0);
    for (uint32_t t = 0; t < lit.count; ++t) {
        simd::Floats fx[3], fy[3], fz[3], fb[3];
        for (int k = 0; k < 3; ++k) {
            fx[k] = simd::splat(lit.fx[k][t]);
            fy[k] = simd::splat(lit.fy[k][t]);
            fz[k] = simd::splat(lit.fz[k][t]);
            fb[k] = simd::splat(lit.fbound[k][t]);
        }
        const float dq = lit.dq[t], qb = lit.qbound[t];
        const bool light_up = dq > qb, light_down = -dq > qb, two_sided = lit.two_sided >> t & 1;
        const simd::Floats nx = simd::splat(lit.nx[t]), ny = simd::splat(lit.ny[t]), nz = simd::splat(lit.nz[t]),
                           sdq = simd::splat(dq), sqb = simd::splat(qb), spb = simd::splat(lit.pbound[t]);
        uint64_t miss = 0, in = 0;
        for (uint32_t i = begin; i < end; i += simd::width) {
            if (!simd::group(which, i)) continue;
            const simd::Floats ex = simd::load(tile.ex + i), ey = simd::load(tile.ey + i), ez = simd::load(tile.ez + i),
                               vl = simd::load(tile.vl + i);
            simd::Floats lo = simd::splat(INFINITY), hi = simd::splat(-INFINITY);
            simd::Mask settled = simd::all_lanes();
            for (int k = 0; k < 3; ++k) {
                const simd::Floats o = simd::dot(ex, ey, ez, fx[k], fy[k], fz[k]);
                settled = settled & (simd::abs(o) > simd::fma(vl, fb[k], tiny));
                lo = simd::min(lo, o);
                hi = simd::max(hi, o);
            }
            const simd::Mask mixed = (lo < zero) & (hi > zero);
            uint64_t m = simd::bits(settled & mixed), n = simd::bits(simd::and_not(settled, mixed)), across = 0;
            if (planes && (light_up || light_down)) {
                simd::Mask up, down;
                crossing_signs(ex, ey, ez, vl, nx, ny, nz, sdq, sqb, spb, simd::load(tile.keep + i), up, down);
                m |= simd::bits(light_up ? up : down);
                across = light_up ? simd::bits(down) : two_sided ? simd::bits(up) : 0;
            }
            miss |= m << i;
            in |= n << i;
            crossed |= (across & n) << i;
        }
        missed[t] = miss;
        inside[t] = in;
        all_missed &= miss;
    }
    crossed &= which;
    *blocked = crossed;
    const uint64_t left = which & ~crossed & ~all_missed;
    *candidates = left;
    for (uint64_t w = left; w; w &= w - 1) {
        const uint32_t i = math::lowest_bit(w);
        uint32_t meet = 0, in = 0;
        for (uint32_t t = 0; t < lit.count; ++t) {
            const uint32_t kept = uint32_t(~missed[t] >> i & 1);
            meet |= kept << t;
            in |= (kept & uint32_t(inside[t] >> i & 1)) << t;
        }
        may_meet[i] = meet;
        through[i] = in;
    }
    return true;
}

// True when segment p -> light meets a triangle of `lit` that blocks; the same answers as
// cb::segment_triangle on each. Every sign it needs is first settled against its error bound: the line
// through p and the light first, for all triangles at once (line_tests: may_meet and through; the line
// misses most triangles, and then nothing else matters), then in double the side of the plane where
// contacts start to count, then the edge signs float left unsettled, then the point's side of the plane; a
// triangle the bounds cannot settle (a segment within rounding of its plane or of an edge line) goes to the
// exact test. Sets *touched when an exactly tested triangle was touched. Makes the double terms of the
// triangles it needs that `lit` lacks.
inline bool triangles_block(Triangles& lit, const double* p, double from, const double* light, uint32_t may_meet,
                            uint32_t through, bool* touched) {
    const double e0 = p[0] - light[0], e1 = p[1] - light[1], e2 = p[2] - light[2];
    const double edge_scale = det_error * (std::fabs(e0) + std::fabs(e1) + std::fabs(e2));
    for (; may_meet; may_meet &= may_meet - 1) {
        const uint32_t t = math::lowest_bit(may_meet);
        const TriangleTerms& terms = lit.terms[t];
        if (!(lit.has_plane >> t & 1)) plane_terms(lit, t, light, lit.terms[t]), lit.has_plane |= 1u << t;
        // The plane first: a segment that from f on stays on the light's side of the plane meets nothing of the
        // triangle, wherever its line passes. So go the points on or by the plane of a neighbour (a floor's
        // triangles, a grazing light), whose lines pass too near the edges for the float test to settle. Not
        // when contacts are counted (`touched`): a point on a neighbour's edge touches it, and the exact test
        // reports that.
        const double dq = terms.dq;
        const bool light_side = std::fabs(dq) > terms.bq;  // the light's side settled
        double dp = 0, bp = INFINITY, mix = 0, mix_bound = INFINITY;
        if (light_side) {
            // mix: the side of the point at f, where contacts start to count (see segment_triangle)
            dp = plane_side(terms, p, bp);
            mix = (1 - from) * dp + from * dq;
            mix_bound = (1 - from) * bp + from * terms.bq + 8e-16 * (std::fabs(dp) + std::fabs(dq));
            if (!touched && std::fabs(mix) > mix_bound && (mix > 0) == (dq > 0)) continue;
        }
        bool settled = through >> t & 1;
        if (!settled && !(lit.has_edges >> t & 1)) edge_terms(lit, t, light, lit.terms[t]), lit.has_edges |= 1u << t;
        if (!settled) {  // the signs in double
            double o[3];
            settled = true;
            for (int k = 0; k < 3; ++k) {
                o[k] = e0 * terms.n[k][0] + e1 * terms.n[k][1] + e2 * terms.n[k][2];
                settled = settled && std::fabs(o[k]) > edge_scale * terms.scale[k];
            }
            if (settled && ((o[0] > 0) != (o[1] > 0) || (o[1] > 0) != (o[2] > 0))) continue;  // the line passes outside
        }
        // Through the interior: the point's side of the plane decides, then where the crossing lies.
        bool decided = false, blocks = false;
        if (settled && light_side && std::fabs(dp) > bp) {
            decided = true;
            if ((dq > 0) == (dp > 0) || (!(lit.two_sided >> t & 1) && dq < 0))
                continue;  // no crossing, or front-facing
            if (std::fabs(mix) > mix_bound)
                blocks = (mix > 0) == (dp > 0);
            else
                decided = false;
        }
        if (!decided) {
            SegmentTest s = exact_triangle(p, light, lit.corner[t], lit.two_sided >> t & 1, from);
            if (touched) *touched |= s.touching;
            blocks = s.blocks;
        }
        if (blocks) return true;
    }
    return false;
}

// Where an owner's entries start in a direct-mapped table: instances of one mesh name the same clusters, and
// a level's tile meets several of them, so each owner's run of slots starts at a place of its own.
inline uint32_t owner_salt(const void* owner) {
    return uint32_t((uint64_t(reinterpret_cast<uintptr_t>(owner)) >> 4) * 0x9e3779b97f4a7c15ULL >> 40);
}

// Triangle groups already lit, kept for later tests from the same light: a direct-mapped table, about 570 KB.
// An entry is named by its owner (a token for one mesh, light and mode: cb::occluded_batch uses the traversal),
// its fine cluster and its first triangle. clear() before the owners' lights or meshes change.
struct Cache {
    static constexpr uint32_t size = 128;
    const void* owner[size];
    uint32_t cluster[size], first[size];
    lit::Triangles entry[size];
    void clear() {
        for (const void*& o : owner) o = nullptr;
    }
    static uint32_t slot(const void* o, uint32_t f, uint32_t first) {
        return (owner_salt(o) + f + first / lit::capacity) % size;
    }
    bool holds(const void* o, uint32_t f, uint32_t first) const {
        const uint32_t s = slot(o, f, first);
        return owner[s] == o && cluster[s] == f && this->first[s] == first;
    }
};

}  // namespace lit

// Which of the points p[i], i in `which` (bits of a mask), the triangles of fine cluster `f` (mesh-local)
// of `mesh` shadow from the light, in the mesh's frame, contacts counting from from[i] on (shadow_from of the
// world point, which may_block): the same answers as cb::segment_triangle on each triangle. The light's
// terms are computed once for all the points, 16 triangles at a time (or taken from `cache`, under `owner`,
// and left there). Sets *touched when an exactly tested triangle was touched. Uses
// about 7 KB of stack, and the exact test's 50 KB when a sign needs it (docs/RUNTIME.md).
inline uint64_t cluster_blocks_points(const AssetView& v, const MeshRecord& mesh, uint32_t f, const double (*p)[3],
                                      const double* from, uint64_t which, const double* light, bool one_sided,
                                      QueryStats* stats, bool* touched = nullptr, lit::Cache* cache = nullptr,
                                      const void* owner = nullptr, const lit::TileView* tile = nullptr) {
    using namespace lit;
    const FineCluster& c = v.fine[mesh.first_fine + f];
    uint64_t blocked = 0;
    if (stats)
        for (uint64_t w = which; w; w &= w - 1) ++stats->clusters_tested;
    Triangles own;
    for (uint32_t first = 0; first < c.triangle_count && which; first += capacity) {
        const uint32_t count = std::min<uint32_t>(capacity, c.triangle_count - first);
        Triangles* lit = &own;
        if (cache) {
            const uint32_t slot = lit::Cache::slot(owner, f, first);
            lit = &cache->entry[slot];
            if (!cache->holds(owner, f, first)) {
                light_triangles(v, mesh, c, first, count, light, one_sided, *lit);
                cache->owner[slot] = owner;
                cache->cluster[slot] = f;
                cache->first[slot] = first;
            }
        } else {
            light_triangles(v, mesh, c, first, count, light, one_sided, own);
        }
        if (!lit->count) continue;  // every triangle edge-on to the light
        // A flat group settles the points whose segments clear its plane (not when contacts are counted: a
        // point on the group touches it): before the line tests once its plane is known, and it is made the
        // first time some point needs double work, which a group set up for a point or two rarely does.
        const bool planes = !touched;
        const uint64_t test = planes && lit->flat ? which & ~beside_flat(*lit, p, from, which, light) : which;
        if (!test) continue;
        const uint32_t tested = math::bit_count(uint32_t(test)) + math::bit_count(uint32_t(test >> 32));
        uint32_t may_meet[64], through[64];
        // A tile's line tests at once where half its points or more reach the group: the groups it decides
        // are those near the light, which nearly every point reaches (docs/PERFORMANCE.md).
        uint64_t sure = 0, left = 0;  // points surely blocked (no double work), points with triangles left
        const bool whole = tile && tested >= 32 && tile_line_tests(*lit, *tile, test, may_meet, through, &sure, &left);
        // Otherwise across the points where that takes fewer vector steps: a triangle per step for each group of
        // lanes holding a point, against a vector of triangles per step for each point.
        if (!whole &&
            !(tile && tested * triangle_steps(lit->count) >= lit->count * lane_groups(test) &&
              tile_points_line_tests(*lit, *tile, test, may_meet, through, &sure, &left)))
            sure = line_tests(*lit, p, from, test, light, may_meet, through, &left);
        if (stats) stats->triangles_tested += uint64_t(lit->count) * tested;
        if (left && planes && !lit->flat_known) {
            group_plane(*lit);
            if (lit->flat) left &= ~beside_flat(*lit, p, from, left, light);
        }
        blocked |= sure;
        which &= ~sure;
        for (uint64_t w = left; w; w &= w - 1) {
            const uint32_t i = math::lowest_bit(w);
            if (triangles_block(*lit, p[i], from[i], light, may_meet[i], through[i], touched)) {
                blocked |= uint64_t(1) << i;
                which &= ~(uint64_t(1) << i);
            }
        }
    }
    return blocked;
}

// One point: true when a triangle of fine cluster `f` blocks the segment p -> light, contacts counting from
// `from` on (shadow_from).
inline bool cluster_blocks(const AssetView& v, const MeshRecord& mesh, uint32_t f, const double* p, double from,
                           const double* light, bool one_sided, QueryStats* stats, bool* touched = nullptr) {
    const double(*one)[3] = reinterpret_cast<const double(*)[3]>(p);
    return cluster_blocks_points(v, mesh, f, one, &from, 1, light, one_sided, stats, touched) != 0;
}

}  // namespace CB_LANES
}  // namespace cb
