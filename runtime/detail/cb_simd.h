// The float lanes the runtime's filters run on: 16 with AVX-512, 8 with AVX, 4 with SSE2, and 4 portable
// ones (CB_NO_SIMD, or a target without SSE2). Each filter is written once over cb::simd::Floats; every
// build gives the same answers. Each lane computes the same IEEE operations in the same order, except that
// fma(a, b, c) rounds a * b + c once where the target has fused multiply-adds (AVX-512, or FMA) and twice
// elsewhere: the filters' error bounds hold for both (a fused result's error is at most the unfused one's
// bound), and every answer a filter leaves open is decided exactly. The choice follows the target flags of
// each translation unit (-mavx2 -mfma, -mavx512f); units built for different lanes may share a program
// (CB_LANES below). Header-only C++17, no dependencies. MIT licensed.
#pragma once

#include <cmath>
#include <cstdint>

// CB_SIMD_SSE2: SSE2 intrinsics may be used (also for fixed 4-wide work); CB_SIMD_AVX512 or CB_SIMD_AVX:
// the lanes are AVX-512's or AVX's.
#if defined(__SSE2__) && !defined(CB_NO_SIMD)
#define CB_SIMD_SSE2 1
#include <emmintrin.h>
#if defined(__AVX512F__)
#define CB_SIMD_AVX512 1
#include <immintrin.h>
#elif defined(__AVX__)
#define CB_SIMD_AVX 1
#include <immintrin.h>
#endif
#endif

// CB_LANES names the inline namespace of cb that holds every part of the runtime whose code depends on the
// lanes (all of it but cb_asset.h and the two vocabulary types cb::QueryStats and cb::Traversal). One program
// may so include the runtime in translation units built for different targets and pick one at run time, as
// clusterbake's own query library does: their functions never share a symbol, so the linker cannot swap an
// AVX-512 build of a function in for the SSE2 one.
#if defined(CB_SIMD_AVX512)
#define CB_LANES lanes_avx512
#elif defined(CB_SIMD_AVX)
#define CB_LANES lanes_avx
#elif defined(CB_SIMD_SSE2)
#define CB_LANES lanes_sse2
#else
#define CB_LANES lanes_portable
#endif

