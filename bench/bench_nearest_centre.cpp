// Nearest-centre search inside Lloyd iterations: brute force against FLANN's exact k-d tree, for growing
// centre counts, on triangle boxes of a real mesh (6-D points). Prints the table behind flann_crossover.
//
//   bench_nearest_centre [MESH] [POINTS=2048]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>
#include <random>
#include <string>
#include <vector>

#include "load.h"
#include "nearest_centre.h"

static int run(int argc, char** argv) {
    std::string mesh = argc > 1 ? argv[1] : std::string(CB_SHARED_DATA) + "/scanned/dragon_vrip_res2_binary.ply";
    size_t n = argc > 2 ? std::stoul(argv[2]) : 2048;
    cb::Scene scene = cb::load_scene(mesh);
    const cb::Mesh& m = scene.meshes[0];
    // Boxes of a random contiguous run of triangles, as a k-means node would see them.
    std::vector<float> points(n * 6);
    std::mt19937 rng(1);
    size_t start = rng() % (m.triangle_count() - n);
    for (size_t i = 0; i < n; ++i)
        for (int k = 0; k < 3; ++k) {
            const uint32_t* t = &m.indices[(start + i) * 3];
            float a = m.positions[t[0] * 3 + k], b = m.positions[t[1] * 3 + k], c = m.positions[t[2] * 3 + k];
            points[i * 6 + k] = std::min({a, b, c});
            points[i * 6 + 3 + k] = std::max({a, b, c});
        }
    std::printf("%zu points from %s; microseconds per assignment pass, median of 9\n\n", n, mesh.c_str());
    std::printf("| centres | brute force | FLANN k-d tree | FLANN / brute |\n|---|---|---|---|\n");
    std::vector<uint32_t> assignment(n);
    std::vector<float> d2(n);
    for (size_t k : {4, 8, 16, 32, 48, 64, 96, 128, 256, 512}) {
        if (k > n) break;
        std::vector<float> centres;
        for (size_t c = 0; c < k; ++c)
            centres.insert(centres.end(), &points[(c * n / k) * 6], &points[(c * n / k) * 6 + 6]);
        auto time = [&](auto&& f) {
            std::vector<double> t;
            for (int r = 0; r < 9; ++r) {
                auto s = std::chrono::steady_clock::now();
                f();
                t.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - s).count());
            }
            std::sort(t.begin(), t.end());
            return t[4];
        };
        double brute =
            time([&] { cb::assign_nearest_brute(points.data(), n, centres.data(), k, assignment.data(), d2.data()); });
        double flann =
            time([&] { cb::assign_nearest_flann(points.data(), n, centres.data(), k, assignment.data(), d2.data()); });
        std::printf("| %zu | %.1f | %.1f | %.2f |\n", k, brute, flann, flann / brute);
    }
    std::printf("\nflann_crossover in use: %zu centres\n", cb::flann_crossover);
    return 0;
}

int main(int argc, char** argv) {
    try {
        return run(argc, argv);
    } catch (const std::exception& e) {  // a missing or unreadable mesh: one line, exit code 2
        std::fprintf(stderr, "bench_nearest_centre: %s\n", e.what());
        return 2;
    }
}
