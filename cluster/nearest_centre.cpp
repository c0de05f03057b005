#include "nearest_centre.h"

#include <flann/flann.hpp>

#include <cmath>
#include <vector>

namespace cb {

// The tree wins from about 40 centres (bench_nearest_centre; figures in docs/PERFORMANCE.md). The default
// k0 = 8 never gets there; larger --k0 does.
const size_t flann_crossover = 40;

size_t assign_nearest_brute(const float* points, size_t n, const float* centres, size_t k, uint32_t* assignment,
                            float* nearest_d2) {
    size_t changed = 0;
    for (size_t i = 0; i < n; ++i) {
        const float* p = points + i * 6;
        float best = INFINITY;
        uint32_t best_c = 0;
        for (size_t c = 0; c < k; ++c) {
            const float* q = centres + c * 6;
            float d = 0;
            for (int j = 0; j < 6; ++j) d += (p[j] - q[j]) * (p[j] - q[j]);
            if (d < best) best = d, best_c = uint32_t(c);
        }
        changed += assignment[i] != best_c;
        assignment[i] = best_c;
        nearest_d2[i] = best;
    }
    return changed;
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
                      float* nearest_d2) {
    return k >= flann_crossover ? assign_nearest_flann(points, n, centres, k, assignment, nearest_d2)
                                : assign_nearest_brute(points, n, centres, k, assignment, nearest_d2);
}

}  // namespace cb
