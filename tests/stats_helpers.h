// What the statistics and report tests share: generated scenes, running the CLI, reading files and PNGs.
#pragma once

#include <png.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

#include "scene.h"

namespace cb::test {

inline Mesh mesh_of(std::vector<float> positions, std::vector<uint32_t> indices) {
    Mesh m;
    m.name = "generated";
    m.positions = std::move(positions);
    m.indices = std::move(indices);
    m.primitives.push_back({0, uint32_t(m.indices.size() / 3), false});
    return m;
}

inline Scene scene_of(Mesh m) {
    Scene s;
    s.meshes.push_back(std::move(m));
    s.instances.push_back({0, identity_transform(), "only"});
    return s;
}

// The cube [0, 1]^3, 12 triangles wound outward.
inline Mesh unit_cube() {
    std::vector<float> p;
    for (int i = 0; i < 8; ++i) p.insert(p.end(), {float(i & 1), float(i >> 1 & 1), float(i >> 2 & 1)});
    const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {1, 3, 7, 5}, {0, 4, 6, 2}};
    std::vector<uint32_t> t;
    for (const auto& q : quads) t.insert(t.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
    return mesh_of(p, t);
}

struct CliRun {
    int code = -1;
    std::string out, err;
};

inline std::string slurp(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Runs `program args`, capturing stdout and stderr in files named after this process (ctest runs tests
// in parallel).
inline CliRun run_program(const std::string& program, const std::string& args) {
    static int calls = 0;
    auto base = std::filesystem::temp_directory_path() /
        ("cb_stats_" + std::to_string(getpid()) + "_" + std::to_string(calls++));
    std::string out = base.string() + ".out", err = base.string() + ".err";
    int status = std::system((program + " " + args + " >" + out + " 2>" + err).c_str());
    CliRun r;
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = slurp(out);
    r.err = slurp(err);
    std::filesystem::remove(out);
    std::filesystem::remove(err);
    return r;
}

inline CliRun run_cli(const std::string& args) { return run_program(CB_CLI, args); }

struct Rgb {
    uint32_t width = 0, height = 0;
    std::vector<uint8_t> pixels;  // rgb
};

// Decodes any PNG to 8-bit RGB with libpng; width 0 when it does not decode.
inline Rgb read_png(const std::string& path) {
    Rgb out;
    png_image img{};
    img.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&img, path.c_str())) return out;
    img.format = PNG_FORMAT_RGB;
    std::vector<uint8_t> buf(PNG_IMAGE_SIZE(img));
    if (!png_image_finish_read(&img, nullptr, buf.data(), 0, nullptr)) return out;
    out.width = img.width;
    out.height = img.height;
    out.pixels = std::move(buf);
    return out;
}

// Variance of the grey level over every pixel.
inline double grey_variance(const Rgb& img) {
    double sum = 0, sum2 = 0;
    size_t n = size_t(img.width) * img.height;
    for (size_t i = 0; i < n; ++i) {
        double g = (img.pixels[i * 3] + img.pixels[i * 3 + 1] + img.pixels[i * 3 + 2]) / 3.0;
        sum += g;
        sum2 += g * g;
    }
    return n ? sum2 / n - (sum / n) * (sum / n) : 0;
}

}  // namespace cb::test
