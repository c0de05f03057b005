#include "nearest_centre.h"

#include <flann/flann.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

#include "vector_clones.h"

namespace cb {

// The tree wins from about 256 centres (bench_nearest_centre; figures in docs/PERFORMANCE.md): below, the
// blocked scan's vector lanes beat its search. The default k0 = 8 never gets there; a large --k0 does.
const size_t flann_crossover = 256;

// A centre's six coordinates, held by value so that a loop over points keeps them in registers.
struct Centre {
    float q[6];
};

// The squared distance from point i of six coordinate arrays to centre c: the six terms summed in coordinate
// order, as a point-by-point scan sums them, so the same float in any lane.
inline float distance2_at(const float* const x[6], size_t i, const Centre& c) {
    float d = 0;
    for (int j = 0; j < 6; ++j) {
        const float e = x[j][i] - c.q[j];
        d += e * e;
    }
    return d;
}

// The scan of one block of `nearest_block` points, given as six coordinate arrays, over the k centres: each
// distance sums its six terms in coordinate order, and a centre replaces the best only when strictly
// nearer, so the same floats and the same ties as a point-by-point scan. Inlined into each clone below.
constexpr size_t nearest_block = 64;
[[gnu::always_inline]] inline size_t scan_block(const float* const x[6], size_t m, const float* centres, size_t k,
                                                uint32_t* assignment, float* nearest_d2) {
    alignas(64) float best[nearest_block];
    alignas(64) uint32_t best_c[nearest_block];
    for (size_t i = 0; i < nearest_block; ++i) {
        best[i] = INFINITY;
        best_c[i] = 0;
    }
    for (size_t c = 0; c < k; ++c) {
        Centre q;
        std::copy_n(centres + c * 6, 6, q.q);
        const uint32_t id = uint32_t(c);
        for (size_t i = 0; i < nearest_block; ++i) {
            const float d = distance2_at(x, i, q);
            // Branch-free so that the compiler keeps the lanes: an all-ones mask where nearer.
            const uint32_t nearer = 0u - uint32_t(d < best[i]);
            best_c[i] = (id & nearer) | (best_c[i] & ~nearer);
            best[i] = d < best[i] ? d : best[i];
        }
    }
    size_t changed = 0;
    for (size_t i = 0; i < m; ++i) {
        changed += assignment[i] != best_c[i];
        assignment[i] = best_c[i];
        nearest_d2[i] = best[i];
    }
    return changed;
}

// Cloned (vector_clones.h): the block scan then takes 16 or 8 points a step instead of 4.
CB_VECTOR_CLONES size_t assign_nearest_brute(const float* points, size_t n, const float* centres, size_t k,
                                             uint32_t* assignment, float* nearest_d2) {
    // Blocks of points transposed to one array per coordinate, so the scan over a block runs across points
    // in vector lanes.
    alignas(64) float x[6][nearest_block];
    const float* const lanes[6] = {x[0], x[1], x[2], x[3], x[4], x[5]};
    size_t changed = 0;
    for (size_t at = 0; at < n; at += nearest_block) {
        const size_t m = std::min(nearest_block, n - at);
        for (size_t i = 0; i < m; ++i)
            for (int j = 0; j < 6; ++j) x[j][i] = points[(at + i) * 6 + j];
        for (size_t i = m; i < nearest_block; ++i)
            for (int j = 0; j < 6; ++j) x[j][i] = 0;
        changed += scan_block(lanes, m, centres, k, assignment + at, nearest_d2 + at);
    }
    return changed;
}

CB_VECTOR_CLONES size_t assign_nearest_coords(const float* coords, size_t n, const float* centres, size_t k,
                                              uint32_t* assignment, float* nearest_d2) {
    // Whole blocks straight from the arrays; the last, partial one copied out and padded.
    alignas(64) float x[6][nearest_block];
    size_t changed = 0;
    for (size_t at = 0; at < n; at += nearest_block) {
        const size_t m = std::min(nearest_block, n - at);
        const float* lanes[6];
        for (int j = 0; j < 6; ++j) lanes[j] = coords + size_t(j) * n + at;
        if (m < nearest_block) {
            for (int j = 0; j < 6; ++j) {
                std::copy_n(lanes[j], m, x[j]);
                std::fill(x[j] + m, x[j] + nearest_block, 0.0f);
                lanes[j] = x[j];
            }
        }
        changed += scan_block(lanes, m, centres, k, assignment + at, nearest_d2 + at);
    }
    return changed;
}

CB_VECTOR_CLONES void lower_nearest(const float* coords, size_t n, const float* centre, float* nearest_d2,
                                    double* block_sums) {
    const float* x[6];
    for (int j = 0; j < 6; ++j) x[j] = coords + size_t(j) * n;
    Centre q;
    std::copy_n(centre, 6, q.q);
    for (size_t i = 0; i < n; ++i) {
        const float d = distance2_at(x, i, q);
        nearest_d2[i] = d < nearest_d2[i] ? d : nearest_d2[i];
    }
    // Each block sums in 8 running sums (point i into sum i mod 8), then those in a fixed tree: lanes for
    // any vector width, and the same doubles on every processor.
    constexpr size_t lanes = 8;
    for (size_t b = 0; b * lower_nearest_block < n; ++b) {
        const size_t at = b * lower_nearest_block, m = std::min(lower_nearest_block, n - at);
        double acc[lanes] = {};
        size_t i = 0;
        for (; i + lanes <= m; i += lanes)
            for (size_t l = 0; l < lanes; ++l) acc[l] += nearest_d2[at + i + l];
        for (; i < m; ++i) acc[i % lanes] += nearest_d2[at + i];
        block_sums[b] = ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]));
    }
}

size_t assign_nearest_flann(const float* points, size_t n, const float* centres, size_t k, uint32_t* assignment,
                            float* nearest_d2) {
    flann::Matrix<float> data(const_cast<float*>(centres), k, 6);
    flann::Index<flann::L2<float>> index(data, flann::KDTreeSingleIndexParams(8));  // exact search
    index.buildIndex();
    flann::Matrix<float> query(const_cast<float*>(points), n, 6);
    std::vector<size_t> found(n);
    std::vector<float> dist(n);
    flann::Matrix<size_t> found_m(found.data(), n, 1);
    flann::Matrix<float> dist_m(dist.data(), n, 1);
    flann::SearchParams params;
    params.cores = 1;  // parallelism is over coarse chunks, one level up
    index.knnSearch(query, found_m, dist_m, 1, params);
    size_t changed = 0;
    for (size_t i = 0; i < n; ++i) {
        uint32_t c = uint32_t(found[i]);
        changed += assignment[i] != c;
        assignment[i] = c;
        nearest_d2[i] = dist[i];
    }
    return changed;
}

size_t assign_nearest(const float* points, size_t n, const float* centres, size_t k, uint32_t* assignment,
                      float* nearest_d2, const float* coords) {
    if (k >= flann_crossover) return assign_nearest_flann(points, n, centres, k, assignment, nearest_d2);
    return coords ? assign_nearest_coords(coords, n, centres, k, assignment, nearest_d2)
                  : assign_nearest_brute(points, n, centres, k, assignment, nearest_d2);
}

}  // namespace cb
