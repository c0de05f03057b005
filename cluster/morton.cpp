// Morton order of triangles: 21 bits per axis of each triangle's box centre, LSD radix sort.
#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

#include "cluster.h"
#include "parallel.h"

namespace cb {
namespace {

// Spreads the low 21 bits of x so that bit i lands on bit 3i.
uint64_t spread3(uint64_t x) {
    x &= 0x1fffff;
    x = (x | x << 32) & 0x1f00000000ffffULL;
    x = (x | x << 16) & 0x1f0000ff0000ffULL;
    x = (x | x << 8) & 0x100f00f00f00f00fULL;
    x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
    x = (x | x << 2) & 0x1249249249249249ULL;
    return x;
}

// Twice a triangle's box centre along axis k (min + max, exact for floats).
inline double doubled_centre(const float* positions, const uint32_t* tri, int k) {
    float a = positions[size_t(tri[0]) * 3 + k], b = positions[size_t(tri[1]) * 3 + k],
          c = positions[size_t(tri[2]) * 3 + k];
    return double(std::min({a, b, c})) + double(std::max({a, b, c}));
}

}  // namespace

std::vector<uint32_t> morton_order(const float* positions, const uint32_t* indices, size_t triangle_count,
                                   unsigned threads) {
    // Work in parts of consecutive triangles, one item of parallel_for each: bounds, keys, and each radix
    // pass's counts and scatter. A stable sort has one answer, so the parts change nothing in it.
    const size_t part = std::max<size_t>(size_t(1) << 16, (triangle_count + 63) / 64);
    const size_t parts = std::max<size_t>(1, (triangle_count + part - 1) / part);
    auto range = [&](size_t p) { return std::pair(p * part, std::min(triangle_count, (p + 1) * part)); };

    std::vector<std::array<double, 6>> part_bounds(parts);
    parallel_for(parts, threads, [&](size_t p) {
        std::array<double, 6> b = {INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY};
        auto [first, last] = range(p);
        for (size_t t = first; t < last; ++t)
            for (int k = 0; k < 3; ++k) {
                double m = doubled_centre(positions, indices + t * 3, k);
                b[k] = std::min(b[k], m);
                b[3 + k] = std::max(b[3 + k], m);
            }
        part_bounds[p] = b;
    });
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (const auto& b : part_bounds)
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], b[k]);
            hi[k] = std::max(hi[k], b[3 + k]);
        }
    const double cells = double((1u << 21) - 1);
    double scale[3];
    for (int k = 0; k < 3; ++k) scale[k] = hi[k] > lo[k] ? cells / (hi[k] - lo[k]) : 0.0;

    std::vector<uint64_t> keys(triangle_count), keys_tmp(triangle_count);
    std::vector<uint32_t> order(triangle_count), order_tmp(triangle_count);
    parallel_for(parts, threads, [&](size_t p) {
        auto [first, last] = range(p);
        for (size_t t = first; t < last; ++t) {
            uint64_t code = 0;
            for (int k = 0; k < 3; ++k) {
                double q = std::clamp((doubled_centre(positions, indices + t * 3, k) - lo[k]) * scale[k], 0.0, cells);
                code |= spread3(uint64_t(q)) << k;
            }
            keys[t] = code;
            order[t] = uint32_t(t);
        }
    });

    // Stable LSD radix sort, 11 bits per pass: a part's 2048 counts stay in the first-level cache, where
    // 16-bit digits scatter over 64k places. Passes where every key has the same digit are skipped.
    constexpr int bits = 11, passes = 6;
    constexpr uint64_t mask = (1u << bits) - 1;
    std::vector<uint32_t> count(parts << bits);
    for (int pass = 0; pass < passes && triangle_count > 0; ++pass) {
        const int shift = pass * bits;
        parallel_for(parts, threads, [&](size_t p) {
            uint32_t* c = &count[p << bits];
            std::fill_n(c, size_t(1) << bits, 0u);
            auto [first, last] = range(p);
            for (size_t i = first; i < last; ++i) ++c[(keys[i] >> shift) & mask];
        });
        size_t same = 0;  // parts' counts of the first key's digit
        for (size_t p = 0; p < parts; ++p) same += count[(p << bits) + ((keys[0] >> shift) & mask)];
        if (same == triangle_count) continue;
        // Each part's start for each digit: all smaller digits, then this digit in earlier parts.
        uint32_t sum = 0;
        for (size_t d = 0; d <= mask; ++d)
            for (size_t p = 0; p < parts; ++p) {
                uint32_t n = count[(p << bits) + d];
                count[(p << bits) + d] = sum;
                sum += n;
            }
        parallel_for(parts, threads, [&](size_t p) {
            uint32_t* c = &count[p << bits];
            auto [first, last] = range(p);
            for (size_t i = first; i < last; ++i) {
                uint32_t slot = c[(keys[i] >> shift) & mask]++;
                keys_tmp[slot] = keys[i];
                order_tmp[slot] = order[i];
            }
        });
        keys.swap(keys_tmp);
        order.swap(order_tmp);
    }
    return order;
}

}  // namespace cb
