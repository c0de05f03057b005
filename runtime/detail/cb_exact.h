// Exact geometric predicates for the runtime: the sign of 3-D orientation determinants of double inputs,
// always correct. A double evaluation with an error bound answers almost every call; when it cannot
// decide, the determinant is evaluated exactly with floating-point expansions (a value held as a sum of
// non-overlapping doubles, after Priest and Shewchuk), which needs only std::fma and no allocation.
// Domain: finite inputs whose products of three differences neither overflow nor underflow into
// subnormals (roughly magnitudes between 1e-90 and 1e90, or zero); every float coordinate, and every
// double a scene or query can reasonably hold, qualifies.
// Header-only C++17, no dependencies, no exceptions. MIT licensed (runtime/LICENSE).
#pragma once

#include <cmath>

#include "cb_simd.h"

namespace cb {
inline namespace CB_LANES {
namespace exact {

// An expansion: `n` doubles of increasing magnitude, pairwise non-overlapping, whose exact sum is the value.
// The orientation determinant needs at most 192 terms (three products of 2 x 16 two-term products); 256
// leaves room for the scalings the segment test applies on top.
struct Expansion {
    double t[256];
    int n = 0;
};

inline void two_sum(double a, double b, double& sum, double& err) {
    sum = a + b;
    double bv = sum - a, av = sum - bv;
    err = (a - av) + (b - bv);
}

inline void two_product(double a, double b, double& product, double& err) {
    product = a * b;
    err = std::fma(a, b, -product);  // exact: the rounding error of a product is a double
}

// e += b, exactly (Shewchuk's Grow-Expansion with zero elimination). Inside the domain an expansion never
// nears its capacity; outside it (a NaN or an infinity makes every error term nonzero) terms past the
// capacity are dropped, so the sign is unspecified but nothing is written out of bounds.
inline void grow(Expansion& e, double b) {
    constexpr int capacity = int(sizeof(e.t) / sizeof(e.t[0]));
    double q = b;
    int out = 0;
    for (int i = 0; i < e.n; ++i) {
        double sum, err;
        two_sum(q, e.t[i], sum, err);
        q = sum;
        if (err != 0 && out < capacity - 1) e.t[out++] = err;
    }
    if (q != 0 || out == 0) e.t[out++] = q;
    e.n = out;
}

inline void add(Expansion& e, const Expansion& f) {
    for (int i = 0; i < f.n; ++i) grow(e, f.t[i]);
}

// e * f, exactly: every term product and its rounding error, accumulated.
inline Expansion multiply(const Expansion& e, const Expansion& f) {
    Expansion out;
    for (int i = 0; i < e.n; ++i)
        for (int j = 0; j < f.n; ++j) {
            double p, err;
            two_product(e.t[i], f.t[j], p, err);
            if (err != 0) grow(out, err);
            grow(out, p);
        }
    return out;
}

inline Expansion difference(double a, double b) {
    Expansion e;
    double s, err;
    two_sum(a, -b, s, err);
    if (err != 0) e.t[e.n++] = err;
    e.t[e.n++] = s;
    return e;
}

inline Expansion negated(Expansion e) {
    for (int i = 0; i < e.n; ++i) e.t[i] = -e.t[i];
    return e;
}

// e with the same value in fewer terms (Shewchuk's Compress: a nonadjacent expansion, whose length the value's
// exponent range bounds): a sum of expansions has up to the count of both, and compressing first keeps
// scaled()'s doubling far below the capacity.
inline Expansion compressed(const Expansion& e) {
    if (e.n < 2) return e;
    double g[256];
    int bottom = e.n - 1;
    double q = e.t[e.n - 1];
    for (int i = e.n - 2; i >= 0; --i) {
        const double sum = q + e.t[i], err = e.t[i] - (sum - q);  // Fast-Two-Sum: |q| >= |e.t[i]| or q is 0
        if (err != 0) {
            g[bottom--] = sum;
            q = err;
        } else {
            q = sum;
        }
    }
    g[bottom] = q;
    Expansion out;
    for (int i = bottom + 1; i < e.n; ++i) {
        const double sum = g[i] + q, err = q - (sum - g[i]);
        if (err != 0) out.t[out.n++] = err;
        q = sum;
    }
    out.t[out.n++] = q;
    return out;
}

// e * s for any double s, exactly: every term's product and its rounding error.
inline Expansion scaled(const Expansion& e, double s) {
    Expansion out;
    for (int i = 0; i < e.n; ++i) {
        double p, err;
        two_product(e.t[i], s, p, err);
        if (err != 0) grow(out, err);
        grow(out, p);
    }
    return out;
}

// The sign of an expansion is the sign of its largest (last) non-zero term.
inline int sign(const Expansion& e) {
    for (int i = e.n - 1; i >= 0; --i)
        if (e.t[i] != 0) return e.t[i] > 0 ? 1 : -1;
    return 0;
}

// The determinant | a - d, b - d, c - d | (rows), exactly.
inline Expansion orient3d_exact(const double* a, const double* b, const double* c, const double* d) {
    Expansion ad[3], bd[3], cd[3];
    for (int k = 0; k < 3; ++k) {
        ad[k] = difference(a[k], d[k]);
        bd[k] = difference(b[k], d[k]);
        cd[k] = difference(c[k], d[k]);
    }
    // ad . (bd x cd)
    Expansion x = multiply(bd[1], cd[2]), t = negated(multiply(bd[2], cd[1]));
    add(x, t);
    Expansion y = multiply(bd[2], cd[0]);
    add(y, negated(multiply(bd[0], cd[2])));
    Expansion z = multiply(bd[0], cd[1]);
    add(z, negated(multiply(bd[1], cd[0])));
    Expansion det = multiply(ad[0], x);
    add(det, multiply(ad[1], y));
    add(det, multiply(ad[2], z));
    return det;
}

// The determinant | a - d, b - d, c - d | in double, and a bound on its error: the exact value lies within
// `bound` of `det`.
inline double orient3d_estimate(const double* a, const double* b, const double* c, const double* d, double& bound) {
    double adx = a[0] - d[0], ady = a[1] - d[1], adz = a[2] - d[2];
    double bdx = b[0] - d[0], bdy = b[1] - d[1], bdz = b[2] - d[2];
    double cdx = c[0] - d[0], cdy = c[1] - d[1], cdz = c[2] - d[2];
    double bc = bdy * cdz - bdz * cdy, ca = bdz * cdx - bdx * cdz, ab = bdx * cdy - bdy * cdx;
    double permanent = std::fabs(adx) * (std::fabs(bdy * cdz) + std::fabs(bdz * cdy)) +
        std::fabs(ady) * (std::fabs(bdz * cdx) + std::fabs(bdx * cdz)) +
        std::fabs(adz) * (std::fabs(bdx * cdy) + std::fabs(bdy * cdx));
    // Shewchuk's first error bound for this evaluation is (7 + 56 eps) eps * permanent, eps = 2^-53;
    // 1e-15 is above it.
    bound = 1e-15 * permanent;
    return adx * bc + ady * ca + adz * ab;
}

// The sign an estimate and its bound settle: +1 or -1, 0 for a zero bound, `unsettled` otherwise. A zero bound
// is an exact zero: each product of the determinant then has a rounded difference of zero, which in the
// domain above (no product underflows) is an exact zero (two points on an axis-aligned plane, a triangle with
// two equal corners).
constexpr int unsettled = 2;
inline int settled_sign(double estimate, double bound) {
    return estimate > bound ? 1 : -estimate > bound ? -1 : bound == 0 ? 0 : unsettled;
}

// The determinant of three rows, each entry given exactly as an expansion (a difference of doubles, or a
// double), exactly: row 0 . (row 1 x row 2).
inline Expansion det3_exact(const Expansion (&r)[3][3]) {
    Expansion x = multiply(r[1][1], r[2][2]);
    add(x, negated(multiply(r[1][2], r[2][1])));
    Expansion y = multiply(r[1][2], r[2][0]);
    add(y, negated(multiply(r[1][0], r[2][2])));
    Expansion z = multiply(r[1][0], r[2][1]);
    add(z, negated(multiply(r[1][1], r[2][0])));
    Expansion det = multiply(r[0][0], x);
    add(det, multiply(r[0][1], y));
    add(det, multiply(r[0][2], z));
    return det;
}

// A double as an expansion of one term (none for zero).
inline Expansion single(double a) {
    Expansion e;
    if (a != 0) e.t[e.n++] = a;
    return e;
}

// The determinant of three rows given in double, each row either a difference x - y of doubles or, when
// `y` is null, the double vector x itself; in double with a bound on its error (`bound`, as
// orient3d_estimate's: the same products of three rounded differences at most), and exactly.
struct Row {
    const double *x, *y;  // y null: the row is x
};
inline double det3_estimate(const Row (&rows)[3], double& bound) {
    double r[3][3];
    for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k) r[i][k] = rows[i].y ? rows[i].x[k] - rows[i].y[k] : rows[i].x[k];
    const double bc = r[1][1] * r[2][2] - r[1][2] * r[2][1], ca = r[1][2] * r[2][0] - r[1][0] * r[2][2],
                 ab = r[1][0] * r[2][1] - r[1][1] * r[2][0];
    const double permanent = std::fabs(r[0][0]) * (std::fabs(r[1][1] * r[2][2]) + std::fabs(r[1][2] * r[2][1])) +
        std::fabs(r[0][1]) * (std::fabs(r[1][2] * r[2][0]) + std::fabs(r[1][0] * r[2][2])) +
        std::fabs(r[0][2]) * (std::fabs(r[1][0] * r[2][1]) + std::fabs(r[1][1] * r[2][0]));
    bound = 1e-15 * permanent;
    return r[0][0] * bc + r[0][1] * ca + r[0][2] * ab;
}
inline Expansion det3_exact(const Row (&rows)[3]) {
    Expansion r[3][3];
    for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k) r[i][k] = rows[i].y ? difference(rows[i].x[k], rows[i].y[k]) : single(rows[i].x[k]);
    return det3_exact(r);
}
inline int det3_sign(const Row (&rows)[3]) {
    double bound, det = det3_estimate(rows, bound);
    const int s = settled_sign(det, bound);
    return s != unsettled ? s : sign(det3_exact(rows));
}

// Sign of | a - d, b - d, c - d |: +1, 0 or -1, exact. Positive when d sees a, b, c clockwise (equivalently,
// a is on the side that (b - d) x (c - d) points to).
inline int orient3d(const double* a, const double* b, const double* c, const double* d) {
    double bound, det = orient3d_estimate(a, b, c, d, bound);
    // Non-finite values fall through to the exact path, which then decides.
    const int s = settled_sign(det, bound);
    return s != unsettled ? s : sign(orient3d_exact(a, b, c, d));
}

}  // namespace exact
}  // namespace CB_LANES
}  // namespace cb
