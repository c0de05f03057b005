// Nearest-centre assignment for Lloyd iterations over 6-D points.
#pragma once

#include <cstddef>
#include <cstdint>

namespace cb {

// The centre count from which FLANN's exact k-d tree beats the brute-force scan (bench_nearest_centre
// measures both; the figures are in docs/PERFORMANCE.md).
extern const size_t flann_crossover;

// Sets assignment[i] to the index of the centre nearest points[i] (ties: lowest index) and nearest_d2[i]
// to its squared distance; returns how many assignments changed. Brute force below flann_crossover
// centres, FLANN above.
size_t assign_nearest(const float* points, size_t n, const float* centres, size_t k, uint32_t* assignment,
                      float* nearest_d2);

// Both strategies, always, for the benchmark and the tests.
size_t assign_nearest_brute(const float* points, size_t n, const float* centres, size_t k, uint32_t* assignment,
                            float* nearest_d2);
size_t assign_nearest_flann(const float* points, size_t n, const float* centres, size_t k, uint32_t* assignment,
                            float* nearest_d2);

}  // namespace cb
