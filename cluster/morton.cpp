// Morton order of triangles: 21 bits per axis of each triangle's box centre, radix sorted.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <utility>

#include "cluster.h"
#include "parallel.h"
#include "populate_pages.h"
#include "unset_vector.h"

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

// Key sorting: stable counting passes, each on the highest digit in which a range's keys differ, splitting
// the range into one range per digit value, which are sorted the same way in turn; ranges of a few keys sort
// by insertion. The first split runs across the whole array in parallel parts, the rest range by range, in
// cache. A digit is about log2(n) - 2 bits wide: a few keys per value, so that a range of a few thousand
// keys is sorted after one or two passes, where passes per digit from the lowest (LSD) take five to seven
// over the 40 to 50 bits in which such a range of Morton codes differs. Every step is stable, so the order is
// the one stable order of the keys whatever the thread count.
constexpr int radix_bits = 11;                    // at most 2048 counts: 8 KB, in the first-level cache
constexpr int least_bits = 4;                     // 16 counts for the smallest ranges split
constexpr size_t cached_limit = size_t(1) << 16;  // 64 Ki keys with their indices and scatter room: 1.5 MB
constexpr size_t insertion_limit = 32;

// The bits in which some of the n keys differ from the first.
uint64_t differing_bits(const uint64_t* keys, size_t n) {
    uint64_t d = 0;
    for (size_t i = 1; i < n; ++i) d |= keys[i] ^ keys[0];
    return d;
}

// The scatter room's keys. The room may be a caller's array of uint32_t lent for the sort (sort_keys), so its
// keys are read and written through a type that may alias it.
typedef uint64_t __attribute__((may_alias)) RoomKey;

// A stable counting pass on the `bits`-bit digit at `shift`, from (keys, order) to (to_keys, to_order);
// `count` (2^bits entries) ends holding each digit's end.
void scatter_digit(const uint64_t* keys, const uint32_t* order, size_t n, int shift, int bits, uint32_t* count,
                   RoomKey* to_keys, uint32_t* to_order) {
    const size_t digits = size_t(1) << bits;
    const uint64_t mask = digits - 1;
    std::fill_n(count, digits, 0u);
    for (size_t i = 0; i < n; ++i) ++count[(keys[i] >> shift) & mask];
    uint32_t sum = 0;
    for (size_t d = 0; d < digits; ++d) {
        const uint32_t c = count[d];
        count[d] = sum;
        sum += c;
    }
    for (size_t i = 0; i < n; ++i) {
        const uint32_t slot = count[(keys[i] >> shift) & mask]++;
        to_keys[slot] = keys[i];
        to_order[slot] = order[i];
    }
}

// Sorts (keys, order)[0, n) stably by key, with (tmp_keys, tmp_order)[0, n) as scatter room. Each level
// splits below the highest differing bit of the one before, so the recursion is at most 64 / least_bits
// deep.
void sort_range(uint64_t* keys, uint32_t* order, RoomKey* tmp_keys, uint32_t* tmp_order, size_t n) {
    if (n <= insertion_limit) {
        for (size_t i = 1; i < n; ++i) {
            const uint64_t k = keys[i];
            const uint32_t o = order[i];
            size_t j = i;
            for (; j > 0 && keys[j - 1] > k; --j) {
                keys[j] = keys[j - 1];
                order[j] = order[j - 1];
            }
            keys[j] = k;
            order[j] = o;
        }
        return;
    }
    const uint64_t differ = differing_bits(keys, n);
    if (!differ) return;
    const int top = 64 - std::countl_zero(differ);
    const int bits = std::clamp(int(std::bit_width(n)) - 2, least_bits, radix_bits);
    const int shift = std::max(0, top - bits);
    uint32_t count[size_t(1) << radix_bits];
    scatter_digit(keys, order, n, shift, bits, count, tmp_keys, tmp_order);
    std::copy_n(tmp_keys, n, keys);
    std::copy_n(tmp_order, n, order);
    for (size_t d = 0, start = 0; d < (size_t(1) << bits); start = count[d++])
        sort_range(keys + start, order + start, tmp_keys + start, tmp_order + start, count[d] - start);
}

}  // namespace

