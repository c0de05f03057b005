// What the example programs read from files: an asset, opened in place, and points. An engine has its own
// file system; these are here only so that the examples run from the command line.
#pragma once

#include <clusterbake/cb_asset.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

namespace example {

// The whole file in memory aligned for any standard type (malloc's guarantee), as the view's doubles need;
// null when it cannot be read. The caller frees it with std::free.
inline void* read_file(const char* path, size_t& size) {
    FILE* f = std::fopen(path, "rb");
    if (!f) return nullptr;
    std::fseek(f, 0, SEEK_END);
    const long length = std::ftell(f);
    std::fseek(f, 0, SEEK_SET);
    void* bytes = length > 0 ? std::malloc(size_t(length)) : nullptr;
    if (bytes && std::fread(bytes, 1, size_t(length), f) != size_t(length)) {
        std::free(bytes);
        bytes = nullptr;
    }
    std::fclose(f);
    size = size_t(length);
    return bytes;
}

// The asset file read (read_file) and opened into `view`; false after "PATH: error" on stderr.
inline bool open_asset_file(const char* path, void*& bytes, size_t& size, cb::AssetView& view) {
    bytes = read_file(path, size);
    const cb::AssetError error = bytes ? cb::open_asset(bytes, size, &view) : cb::AssetError::too_small;
    if (error == cb::AssetError::ok) return true;
    std::fprintf(stderr, "%s: %s\n", path, cb::asset_error_text(error));
    return false;
}

// Points, one "x y z" a line, as xyz triples; empty when the file cannot be read.
inline std::vector<double> read_points(const char* path) {
    std::vector<double> points;
    if (FILE* f = std::fopen(path, "r")) {
        double p[3];
        while (std::fscanf(f, "%lf %lf %lf", &p[0], &p[1], &p[2]) == 3) points.insert(points.end(), p, p + 3);
        std::fclose(f);
    }
    return points;
}

}  // namespace example
