#include "load.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <new>

#include "file_access.h"
#include "parallel.h"

namespace cb {

Scene load_scene_unguarded(const std::string& path, const LoadOptions& options);

Transform multiply(const Transform& a, const Transform& b) {
    Transform r{};
    for (int col = 0; col < 4; ++col)
        for (int row = 0; row < 4; ++row) {
            double s = 0;
            for (int k = 0; k < 4; ++k) s += a[k * 4 + row] * b[col * 4 + k];
            r[col * 4 + row] = s;
        }
    return r;
}

bool is_degenerate(const Mesh& mesh, size_t t) {
    const uint32_t* i = &mesh.indices[t * 3];
    if (i[0] == i[1] || i[1] == i[2] || i[0] == i[2]) return true;
    const float* a = &mesh.positions[size_t(i[0]) * 3];
    const float* b = &mesh.positions[size_t(i[1]) * 3];
    const float* c = &mesh.positions[size_t(i[2]) * 3];
    double u[3], v[3];
    for (int k = 0; k < 3; ++k) {
        u[k] = double(b[k]) - a[k];
        v[k] = double(c[k]) - a[k];
    }
    // Zero area as computed in double from the stored floats.
    return u[1] * v[2] - u[2] * v[1] == 0 && u[2] * v[0] - u[0] * v[2] == 0 && u[0] * v[1] - u[1] * v[0] == 0;
}

namespace {

// A part of a mesh's elements for a thread: large enough that starting threads costs little beside it.
constexpr size_t smallest_part = size_t(1) << 18;

}  // namespace

uint64_t count_degenerate(const Mesh& mesh, unsigned threads) {
    const Parts parts(mesh.triangle_count(), smallest_part);
    std::vector<uint64_t> part_degenerate(parts.count(), 0);
    parallel_for(parts.count(), threads, [&](size_t p) {
        for (size_t t = parts.first(p); t < parts.last(p); ++t) part_degenerate[p] += is_degenerate(mesh, t);
    });
    uint64_t n = 0;
    for (uint64_t d : part_degenerate) n += d;
    return n;
}

namespace {

// The first i in [0, n) with fails(i), or SIZE_MAX: each part finds its own first, and the lowest of those is
// the one a scan from 0 finds.
template <class Fails>
size_t first_failing(size_t n, unsigned threads, Fails&& fails) {
    const Parts parts(n, smallest_part);
    std::vector<size_t> first(std::max<size_t>(1, parts.count()), SIZE_MAX);
    parallel_for(parts.count(), threads, [&](size_t p) {
        for (size_t i = parts.first(p); i < parts.last(p); ++i)
            if (fails(i)) {
                first[p] = i;
                return;
            }
    });
    return *std::min_element(first.begin(), first.end());
}

}  // namespace

void validate_scene(Scene& scene, const std::string& name, unsigned threads) {
    uint64_t degenerate = 0;
    for (size_t m = 0; m < scene.meshes.size(); ++m) {
        const Mesh& mesh = scene.meshes[m];
        std::string where = name + ": mesh " + std::to_string(m);
        if (mesh.positions.size() % 3 != 0 || mesh.indices.size() % 3 != 0)
            throw LoadError(where + ": arrays are not whole vertices or triangles");
        size_t n = mesh.vertex_count();
        const size_t bad_index =
            first_failing(mesh.indices.size(), threads, [&](size_t i) { return mesh.indices[i] >= n; });
        if (bad_index != SIZE_MAX)
            throw LoadError(where + ": triangle " + std::to_string(bad_index / 3) + ": index " +
                            std::to_string(mesh.indices[bad_index]) + " out of range (" + std::to_string(n) +
                            " vertices)");
        const size_t bad_position =
            first_failing(mesh.positions.size(), threads, [&](size_t i) { return !std::isfinite(mesh.positions[i]); });
        if (bad_position != SIZE_MAX)
            throw LoadError(where + ": vertex " + std::to_string(bad_position / 3) + ": position is not finite");
        degenerate += count_degenerate(mesh, threads);
    }
    for (size_t k = 0; k < scene.instances.size(); ++k) {
        const Instance& inst = scene.instances[k];
        if (inst.mesh >= scene.meshes.size())
            throw LoadError(name + ": instance " + std::to_string(k) + ": mesh " + std::to_string(inst.mesh) +
                            " does not exist");
        for (double v : inst.world)
            if (!std::isfinite(v)) throw LoadError(name + ": instance " + std::to_string(k) + ": non-finite transform");
    }
    scene.report.degenerate_triangles = degenerate;
}

Scene single_mesh_scene(Mesh mesh, const std::string& name, const Origin& origin, unsigned threads) {
    mesh.name = name;
    mesh.primitives.push_back({0, uint32_t(mesh.triangle_count()), false});
    Scene scene;
    scene.report.primitives = 1;
    scene.meshes.push_back(std::move(mesh));
    scene.instances.push_back({0, with_origin(identity_transform(), origin), name});
    validate_scene(scene, name, threads);
    return scene;
}

std::string byte_size_text(uint64_t bytes) {
    static const char* units[] = {"bytes", "KiB", "MiB", "GiB", "TiB"};
    int unit = 0;
    while (unit < 4 && bytes >= (uint64_t(1) << (10 * (unit + 1)))) ++unit;
    return std::to_string(bytes >> (10 * unit)) + " " + units[unit];
}

FileFormat format_from_path(std::string_view path) {
    size_t dot = path.find_last_of('.');
    if (dot == std::string_view::npos) return FileFormat::unknown;
    std::string ext(path.substr(dot + 1));
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    if (ext == "gltf") return FileFormat::gltf;
    if (ext == "glb") return FileFormat::glb;
    if (ext == "obj") return FileFormat::obj;
    if (ext == "ply") return FileFormat::ply;
    if (ext == "off") return FileFormat::off;
    if (ext == "stl") return FileFormat::stl;
    return FileFormat::unknown;
}

Scene load_scene(const std::string& path, const LoadOptions& options) {
    try {
        return load_scene_unguarded(path, options);
    } catch (const std::bad_alloc&) {
        // A file can still describe more than this machine holds; say so rather than crash.
        throw LoadOutOfMemory(path + ": out of memory while loading");
    }
}

Scene load_scene_unguarded(const std::string& path, const LoadOptions& options) {
    FileFormat format = format_from_path(path);
    if (format == FileFormat::unknown)
        throw LoadError(path + ": unknown file type (expected .gltf .glb .obj .ply .off .stl)");
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec)) throw LoadError(path + ": is a directory");
    // A batch's scene found below its input root through a symbolic link that leads elsewhere.
    if (!options.root.empty() && !options.allow_outside_files) {
        std::string problem = path_outside_root(path, options.root, "the input root");
        if (!problem.empty()) throw LoadError(path + ": refused: " + problem + " (--allow-outside-files reads it)");
    }
    FileBytes bytes;
    std::string error;
    if (!bytes.read(path, error, options.threads)) throw LoadError(error);

    SourceHasher source;
    source.add(std::filesystem::path(path).filename().string(), bytes.data(), bytes.size());
    Scene scene;
    if (format == FileFormat::gltf || format == FileFormat::glb) {
        std::string base = std::filesystem::path(path).parent_path().string();
        scene = load_gltf_memory(bytes.data(), bytes.size(), path, base.empty() ? "." : base, &source, options);
    } else {
        scene = load_mesh_memory(bytes.data(), bytes.size(), format, path, options.threads);
    }
    scene.report.source = source.finish();
    return scene;
}

}  // namespace cb
