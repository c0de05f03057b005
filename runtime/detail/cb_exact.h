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

// An expansion: `n` doubles of increasing magnitude, pairwise non-overlapping, whose exact sum is the value
// (none for zero). The orientation determinant needs at most 192 terms (three minors of at most 16 terms,
// each times a two-term difference); 256 leaves room for the scalings the segment test applies on top.
struct Expansion {
    double t[256];
    int n = 0;
};
constexpr int expansion_capacity = int(sizeof(Expansion::t) / sizeof(Expansion::t[0]));

// A difference of two doubles (or one double), exactly: at most two terms, none for zero.
struct Pair {
    double t[2];
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

// The kernels below work on flat arrays of terms and drop zero terms; each writes into `h`, which must not
// overlap its inputs, and returns the count of terms written. Their inputs and outputs are strongly
// non-overlapping expansions (Shewchuk's condition under round-to-nearest-even), which differences of
// doubles, their products and these kernels' outputs all are: a merge then keeps every term's value exact.

// h = e + f: the terms of both merged by magnitude, a running sum carried through them (Shewchuk's
// Fast-Expansion-Sum, with Two-Sum throughout), each rounding error kept as a term. h holds ne + nf terms.
inline int sum(const double* e, int ne, const double* f, int nf, double* h) {
    int i = 0, j = 0, out = 0;
    auto next = [&] { return j == nf || (i < ne && std::fabs(e[i]) < std::fabs(f[j])) ? e[i++] : f[j++]; };
    if (ne + nf == 0) return 0;
    double q = next();
    while (i + j < ne + nf) {
        double s, err;
        two_sum(q, next(), s, err);
        if (err != 0) h[out++] = err;
        q = s;
    }
    if (q != 0) h[out++] = q;
    return out;
}

// h = e * b: each term's product and its rounding error, carried from the smallest up (Shewchuk's
// Scale-Expansion). h holds 2 ne terms.
inline int scale(const double* e, int ne, double b, double* h) {
    if (ne == 0) return 0;
    int out = 0;
    double q, err;
    two_product(e[0], b, q, err);
    if (err != 0) h[out++] = err;
    for (int i = 1; i < ne; ++i) {
        double p, p_err, s;
        two_product(e[i], b, p, p_err);
        two_sum(q, p_err, s, err);
        if (err != 0) h[out++] = err;
        two_sum(p, s, q, err);
        if (err != 0) h[out++] = err;
    }
    if (q != 0) h[out++] = q;
    return out;
}

// h = e * f for f of at most two terms; h holds 4 ne terms, `scratch` as many.
inline int product(const double* e, int ne, const Pair& f, double* h, double* scratch) {
    if (f.n < 2) return f.n == 0 ? 0 : scale(e, ne, f.t[0], h);
    const int n0 = scale(e, ne, f.t[0], scratch), n1 = scale(e, ne, f.t[1], scratch + 2 * ne);
    return sum(scratch, n0, scratch + 2 * ne, n1, h);
}

// An expansion from `n` terms; beyond the capacity (only outside the domain: a NaN or an infinity makes every
// error term nonzero) the smallest terms are dropped, so the sign is unspecified but nothing is written out of
// bounds.
inline Expansion expansion_of(const double* h, int n) {
    Expansion e;
    const int skip = n > expansion_capacity ? n - expansion_capacity : 0;
    for (int i = skip; i < n; ++i) e.t[e.n++] = h[i];
    return e;
}

// e += b, exactly.
inline void grow(Expansion& e, double b) {
    double h[expansion_capacity + 1];
    e = expansion_of(h, sum(e.t, e.n, &b, 1, h));
}

// e += f, exactly.
inline void add(Expansion& e, const Expansion& f) {
    double h[2 * expansion_capacity];
    e = expansion_of(h, sum(e.t, e.n, f.t, f.n, h));
}

inline Pair difference(double a, double b) {
    Pair e;
    double s, err;
    two_sum(a, -b, s, err);
    if (err != 0) e.t[e.n++] = err;
    if (s != 0) e.t[e.n++] = s;
    return e;
}

// A double as an expansion of one term (none for zero).
inline Pair single(double a) {
    Pair e;
    if (a != 0) e.t[e.n++] = a;
    return e;
}

inline Pair negated(Pair e) {
    for (int i = 0; i < e.n; ++i) e.t[i] = -e.t[i];
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
    double g[expansion_capacity];
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
    if (q != 0) out.t[out.n++] = q;
    return out;
}

// e * s for any double s, exactly.
inline Expansion scaled(const Expansion& e, double s) {
    double h[2 * expansion_capacity];
    return expansion_of(h, scale(e.t, e.n, s, h));
}

// The sign of an expansion is the sign of its largest (last) non-zero term.
inline int sign(const double* h, int n) {
    for (int i = n - 1; i >= 0; --i)
        if (h[i] != 0) return h[i] > 0 ? 1 : -1;
    return 0;
}
inline int sign(const Expansion& e) { return sign(e.t, e.n); }

// The 2 x 2 determinant | a b ; c d | = a d - b c of exact differences, exactly: at most 16 terms in h.
inline int det2_exact(const Pair& a, const Pair& b, const Pair& c, const Pair& d, double* h) {
    double plus[8], minus[8], scratch[8];
    const int np = product(a.t, a.n, d, plus, scratch), nm = product(b.t, b.n, negated(c), minus, scratch);
    return sum(plus, np, minus, nm, h);
}

// The determinant of three rows whose entries are exact differences, exactly: row 0 . (row 1 x row 2), each
// 2 x 2 minor (at most 16 terms) times its row 0 entry (64), the three summed (192).
inline Expansion det3_exact(const Pair (&r)[3][3]) {
    double part[3][64], scratch[64], terms[128], all[192];
    int count[3];
    for (int k = 0; k < 3; ++k) {
        const int u = (k + 1) % 3, v = (k + 2) % 3;
        double minor[16];
        const int n = det2_exact(r[1][u], r[1][v], r[2][u], r[2][v], minor);
        count[k] = product(minor, n, r[0][k], part[k], scratch);
    }
    const int n01 = sum(part[0], count[0], part[1], count[1], terms);
    return expansion_of(all, sum(terms, n01, part[2], count[2], all));
}

// The determinant | a - d, b - d, c - d | (rows), exactly.
inline Expansion orient3d_exact(const double* a, const double* b, const double* c, const double* d) {
    Pair r[3][3];
    for (int k = 0; k < 3; ++k) {
        r[0][k] = difference(a[k], d[k]);
        r[1][k] = difference(b[k], d[k]);
        r[2][k] = difference(c[k], d[k]);
    }
    return det3_exact(r);
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
    Pair r[3][3];
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