void sort_keys(uint64_t* keys, uint32_t* order, size_t n, unsigned threads, uint32_t* scratch) {
    const Parts parts(n, size_t(1) << 16);
    std::vector<uint64_t> part_differ(parts.count());
    parallel_for(parts.count(), threads, [&](size_t p) {
        uint64_t d = 0;
        for (size_t i = parts.first(p); i < parts.last(p); ++i) {
            order[i] = uint32_t(i);
            d |= keys[i] ^ keys[0];
        }
        part_differ[p] = d;
    });
    uint64_t differ = 0;
    for (uint64_t d : part_differ) differ |= d;
    if (!differ) return;
    // The scatter room: the caller's, or fresh.
    UnsetVector<uint32_t> own;
    if (!scratch) {
        parallel_resize(own, 3 * n, threads);
        scratch = own.data();
    }
    RoomKey* const tmp_keys = reinterpret_cast<RoomKey*>(scratch);
    uint32_t* const tmp_order = scratch + 2 * n;
    if (n <= cached_limit) return sort_range(keys, order, tmp_keys, tmp_order, n);

    // The split on the highest differing digit: each part counts its digits, then scatters its keys to
    // their digit's range after those of earlier parts.
    const int shift = std::max(0, 64 - std::countl_zero(differ) - radix_bits);
    constexpr size_t digits = size_t(1) << radix_bits;
    constexpr uint64_t mask = digits - 1;
    std::vector<uint32_t> count(parts.count() * digits);
    parallel_for(parts.count(), threads, [&](size_t p) {
        uint32_t* c = &count[p * digits];
        for (size_t i = parts.first(p); i < parts.last(p); ++i) ++c[(keys[i] >> shift) & mask];
    });
    std::vector<size_t> digit_start(digits + 1);
    uint32_t sum = 0;
    for (size_t d = 0; d < digits; ++d) {
        digit_start[d] = sum;
        for (size_t p = 0; p < parts.count(); ++p) {
            const uint32_t c = count[p * digits + d];
            count[p * digits + d] = sum;
            sum += c;
        }
    }
    digit_start[digits] = n;
    parallel_for(parts.count(), threads, [&](size_t p) {
        uint32_t* c = &count[p * digits];
        for (size_t i = parts.first(p); i < parts.last(p); ++i) {
            const uint32_t slot = c[(keys[i] >> shift) & mask]++;
            tmp_keys[slot] = keys[i];
            tmp_order[slot] = order[i];
        }
    });
    parallel_for(parts.count(), threads, [&](size_t p) {
        std::copy(tmp_keys + parts.first(p), tmp_keys + parts.last(p), keys + parts.first(p));
        std::copy(tmp_order + parts.first(p), tmp_order + parts.last(p), order + parts.first(p));
    });
    parallel_for(digits, threads, [&](size_t d) {
        const size_t start = digit_start[d], size = digit_start[d + 1] - start;
        sort_range(keys + start, order + start, tmp_keys + start, tmp_order + start, size);
    });
}

UnsetVector<uint32_t> morton_order(const float* positions, const uint32_t* indices, size_t triangle_count,
                                   unsigned threads, uint32_t* scratch) {
    // Bounds and keys in parts of consecutive triangles, one item of parallel_for each; sort_keys sorts them
    // in parts of its own, with the one answer of a stable sort.
    const Parts parts(triangle_count, size_t(1) << 16);
    double lo[3], hi[3];
    parallel_box(
        parts, threads, [&](size_t t, int k) { return doubled_centre(positions, indices + t * 3, k); }, lo, hi);
    const double cells = double((1u << 21) - 1);
    double scale[3];
    for (int k = 0; k < 3; ++k) scale[k] = hi[k] > lo[k] ? cells / (hi[k] - lo[k]) : 0.0;

    UnsetVector<uint64_t> keys;
    parallel_resize(keys, triangle_count, threads);
    parallel_for(parts.count(), threads, [&](size_t p) {
        for (size_t t = parts.first(p); t < parts.last(p); ++t) {
            uint64_t code = 0;
            for (int k = 0; k < 3; ++k) {
                double q = std::clamp((doubled_centre(positions, indices + t * 3, k) - lo[k]) * scale[k], 0.0, cells);
                code |= spread3(uint64_t(q)) << k;
            }
            keys[t] = code;
        }
    });
    UnsetVector<uint32_t> order;
    parallel_resize(order, triangle_count, threads);
    sort_keys(keys.data(), order.data(), triangle_count, threads, scratch);
    return order;
}

}  // namespace cb