namespace cb {
inline namespace CB_LANES {
namespace simd {

// Comparisons are ordered: a lane holding NaN compares false. min(a, b) and max(a, b) return b when
// either is NaN, as the x86 instructions do.
#if defined(CB_SIMD_AVX512)
constexpr uint32_t width = 16;
constexpr char name[] = "avx512";
struct Floats {
    __m512 v;
};
struct Mask {
    __mmask16 m;
};
inline Floats load(const float* p) { return {_mm512_load_ps(p)}; }  // 64-byte aligned
inline Floats loadu(const float* p) { return {_mm512_loadu_ps(p)}; }
inline Floats splat(float x) { return {_mm512_set1_ps(x)}; }
inline Floats operator+(Floats a, Floats b) { return {_mm512_add_ps(a.v, b.v)}; }
inline Floats operator-(Floats a, Floats b) { return {_mm512_sub_ps(a.v, b.v)}; }
inline Floats operator*(Floats a, Floats b) { return {_mm512_mul_ps(a.v, b.v)}; }
inline Floats fma(Floats a, Floats b, Floats c) { return {_mm512_fmadd_ps(a.v, b.v, c.v)}; }
inline Floats fms(Floats a, Floats b, Floats c) { return {_mm512_fmsub_ps(a.v, b.v, c.v)}; }
// (The masked forms: GCC 12 warns that the plain ones read an undefined register.)
inline Floats min(Floats a, Floats b) { return {_mm512_mask_min_ps(a.v, 0xffff, a.v, b.v)}; }
inline Floats max(Floats a, Floats b) { return {_mm512_mask_max_ps(a.v, 0xffff, a.v, b.v)}; }
inline Floats abs(Floats a) { return {_mm512_abs_ps(a.v)}; }
inline Floats sqrt(Floats a) { return {_mm512_mask_sqrt_ps(a.v, 0xffff, a.v)}; }
inline void store(float* p, Floats a) { _mm512_store_ps(p, a.v); }
inline Mask operator>=(Floats a, Floats b) { return {_mm512_cmp_ps_mask(a.v, b.v, _CMP_GE_OQ)}; }
inline Mask operator>(Floats a, Floats b) { return {_mm512_cmp_ps_mask(a.v, b.v, _CMP_GT_OQ)}; }
inline Mask operator<=(Floats a, Floats b) { return {_mm512_cmp_ps_mask(a.v, b.v, _CMP_LE_OQ)}; }
inline Mask operator<(Floats a, Floats b) { return {_mm512_cmp_ps_mask(a.v, b.v, _CMP_LT_OQ)}; }
inline Mask operator&(Mask a, Mask b) { return {__mmask16(a.m & b.m)}; }
inline Mask and_not(Mask a, Mask b) { return {__mmask16(a.m & ~b.m)}; }
inline Mask all_lanes() { return {__mmask16(0xffff)}; }
inline uint32_t bits(Mask m) { return m.m; }
inline Floats select(Mask m, Floats a, Floats b) { return {_mm512_mask_blend_ps(m.m, b.v, a.v)}; }  // m ? a : b
#elif defined(CB_SIMD_AVX)
constexpr uint32_t width = 8;
#if defined(__AVX2__) && defined(__FMA__)
constexpr char name[] = "avx2";
#else
constexpr char name[] = "avx";
#endif
struct Floats {
    __m256 v;
};
struct Mask {
    __m256 v;
};
inline Floats load(const float* p) { return {_mm256_load_ps(p)}; }  // 32-byte aligned
inline Floats loadu(const float* p) { return {_mm256_loadu_ps(p)}; }
inline Floats splat(float x) { return {_mm256_set1_ps(x)}; }
inline Floats operator+(Floats a, Floats b) { return {_mm256_add_ps(a.v, b.v)}; }
inline Floats operator-(Floats a, Floats b) { return {_mm256_sub_ps(a.v, b.v)}; }
inline Floats operator*(Floats a, Floats b) { return {_mm256_mul_ps(a.v, b.v)}; }
#if defined(__FMA__)
inline Floats fma(Floats a, Floats b, Floats c) { return {_mm256_fmadd_ps(a.v, b.v, c.v)}; }
inline Floats fms(Floats a, Floats b, Floats c) { return {_mm256_fmsub_ps(a.v, b.v, c.v)}; }
#else
inline Floats fma(Floats a, Floats b, Floats c) { return a * b + c; }
inline Floats fms(Floats a, Floats b, Floats c) { return a * b - c; }
#endif
inline Floats min(Floats a, Floats b) { return {_mm256_min_ps(a.v, b.v)}; }
inline Floats max(Floats a, Floats b) { return {_mm256_max_ps(a.v, b.v)}; }
inline Floats abs(Floats a) { return {_mm256_andnot_ps(_mm256_set1_ps(-0.0f), a.v)}; }
inline Floats sqrt(Floats a) { return {_mm256_sqrt_ps(a.v)}; }
inline void store(float* p, Floats a) { _mm256_store_ps(p, a.v); }
inline Mask operator>=(Floats a, Floats b) { return {_mm256_cmp_ps(a.v, b.v, _CMP_GE_OQ)}; }
inline Mask operator>(Floats a, Floats b) { return {_mm256_cmp_ps(a.v, b.v, _CMP_GT_OQ)}; }
inline Mask operator<=(Floats a, Floats b) { return {_mm256_cmp_ps(a.v, b.v, _CMP_LE_OQ)}; }
inline Mask operator<(Floats a, Floats b) { return {_mm256_cmp_ps(a.v, b.v, _CMP_LT_OQ)}; }
inline Mask operator&(Mask a, Mask b) { return {_mm256_and_ps(a.v, b.v)}; }
inline Mask and_not(Mask a, Mask b) { return {_mm256_andnot_ps(b.v, a.v)}; }  // a and not b
inline Mask all_lanes() { return {_mm256_castsi256_ps(_mm256_set1_epi32(-1))}; }
inline uint32_t bits(Mask m) { return uint32_t(_mm256_movemask_ps(m.v)); }
inline Floats select(Mask m, Floats a, Floats b) { return {_mm256_blendv_ps(b.v, a.v, m.v)}; }  // m ? a : b
#elif defined(CB_SIMD_SSE2)
constexpr uint32_t width = 4;
constexpr char name[] = "sse2";
struct Floats {
    __m128 v;
};
struct Mask {
    __m128 v;
};
inline Floats load(const float* p) { return {_mm_load_ps(p)}; }  // 16-byte aligned
inline Floats loadu(const float* p) { return {_mm_loadu_ps(p)}; }
inline Floats splat(float x) { return {_mm_set1_ps(x)}; }
inline Floats operator+(Floats a, Floats b) { return {_mm_add_ps(a.v, b.v)}; }
inline Floats operator-(Floats a, Floats b) { return {_mm_sub_ps(a.v, b.v)}; }
inline Floats operator*(Floats a, Floats b) { return {_mm_mul_ps(a.v, b.v)}; }
inline Floats fma(Floats a, Floats b, Floats c) { return a * b + c; }  // (SSE2 has no fused form)
inline Floats fms(Floats a, Floats b, Floats c) { return a * b - c; }
inline Floats min(Floats a, Floats b) { return {_mm_min_ps(a.v, b.v)}; }
inline Floats max(Floats a, Floats b) { return {_mm_max_ps(a.v, b.v)}; }
inline Floats abs(Floats a) { return {_mm_andnot_ps(_mm_set1_ps(-0.0f), a.v)}; }
inline Floats sqrt(Floats a) { return {_mm_sqrt_ps(a.v)}; }
inline void store(float* p, Floats a) { _mm_store_ps(p, a.v); }
inline Mask operator>=(Floats a, Floats b) { return {_mm_cmpge_ps(a.v, b.v)}; }
inline Mask operator>(Floats a, Floats b) { return {_mm_cmpgt_ps(a.v, b.v)}; }
inline Mask operator<=(Floats a, Floats b) { return {_mm_cmple_ps(a.v, b.v)}; }
inline Mask operator<(Floats a, Floats b) { return {_mm_cmplt_ps(a.v, b.v)}; }
inline Mask operator&(Mask a, Mask b) { return {_mm_and_ps(a.v, b.v)}; }
inline Mask and_not(Mask a, Mask b) { return {_mm_andnot_ps(b.v, a.v)}; }
inline Mask all_lanes() { return {_mm_castsi128_ps(_mm_set1_epi32(-1))}; }
inline uint32_t bits(Mask m) { return uint32_t(_mm_movemask_ps(m.v)); }
inline Floats select(Mask m, Floats a, Floats b) { return {_mm_or_ps(_mm_and_ps(m.v, a.v), _mm_andnot_ps(m.v, b.v))}; }
#else
constexpr uint32_t width = 4;
constexpr char name[] = "portable";
struct Floats {
    float v[width];
};
struct Mask {
    uint32_t b;
};  // bit i: lane i
template <class F>
inline Floats each(F f) {
    Floats r;
    for (uint32_t i = 0; i < width; ++i) r.v[i] = f(i);
    return r;
}
template <class F>
inline Mask each_bit(F f) {
    uint32_t b = 0;
    for (uint32_t i = 0; i < width; ++i) b |= uint32_t(f(i)) << i;
    return {b};
}
inline Floats load(const float* p) {
    return each([&](uint32_t i) { return p[i]; });
}
inline Floats loadu(const float* p) { return load(p); }
inline Floats splat(float x) {
    return each([&](uint32_t) { return x; });
}
inline Floats operator+(Floats a, Floats b) {
    return each([&](uint32_t i) { return a.v[i] + b.v[i]; });
}
inline Floats operator-(Floats a, Floats b) {
    return each([&](uint32_t i) { return a.v[i] - b.v[i]; });
}
inline Floats operator*(Floats a, Floats b) {
    return each([&](uint32_t i) { return a.v[i] * b.v[i]; });
}
inline Floats fma(Floats a, Floats b, Floats c) { return a * b + c; }
inline Floats fms(Floats a, Floats b, Floats c) { return a * b - c; }
inline Floats min(Floats a, Floats b) {
    return each([&](uint32_t i) { return a.v[i] < b.v[i] ? a.v[i] : b.v[i]; });
}
inline Floats max(Floats a, Floats b) {
    return each([&](uint32_t i) { return a.v[i] > b.v[i] ? a.v[i] : b.v[i]; });
}
inline Floats abs(Floats a) {
    return each([&](uint32_t i) { return std::fabs(a.v[i]); });
}
inline Floats sqrt(Floats a) {
    return each([&](uint32_t i) { return std::sqrt(a.v[i]); });
}
inline void store(float* p, Floats a) {
    for (uint32_t i = 0; i < width; ++i) p[i] = a.v[i];
}
inline Mask operator>=(Floats a, Floats b) {
    return each_bit([&](uint32_t i) { return a.v[i] >= b.v[i]; });
}
inline Mask operator>(Floats a, Floats b) {
    return each_bit([&](uint32_t i) { return a.v[i] > b.v[i]; });
}
inline Mask operator<=(Floats a, Floats b) {
    return each_bit([&](uint32_t i) { return a.v[i] <= b.v[i]; });
}
inline Mask operator<(Floats a, Floats b) {
    return each_bit([&](uint32_t i) { return a.v[i] < b.v[i]; });
}
inline Mask operator&(Mask a, Mask b) { return {a.b & b.b}; }
inline Mask and_not(Mask a, Mask b) { return {a.b & ~b.b}; }
inline Mask all_lanes() { return {(1u << width) - 1}; }
inline uint32_t bits(Mask m) { return m.b; }
inline Floats select(Mask m, Floats a, Floats b) {
    return each([&](uint32_t i) { return m.b >> i & 1 ? a.v[i] : b.v[i]; });
}
#endif

inline Floats operator-(Floats a) { return splat(0.0f) - a; }
// x a + y b + z c (+ w), the products fused into the sums where the target allows (fma).
inline Floats dot(Floats x, Floats y, Floats z, Floats a, Floats b, Floats c) { return fma(z, c, fma(y, b, x * a)); }
inline Floats dot(Floats x, Floats y, Floats z, float a, float b, float c) {
    return dot(x, y, z, splat(a), splat(b), splat(c));
}
inline Floats dot_plus(Floats x, Floats y, Floats z, float a, float b, float c, Floats w) {
    return fma(z, splat(c), fma(y, splat(b), fma(x, splat(a), w)));
}

// Double lanes, for the per-point set-up that must stay in double (a tile's points moved into an instance's
// frame): 8 with AVX-512, 4 with AVX, and 2 plain doubles otherwise (SSE2 builds included). Loads and stores
// take any address. fused(a, b, c) rounds a * b + c once on every target (a software fma per
// lane where there is no instruction), so that lanes give the bits std::fma gives.
#if defined(CB_SIMD_AVX512)
constexpr uint32_t dwidth = 8;
struct Doubles {
    __m512d v;
};
struct DoubleMask {
    __mmask8 m;
};
inline Doubles load(const double* p) { return {_mm512_loadu_pd(p)}; }
inline void store(double* p, Doubles a) { _mm512_storeu_pd(p, a.v); }
inline void store_floats(float* p, Doubles a) { _mm256_storeu_ps(p, _mm512_cvtpd_ps(a.v)); }  // each rounded
inline Doubles dsplat(double x) { return {_mm512_set1_pd(x)}; }
inline Doubles operator+(Doubles a, Doubles b) { return {_mm512_add_pd(a.v, b.v)}; }
inline Doubles operator-(Doubles a, Doubles b) { return {_mm512_sub_pd(a.v, b.v)}; }
inline Doubles operator*(Doubles a, Doubles b) { return {_mm512_mul_pd(a.v, b.v)}; }
inline Doubles operator/(Doubles a, Doubles b) { return {_mm512_div_pd(a.v, b.v)}; }
inline Doubles fused(Doubles a, Doubles b, Doubles c) { return {_mm512_fmadd_pd(a.v, b.v, c.v)}; }
inline Doubles sqrt(Doubles a) { return {_mm512_mask_sqrt_pd(a.v, 0xff, a.v)}; }
inline Doubles min(Doubles a, Doubles b) { return {_mm512_mask_min_pd(a.v, 0xff, a.v, b.v)}; }
inline Doubles max(Doubles a, Doubles b) { return {_mm512_mask_max_pd(a.v, 0xff, a.v, b.v)}; }
inline Doubles abs(Doubles a) { return {_mm512_abs_pd(a.v)}; }
inline DoubleMask operator>(Doubles a, Doubles b) { return {_mm512_cmp_pd_mask(a.v, b.v, _CMP_GT_OQ)}; }
inline DoubleMask operator<(Doubles a, Doubles b) { return {_mm512_cmp_pd_mask(a.v, b.v, _CMP_LT_OQ)}; }
inline DoubleMask operator<=(Doubles a, Doubles b) { return {_mm512_cmp_pd_mask(a.v, b.v, _CMP_LE_OQ)}; }
inline DoubleMask operator&(DoubleMask a, DoubleMask b) { return {__mmask8(a.m & b.m)}; }
inline DoubleMask double_lanes(uint32_t bits) { return {__mmask8(bits)}; }
inline uint32_t bits(DoubleMask m) { return m.m; }
inline Doubles select(DoubleMask m, Doubles a, Doubles b) { return {_mm512_mask_blend_pd(m.m, b.v, a.v)}; }
#elif defined(CB_SIMD_AVX)
constexpr uint32_t dwidth = 4;
struct Doubles {
    __m256d v;
};
struct DoubleMask {
    __m256d v;
};
inline Doubles load(const double* p) { return {_mm256_loadu_pd(p)}; }
inline void store(double* p, Doubles a) { _mm256_storeu_pd(p, a.v); }
inline void store_floats(float* p, Doubles a) { _mm_storeu_ps(p, _mm256_cvtpd_ps(a.v)); }  // each rounded
inline Doubles dsplat(double x) { return {_mm256_set1_pd(x)}; }
inline Doubles operator+(Doubles a, Doubles b) { return {_mm256_add_pd(a.v, b.v)}; }
inline Doubles operator-(Doubles a, Doubles b) { return {_mm256_sub_pd(a.v, b.v)}; }
inline Doubles operator*(Doubles a, Doubles b) { return {_mm256_mul_pd(a.v, b.v)}; }
inline Doubles operator/(Doubles a, Doubles b) { return {_mm256_div_pd(a.v, b.v)}; }
#if defined(__FMA__)
inline Doubles fused(Doubles a, Doubles b, Doubles c) { return {_mm256_fmadd_pd(a.v, b.v, c.v)}; }
#else
inline Doubles fused(Doubles a, Doubles b, Doubles c) {
    alignas(32) double x[4], y[4], z[4];
    _mm256_store_pd(x, a.v);
    _mm256_store_pd(y, b.v);
    _mm256_store_pd(z, c.v);
    for (int i = 0; i < 4; ++i) x[i] = std::fma(x[i], y[i], z[i]);
    return {_mm256_load_pd(x)};
}
#endif
inline Doubles sqrt(Doubles a) { return {_mm256_sqrt_pd(a.v)}; }
inline Doubles min(Doubles a, Doubles b) { return {_mm256_min_pd(a.v, b.v)}; }
inline Doubles max(Doubles a, Doubles b) { return {_mm256_max_pd(a.v, b.v)}; }
inline Doubles abs(Doubles a) { return {_mm256_andnot_pd(_mm256_set1_pd(-0.0), a.v)}; }
inline DoubleMask operator>(Doubles a, Doubles b) { return {_mm256_cmp_pd(a.v, b.v, _CMP_GT_OQ)}; }
inline DoubleMask operator<(Doubles a, Doubles b) { return {_mm256_cmp_pd(a.v, b.v, _CMP_LT_OQ)}; }
inline DoubleMask operator<=(Doubles a, Doubles b) { return {_mm256_cmp_pd(a.v, b.v, _CMP_LE_OQ)}; }
inline DoubleMask operator&(DoubleMask a, DoubleMask b) { return {_mm256_and_pd(a.v, b.v)}; }
inline DoubleMask double_lanes(uint32_t bits) {  // (AVX implies SSE4.1's 64-bit compare)
    const __m256i lane = _mm256_setr_epi64x(1, 2, 4, 8), set = _mm256_set1_epi64x(int64_t(bits & 15));
    const __m256i both = _mm256_castpd_si256(_mm256_and_pd(_mm256_castsi256_pd(set), _mm256_castsi256_pd(lane)));
    const __m128i lo = _mm_cmpeq_epi64(_mm256_castsi256_si128(both), _mm256_castsi256_si128(lane)),
                  hi = _mm_cmpeq_epi64(_mm256_extractf128_si256(both, 1), _mm256_extractf128_si256(lane, 1));
    return {_mm256_castsi256_pd(_mm256_set_m128i(hi, lo))};
}
inline uint32_t bits(DoubleMask m) { return uint32_t(_mm256_movemask_pd(m.v)); }
inline Doubles select(DoubleMask m, Doubles a, Doubles b) { return {_mm256_blendv_pd(b.v, a.v, m.v)}; }
#else
constexpr uint32_t dwidth = 2;
struct Doubles {
    double v[2];
};
struct DoubleMask {
    uint32_t b;
};  // bit i: lane i
inline Doubles load(const double* p) { return {{p[0], p[1]}}; }
inline void store(double* p, Doubles a) {
    p[0] = a.v[0];
    p[1] = a.v[1];
}
inline void store_floats(float* p, Doubles a) {
    p[0] = float(a.v[0]);
    p[1] = float(a.v[1]);
}
inline Doubles dsplat(double x) { return {{x, x}}; }
inline Doubles operator+(Doubles a, Doubles b) { return {{a.v[0] + b.v[0], a.v[1] + b.v[1]}}; }
inline Doubles operator-(Doubles a, Doubles b) { return {{a.v[0] - b.v[0], a.v[1] - b.v[1]}}; }
inline Doubles operator*(Doubles a, Doubles b) { return {{a.v[0] * b.v[0], a.v[1] * b.v[1]}}; }
inline Doubles operator/(Doubles a, Doubles b) { return {{a.v[0] / b.v[0], a.v[1] / b.v[1]}}; }
inline Doubles fused(Doubles a, Doubles b, Doubles c) {
    return {{std::fma(a.v[0], b.v[0], c.v[0]), std::fma(a.v[1], b.v[1], c.v[1])}};
}
inline Doubles sqrt(Doubles a) { return {{std::sqrt(a.v[0]), std::sqrt(a.v[1])}}; }
inline Doubles min(Doubles a, Doubles b) {
    return {{a.v[0] < b.v[0] ? a.v[0] : b.v[0], a.v[1] < b.v[1] ? a.v[1] : b.v[1]}};
}
inline Doubles max(Doubles a, Doubles b) {
    return {{a.v[0] > b.v[0] ? a.v[0] : b.v[0], a.v[1] > b.v[1] ? a.v[1] : b.v[1]}};
}
inline Doubles abs(Doubles a) { return {{std::fabs(a.v[0]), std::fabs(a.v[1])}}; }
inline DoubleMask operator>(Doubles a, Doubles b) {
    return {uint32_t(a.v[0] > b.v[0]) | uint32_t(a.v[1] > b.v[1]) << 1};
}
inline DoubleMask operator<(Doubles a, Doubles b) {
    return {uint32_t(a.v[0] < b.v[0]) | uint32_t(a.v[1] < b.v[1]) << 1};
}
inline DoubleMask operator<=(Doubles a, Doubles b) {
    return {uint32_t(a.v[0] <= b.v[0]) | uint32_t(a.v[1] <= b.v[1]) << 1};
}
inline DoubleMask operator&(DoubleMask a, DoubleMask b) { return {a.b & b.b}; }
inline DoubleMask double_lanes(uint32_t bits) { return {bits & 3}; }
inline uint32_t bits(DoubleMask m) { return m.b; }
inline Doubles select(DoubleMask m, Doubles a, Doubles b) {
    return {{m.b & 1 ? a.v[0] : b.v[0], m.b & 2 ? a.v[1] : b.v[1]}};
}
#endif

// A vector of doubles reduced to one: the sum of its lanes in lane order, their least, their greatest.
inline double lane_sum(Doubles v) {
    alignas(64) double lane[dwidth];
    store(lane, v);
    double s = 0;
    for (uint32_t j = 0; j < dwidth; ++j) s += lane[j];
    return s;
}
inline double lane_min(Doubles v) {
    alignas(64) double lane[dwidth];
    store(lane, v);
    double s = lane[0];
    for (uint32_t j = 1; j < dwidth; ++j) s = lane[j] < s ? lane[j] : s;
    return s;
}
inline double lane_max(Doubles v) {
    alignas(64) double lane[dwidth];
    store(lane, v);
    double s = lane[0];
    for (uint32_t j = 1; j < dwidth; ++j) s = lane[j] > s ? lane[j] : s;
    return s;
}

// The lanes, in whole groups of `width`, that nonzero mask `subset` spans: [begin, end).
inline void lane_span(uint64_t subset, uint32_t& begin, uint32_t& end) {
#if defined(__GNUC__)
    const uint32_t low = uint32_t(__builtin_ctzll(subset)), high = 63 - uint32_t(__builtin_clzll(subset));
#else
    uint32_t low = 0, high = 63;
    while (!(subset >> low & 1)) ++low;
    while (!(subset >> high & 1)) --high;
#endif
    begin = low & ~(width - 1);
    end = (high | (width - 1)) + 1;
}

// The bits of lanes [i, i + width) of a 64-bit mask.
inline uint32_t group(uint64_t mask, uint32_t i) { return uint32_t(mask >> i) & ((1u << width) - 1); }
// The same for double lanes: bits [i, i + dwidth).
inline uint32_t double_group(uint64_t mask, uint32_t i) { return uint32_t(mask >> i) & ((1u << dwidth) - 1); }

// Asks for the cache line holding p (any address: a prefetch never faults). An asm statement on x86, since
// GCC deletes calls to a function that does nothing but __builtin_prefetch (it deems it pure).
inline void prefetch(const void* p) {
#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__)) && defined(CB_SIMD_SSE2)
    asm volatile("prefetcht0 %0" : : "m"(*static_cast<const char*>(p)));
#elif defined(__GNUC__)
    __builtin_prefetch(p);
#else
    (void)p;
#endif
}
}  // namespace simd
}  // namespace CB_LANES
}  // namespace cb
