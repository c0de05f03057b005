// Batch queries: arrays of points against one light's traversals (InstanceShadow, or any traversal type
// of cb_tile.h), one per instance, all built for the same light. The points are sorted by their direction
// from the light (cube face, then a Z-order curve on it) and taken in tiles of tile_capacity, each with the
// pyramid from the light that holds their directions (occluded_tile): one scan, or one walk of each tree,
// per tile; the answers are those of a query per point. `scratch` holds batch_scratch_size() words. The
// traversals are const: callers may split the points across threads, each with its own scratch. To split one
// batch across threads, order it once (batch_order) and give each thread ranges of that order
// (occluded_ordered): points close in direction then share tiles, and slices of the caller's array would not
// (a slice of an image is a band of it, whose tiles are narrower and more of them meet its edges).
// Header-only C++17, no exceptions, no allocation. MIT licensed (runtime/LICENSE).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <new>

#include "cb_segment.h"
#include "detail/cb_simd.h"
#include "detail/cb_tile.h"

namespace cb {
inline namespace CB_LANES {

namespace detail {

// The batch's stack: room for the deepest of the trees.
template <class Shadows>
size_t batch_stack_size(const Shadows* trees, size_t tree_count) {
    size_t stack = 0;
    for (size_t t = 0; t < tree_count; ++t) stack = std::max(stack, trees[t].stack_size());
    return stack;
}

}  // namespace detail

// Words of scratch batch_order needs for n points (batch_order_from_keys: n fewer).
inline size_t batch_order_scratch_size(size_t n) { return 2 * n + 6144; }

// keys[i - first] for the points [first, last) (xyz doubles): what batch_order sorts them by, their direction
// from `light`, 23 bits: the cube face (3 bits), then the two face coordinates' bits interleaved (10 each), a
// Z-order curve on the face; zero or non-finite directions get the largest key. Threads may each take a part
// of a batch's points. The order only groups points into tiles, never decides an answer, so the keys are made
// in float (a difference beyond float's range rounds to infinity, IEEE 754, and so gets the largest key), with
// selects and a sign bit rather than a comparison that could trap in a branch, so that the compiler makes a
// vector of keys an instruction.
inline void batch_keys(const double* light, const double* points, size_t first, size_t last, uint32_t* keys) {
    const double lx = light[0], ly = light[1], lz = light[2];
    auto spread = [](uint32_t v) {
        v = (v | v << 8) & 0x00ff00ffu;
        v = (v | v << 4) & 0x0f0f0f0fu;
        v = (v | v << 2) & 0x33333333u;
        v = (v | v << 1) & 0x55555555u;
        return v;
    };
    for (size_t i = first; i < last; ++i) {
        const float x = float(points[i * 3] - lx), y = float(points[i * 3 + 1] - ly), z = float(points[i * 3 + 2] - lz);
        const float ax = std::fabs(x), ay = std::fabs(y), az = std::fabs(z);
        const bool on_x = (ax >= ay) & (ax >= az), on_y = !on_x & (ay >= az);  // the major axis m (else z)
        const float major = on_x ? ax : on_y ? ay : az, sign = on_x ? x : on_y ? y : z;
        const float a = on_x ? y : on_y ? z : x, b = on_x ? z : on_y ? x : y;  // axes m + 1 and m + 2 (mod 3)
        const float scale = 511.5f / major;
        float ca = a * scale + 511.5f, cb = b * scale + 511.5f;
        ca = ca > 0 ? ca : 0.0f;
        cb = cb > 0 ? cb : 0.0f;
        ca = ca < 1023.0f ? ca : 1023.0f;
        cb = cb < 1023.0f ? cb : 1023.0f;
        const uint32_t face = uint32_t(on_x ? 0 : on_y ? 2 : 4) + uint32_t(std::signbit(sign));
        const uint32_t key = face << 20 | spread(uint32_t(int32_t(ca))) | spread(uint32_t(int32_t(cb))) << 1;
        keys[i - first] = ((major > 0) & (major < INFINITY)) ? key : 0x7fffffu;  // zero or not finite: last
    }
}

// order[0, n): the indices 0..n-1 sorted by keys[0, n) (batch_keys), stably. `scratch` holds
// batch_order_scratch_size(n) - n words.
inline void batch_order_from_keys(const uint32_t* keys, size_t n, uint32_t* order, uint32_t* scratch) {
    // A few points (a small mesh's view): a comparison sort of (key, index) pairs gives the same order
    // without the radix sort's 6,144 counts to clear and sum, the most of its cost under a few hundred points.
    constexpr size_t few = 256;
    if (n <= few) {
        uint64_t pairs[few];
        for (size_t i = 0; i < n; ++i) pairs[i] = uint64_t(keys[i] & 0x7fffffu) << 32 | i;
        // A comparator of these lanes' own: std::sort's instance for plain integers would be shared with the
        // builds for other lanes (cb_simd.h), and the linker could keep a wider build's copy.
        std::sort(pairs, pairs + n, [](uint64_t a, uint64_t b) { return a < b; });
        for (size_t i = 0; i < n; ++i) order[i] = uint32_t(pairs[i]);
        return;
    }
    // Radix sort, 12 then 11 bits, both counts in one pass. The passes move indices only, the second reading
    // each key through its index (the keys, just read by the first pass, are mostly still in cache): half the
    // bytes written of moving key and index together.
    uint32_t *moved = scratch, *low = scratch + n, *high = low + 4096;
    std::fill(low, low + 4096 + 2048, 0u);
    for (size_t i = 0; i < n; ++i) {
        ++low[keys[i] & 4095];
        ++high[keys[i] >> 12 & 2047];
    }
    auto starts = [](uint32_t* count, int buckets) {
        uint32_t sum = 0;
        for (int b = 0; b < buckets; ++b) {
            sum += count[b];
            count[b] = sum - count[b];
        }
    };
    starts(low, 4096);
    starts(high, 2048);
    for (size_t i = 0; i < n; ++i) moved[low[keys[i] & 4095]++] = uint32_t(i);
    for (size_t i = 0; i < n; ++i) order[high[keys[moved[i]] >> 12 & 2047]++] = moved[i];
}

// order[0, n): the indices of the n points (xyz doubles) sorted by direction from `light`, the order
// occluded_batch takes them in: batch_keys then batch_order_from_keys. `scratch` holds
// batch_order_scratch_size(n) words.
inline void batch_order(const double* light, const double* points, size_t n, uint32_t* order, uint32_t* scratch) {
    uint32_t* keys = scratch + n + 6144;  // past what batch_order_from_keys uses
    batch_keys(light, points, 0, n, keys);
    batch_order_from_keys(keys, n, order, scratch);
}

// The same for a sun (a light at infinity in direction `toward`, cb_segment.h): the points sorted by where
// they lie across the direction (a Z-order curve over the rectangle that bounds their projections onto the
// plane across it, 10 bits a side), since every point's ray runs the same way; points that are not finite
// come last. `scratch` holds batch_order_scratch_size(n) words.
inline void sun_batch_order(const double* toward, const double* points, size_t n, uint32_t* order, uint32_t* scratch) {
    uint32_t* keys = scratch + n + 6144;  // past what batch_order_from_keys uses
    double frame[3][3];
    if (!direction_frame(toward, frame)) {
        for (size_t i = 0; i < n; ++i) order[i] = uint32_t(i);
        return;
    }
    auto spread = [](uint32_t v) {
        v = (v | v << 8) & 0x00ff00ffu;
        v = (v | v << 4) & 0x0f0f0f0fu;
        v = (v | v << 2) & 0x33333333u;
        v = (v | v << 1) & 0x55555555u;
        return v;
    };
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (size_t i = 0; i < n; ++i) {
        const double* p = points + i * 3;
        const double a = p[0] * frame[1][0] + p[1] * frame[1][1] + p[2] * frame[1][2],
                     b = p[0] * frame[2][0] + p[1] * frame[2][1] + p[2] * frame[2][2];
        if (!(std::fabs(a) < INFINITY && std::fabs(b) < INFINITY)) continue;
        lo[0] = std::min(lo[0], a);
        hi[0] = std::max(hi[0], a);
        lo[1] = std::min(lo[1], b);
        hi[1] = std::max(hi[1], b);
    }
    const double scale[2] = {hi[0] > lo[0] ? 1023.0 / (hi[0] - lo[0]) : 0.0,
                             hi[1] > lo[1] ? 1023.0 / (hi[1] - lo[1]) : 0.0};
    for (size_t i = 0; i < n; ++i) {
        const double* p = points + i * 3;
        const double a = p[0] * frame[1][0] + p[1] * frame[1][1] + p[2] * frame[1][2],
                     b = p[0] * frame[2][0] + p[1] * frame[2][1] + p[2] * frame[2][2];
        if (!(std::fabs(a) < INFINITY && std::fabs(b) < INFINITY)) {
            keys[i] = 0x7fffffu;
            continue;
        }
        auto cell = [](double x) { return x > 0 ? (x < 1023 ? uint32_t(x) : 1023u) : 0u; };  // NaN (inf x 0): 0
        keys[i] = spread(cell((a - lo[0]) * scale[0])) | spread(cell((b - lo[1]) * scale[1])) << 1;
    }
    batch_order_from_keys(keys, n, order, scratch);
}

// The order a batch over `shadows` takes: batch_order from their light, or sun_batch_order for a sun.
template <class Shadows>
void batch_order_for(const Shadows& shadows, const double* points, size_t n, uint32_t* order, uint32_t* scratch) {
    if (shadows.sun())
        sun_batch_order(shadows.world_light(), points, n, order, scratch);
    else
        batch_order(shadows.world_light(), points, n, order, scratch);
}

// Words of scratch occluded_ordered needs: the stack and the tables kept from tile to tile.
template <class Shadows>
size_t ordered_scratch_size(const Shadows* trees, size_t tree_count) {
    const size_t cache = sizeof(TileCache) + alignof(TileCache);
    return detail::batch_stack_size(trees, tree_count) + (cache + sizeof(uint32_t) - 1) / sizeof(uint32_t);
}

// The points order[0, count) of `points`, in that order (a range of batch_order's), in tiles: out[order[i]]
// is 1 when that point is in shadow. `scratch` holds ordered_scratch_size() words.
template <class Shadows>
void occluded_ordered(const Shadows* trees, size_t tree_count, const double* points, const uint32_t* order,
                      size_t count, uint8_t* out, uint32_t* scratch, QueryStats* stats = nullptr) {
    if (tree_count == 0) {
        for (size_t i = 0; i < count; ++i) out[order[i]] = 0;
        return;
    }
    uint32_t* stack = scratch;
    const uintptr_t at = reinterpret_cast<uintptr_t>(stack + detail::batch_stack_size(trees, tree_count));
    TileCache* cache =
        new (reinterpret_cast<void*>((at + alignof(TileCache) - 1) / alignof(TileCache) * alignof(TileCache)))
            TileCache;
    cache->clear();
    for (size_t first = 0; first < count; first += tile_capacity) {
        uint32_t tile = uint32_t(std::min<size_t>(tile_capacity, count - first));
        // The next tile's points, asked for now: sorted by direction, they lie all over the caller's array.
        for (size_t i = first + tile; i < std::min(count, first + tile + tile_capacity); ++i)
            simd::prefetch(points + size_t(order[i]) * 3);
        uint64_t alive = tile == 64 ? ~uint64_t(0) : (uint64_t(1) << tile) - 1, shadowed = 0;
        for (size_t t = 0; t < tree_count && alive; ++t) {
            uint64_t s = trees[t].occluded_tile(points, order + first, tile, alive, stack, stats, cache);
            shadowed |= s;
            alive &= ~s;
        }
        for (uint32_t i = 0; i < tile; ++i) out[order[first + i]] = uint8_t(shadowed >> i & 1);
    }
}

template <class Shadows>
size_t batch_scratch_size(const Shadows* trees, size_t tree_count, size_t n) {
    return n + std::max(batch_order_scratch_size(n), ordered_scratch_size(trees, tree_count));
}

// The batch form: out[i] is 1 when point i (xyz doubles) is in shadow. batch_order, then occluded_ordered
// over the whole order.
template <class Shadows>
void occluded_batch(const Shadows* trees, size_t tree_count, const double* points, size_t n, uint8_t* out,
                    uint32_t* scratch, QueryStats* stats = nullptr) {
    if (tree_count == 0) {
        std::fill(out, out + n, uint8_t(0));
        return;
    }
    uint32_t* order = scratch;
    batch_order_for(trees[0], points, n, order, scratch + n);
    occluded_ordered(trees, tree_count, points, order, n, out, scratch + n, stats);
}

}  // namespace CB_LANES
}  // namespace cb
