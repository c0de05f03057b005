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
// centres, FLANN above. `coords`, when given, holds the same points as six coordinate arrays (as
// lower_nearest takes them), which the brute-force scan then reads instead of transposing `points`.
size_t assign_nearest(const float* points, size_t n, const float* centres, size_t k, uint32_t* assignment,
                      float* nearest_d2, const float* coords = nullptr);

// k-means++ seeding's pass for one new centre over points given as six coordinate arrays (`coords`, each of
// `n` floats: all the x of the boxes' minima, then all their y, ...). Lowers nearest_d2[i] to the squared
// distance from point i to `centre` where that is smaller, and sets block_sums[b] to the sum of the lowered
// nearest_d2 over points [64 b, 64 b + 64), in double, in an order fixed by the indices alone.
void lower_nearest(const float* coords, size_t n, const float* centre, float* nearest_d2, double* block_sums);
constexpr size_t lower_nearest_block = 64;

// Each strategy, always, for the benchmark and the tests: the brute-force scan over 6-float records and over
// coordinate arrays, and FLANN.
size_t assign_nearest_brute(const float* points, size_t n, const float* centres, size_t k, uint32_t* assignment,
                            float* nearest_d2);
size_t assign_nearest_coords(const float* coords, size_t n, const float* centres, size_t k, uint32_t* assignment,
                             float* nearest_d2);
size_t assign_nearest_flann(const float* points, size_t n, const float* centres, size_t k, uint32_t* assignment,
                            float* nearest_d2);

}  // namespace cb
