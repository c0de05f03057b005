// What the benchmarks share: options, the scanned meshes they run on, the big merged scene, timing.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "scene.h"
#include "timing.h"

namespace cb::bench {

namespace fs = std::filesystem;

// A benchmark's main: runs `body`; an input that is missing or cannot be loaded ends the benchmark with
// one line on stderr and exit code 2, never an uncaught exception.
template <class Body>
int guarded_main(const char* name, Body body) {
    try {
        return body();
    } catch (const std::exception& e) {
        std::fprintf(stderr, "%s: %s\n", name, e.what());
        return 2;
    }
}

// The scenes folder must exist (the benchmarks read ../shared/data in place, or --data DIR).
inline void require_data(const fs::path& dir) {
    if (!fs::is_directory(dir))
        throw std::runtime_error(dir.string() +
                                 " is absent: the benchmarks read their scenes there (or give --data DIR)");
}

struct Options {
    fs::path data = fs::path(CB_SHARED_DATA);
    uint32_t fine = 16;
    int runs = 5;
    int copies = 25;             // copies of the dragon in the big scene (0: none)
    int view = 1024;             // bench_shadow: the camera's resolution
    std::string only;            // run only inputs whose name contains this
    int one_sided = 0;           // bench_shadow: 1 builds one-sided trees (chapter 2's mode for closed models)
    std::string level = "scan";  // bench_shadow: scan, top-two, top-one, mtsv-one, mtsv-two, or compare (all of them)
    int frames = 0;  // bench_shadow: N > 0 times only our frames (build and queries, one thread), N per light
};

// --data DIR --fine N --runs N --copies N --view N --only NAME --one-sided 0|1
// --traversal scan|top-two|top-one|mtsv-one|mtsv-two|compare --frames N, over the given defaults.
inline Options parse_options(int argc, char** argv, Options o) {
    for (int i = 1; i + 1 < argc; i += 2) {
        std::string a = argv[i];
        if (a == "--data")
            o.data = argv[i + 1];
        else if (a == "--fine")
            o.fine = uint32_t(std::stoul(argv[i + 1]));
        else if (a == "--runs")
            o.runs = std::stoi(argv[i + 1]);
        else if (a == "--copies")
            o.copies = std::stoi(argv[i + 1]);
        else if (a == "--view")
            o.view = std::stoi(argv[i + 1]);
        else if (a == "--only")
            o.only = argv[i + 1];
        else if (a == "--one-sided")
            o.one_sided = std::stoi(argv[i + 1]);
        else if (a == "--traversal")
            o.level = argv[i + 1];
        else if (a == "--frames")
            o.frames = std::stoi(argv[i + 1]);
        else
            std::fprintf(stderr, "ignoring unknown option %s\n", a.c_str());
    }
    require_data(o.data);
    return o;
}

inline bool wanted(const Options& o, const std::string& name) {
    return o.only.empty() || name.find(o.only) != std::string::npos;
}

// The scanned meshes of the shared data, sorted; empty (with a message) when the folder is missing.
inline std::vector<fs::path> scanned_meshes(const Options& o, const char* program) {
    std::vector<fs::path> files;
    if (!fs::exists(o.data / "scanned")) {
        std::fprintf(stderr, "%s: no scanned meshes under %s (pass --data DIR)\n", program, o.data.string().c_str());
        return files;
    }
    for (const auto& e : fs::directory_iterator(o.data / "scanned"))
        if (wanted(o, e.path().filename().string())) files.push_back(e.path());
    std::sort(files.begin(), files.end());
    return files;
}

// `copies` rotated copies of `base` on a grid 0.25 apart, merged into one mesh: the big scene (25 copies of
// the 202,520-triangle dragon make 5.06 M triangles).
inline Mesh merged_copies(const Mesh& base, int copies) {
    Mesh out;
    out.name = std::to_string(copies) + "x " + base.name;
    int side = int(std::ceil(std::sqrt(double(copies))));
    for (int c = 0; c < copies; ++c) {
        double a = 0.7 * c, s = 1.0 + 0.05 * (c % 5), ca = std::cos(a), sa = std::sin(a);
        double tx = (c % side) * 0.25, tz = (c / side) * 0.25;
        uint32_t offset = uint32_t(out.vertex_count());
        for (size_t k = 0; k < base.vertex_count(); ++k) {
            const float* p = &base.positions[k * 3];
            out.positions.insert(
                out.positions.end(),
                {float(s * (ca * p[0] + sa * p[2]) + tx), float(s * p[1]), float(s * (-sa * p[0] + ca * p[2]) + tz)});
        }
        for (uint32_t i : base.indices) out.indices.push_back(offset + i);
    }
    out.primitives.push_back({0, uint32_t(out.triangle_count()), false});
    return out;
}

template <class F>
double median_seconds(int runs, F&& f) {
    std::vector<double> t;
    for (int r = 0; r < std::max(1, runs); ++r) {
        auto start = std::chrono::steady_clock::now();
        f();
        t.push_back(seconds_since(start));
    }
    return median(t);
}

}  // namespace cb::bench
