// Morton order of triangles: 21 bits per axis of each triangle's box centre, LSD radix sort.
#include <algorithm>
#include <cmath>

#include "cluster.h"

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

}  // namespace

std::vector<uint32_t> morton_order(const float* positions, const uint32_t* indices, size_t triangle_count) {
    // Centres in double (twice the centre: min + max, which is exact for floats) and their bounds.
    std::vector<double> centre(triangle_count * 3);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t t = 0; t < triangle_count; ++t) {
        const float* a = positions + size_t(indices[t * 3]) * 3;
        const float* b = positions + size_t(indices[t * 3 + 1]) * 3;
        const float* c = positions + size_t(indices[t * 3 + 2]) * 3;
        for (int k = 0; k < 3; ++k) {
            double mn = std::min({a[k], b[k], c[k]}), mx = std::max({a[k], b[k], c[k]});
            double m = mn + mx;
            centre[t * 3 + k] = m;
            lo[k] = std::min(lo[k], m);
            hi[k] = std::max(hi[k], m);
        }
    }
    const double cells = double((1u << 21) - 1);
    double scale[3];
    for (int k = 0; k < 3; ++k) scale[k] = hi[k] > lo[k] ? cells / (hi[k] - lo[k]) : 0.0;

    std::vector<uint64_t> keys(triangle_count), keys_tmp(triangle_count);
    std::vector<uint32_t> order(triangle_count), order_tmp(triangle_count);
    for (size_t t = 0; t < triangle_count; ++t) {
        uint64_t code = 0;
        for (int k = 0; k < 3; ++k) {
            double q = std::clamp((centre[t * 3 + k] - lo[k]) * scale[k], 0.0, cells);
            code |= spread3(uint64_t(q)) << k;
        }
        keys[t] = code;
        order[t] = uint32_t(t);
    }

    // Stable LSD radix sort, 11 bits per pass (a 2048-slot count stays in the first-level cache, where
    // 16-bit digits scatter over 64k places), all six counts made in one read; passes where every key has
    // the same digit are skipped.
    constexpr int bits = 11, passes = 6;
    constexpr uint64_t mask = (1u << bits) - 1;
    std::vector<uint32_t> count(size_t(passes) << bits, 0);
    for (uint64_t k : keys)
        for (int p = 0; p < passes; ++p) ++count[(size_t(p) << bits) + ((k >> (p * bits)) & mask)];
    for (int p = 0; p < passes && triangle_count > 0; ++p) {
        uint32_t* c = &count[size_t(p) << bits];
        const int shift = p * bits;
        if (c[(keys[0] >> shift) & mask] == triangle_count) continue;
        uint32_t sum = 0;
        for (size_t d = 0; d <= mask; ++d) {
            uint32_t n = c[d];
            c[d] = sum;
            sum += n;
        }
        for (size_t i = 0; i < triangle_count; ++i) {
            uint32_t slot = c[(keys[i] >> shift) & mask]++;
            keys_tmp[slot] = keys[i];
            order_tmp[slot] = order[i];
        }
        keys.swap(keys_tmp);
        order.swap(order_tmp);
    }
    return order;
}

}  // namespace cb
