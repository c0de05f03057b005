// Small numeric helpers the runtime's filters share: bits of a mask, the float next to a value, and 3-vector
// products in double. Each does exactly what its comment says for every input it allows, so tests may check
// them against the standard library. Header-only C++17, no dependencies, no exceptions, no allocation. MIT
// licensed (runtime/LICENSE).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include "cb_simd.h"

namespace cb {
inline namespace CB_LANES {
namespace math {

// |v|_1.
inline double l1(const double* v) { return std::fabs(v[0]) + std::fabs(v[1]) + std::fabs(v[2]); }
inline uint32_t lowest_bit(uint64_t x) {  // x != 0
#if defined(__GNUC__)
    return uint32_t(__builtin_ctzll(x));
#else
    uint32_t i = 0;
    while (!(x >> i & 1)) ++i;
    return i;
#endif
}
inline uint32_t bit_count(uint32_t x) {
#if defined(__GNUC__)
    return uint32_t(__builtin_popcount(x));
#else
    uint32_t n = 0;
    for (; x; x &= x - 1) ++n;
    return n;
#endif
}
// std::nextafter(f, up ? INFINITY : -INFINITY) for f not NaN, inlined (the library call is not): the next
// float is one step of the bit pattern, away from zero or towards it.
inline float next_float(float f, bool up) {
    if (f == 0) return up ? std::numeric_limits<float>::denorm_min() : -std::numeric_limits<float>::denorm_min();
    uint32_t bits;
    std::memcpy(&bits, &f, sizeof bits);
    bits = (f > 0) == up ? bits + 1 : bits - 1;  // the magnitude grows moving away from zero
    std::memcpy(&f, &bits, sizeof bits);
    return f;
}
inline double dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline void cross3(const double* a, const double* b, double* out) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

// The float nearest x on one side (x not NaN).
inline float round_down(double x) {
    const float f = float(x);
    return double(f) > x ? next_float(f, false) : f;
}
inline float round_up(double x) {
    const float f = float(x);
    return double(f) < x ? next_float(f, true) : f;
}

}  // namespace math
}  // namespace CB_LANES
}  // namespace cb
