// Scene loading: glTF 2.0 (.gltf, .glb, KHR_draco_mesh_compression, KHR_mesh_quantization) through
// tinygltf and Draco; binary STL through OpenMesh's reader; OBJ, OFF, PLY and ASCII STL through readers of
// our own, since OpenMesh's lose faces, precision or fail under fuzzing (see load_text.cpp and load_ply.cpp).
// Each mesh is stored relative to an origin of its own, carried by its instances (mesh_frame.h).
//
// Every loader either returns a Scene whose indices are in range and whose positions are finite, or throws
// LoadError with one line of the form "FILE: ELEMENT: PROBLEM". Degenerate triangles are kept and counted.
// Faces of more than three vertices are triangulated in their plane and counted by shape
// (polygon_triangulate.h).
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

#include "mesh_frame.h"
#include "scene.h"
#include "source_files.h"

namespace cb {

// One line of printable text, whatever the file held: control characters in names or tokens taken from the
// input are replaced by '?'.
struct LoadError : std::runtime_error {
    explicit LoadError(std::string message) : std::runtime_error(printable(std::move(message))) {}

    static std::string printable(std::string s) {
        for (char& c : s)
            if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';
        return s;
    }
};

// A load that ran out of memory ("FILE: out of memory while loading"): under a hard limit on the process
// (bake_file.h, limit_process_memory), a file over its memory budget.
struct LoadOutOfMemory : LoadError {
    using LoadError::LoadError;
};

enum class FileFormat { gltf, glb, obj, ply, off, stl, unknown };

// The bytes a load may hold for what a file declares (decoded arrays, instances) when no other budget is
// given: a scene of 10 million triangles loads and bakes within it (docs/SECURITY.md).
constexpr uint64_t default_memory_budget = uint64_t(4) << 30;

// "800 bytes", "12 KiB", "640 MiB", "4 GiB": a size for a message, rounded down.
std::string byte_size_text(uint64_t bytes);

// What a load trusts the file with. Scene files are untrusted input (docs/SECURITY.md): by default an
// external file a scene names (a glTF buffer) must lie inside `root`, and what the file's declared counts
// would make the loader allocate must fit `memory_budget`.
struct LoadOptions {
    std::string root;                  // external files must lie below it; empty: the scene file's folder
    bool allow_outside_files = false;  // any readable file may be named (pipelines sharing buffers)
    uint64_t memory_budget = default_memory_budget;
    unsigned threads = 1;  // for a mesh file's per-element passes (binary PLY records, validation); 0: all
};

// From the file extension, case-insensitive.
FileFormat format_from_path(std::string_view path);

// Loads any supported file. `path` names the file in every error message. The report's `source` lists the
// files read and their hash (source_files.h).
Scene load_scene(const std::string& path, const LoadOptions& options = {});

// Loads from bytes already in memory. `name` is used in error messages; external glTF resources are looked
// up relative to `base_dir` (none may be named when it is empty), inside `options.root` (`base_dir` when
// empty), and, when `source` is set, added to it as they are read.
Scene load_gltf_memory(const uint8_t* data, size_t size, const std::string& name, const std::string& base_dir,
                       SourceHasher* source = nullptr, const LoadOptions& options = {});
Scene load_mesh_memory(const uint8_t* data, size_t size, FileFormat format, const std::string& name,
                       unsigned threads = 1);

// The per-format readers behind load_mesh_memory.
Scene load_obj_memory(const uint8_t* data, size_t size, const std::string& name);
Scene load_off_memory(const uint8_t* data, size_t size, const std::string& name);
Scene load_ply_memory(const uint8_t* data, size_t size, const std::string& name, unsigned threads = 1);
Scene load_stl_memory(const uint8_t* data, size_t size, const std::string& name);
Scene load_ascii_stl_memory(const uint8_t* data, size_t size, const std::string& name);  // after the 'solid' check

// A scene of one mesh, one instance that places the mesh's origin (mesh_frame.h) and one single-sided
// primitive, validated (on `threads`).
Scene single_mesh_scene(Mesh mesh, const std::string& name, const Origin& origin = {0, 0, 0}, unsigned threads = 1);

// Throws LoadError unless every index is in range and every position finite; fills report.degenerate_triangles.
// A mesh's elements are checked in parts on `threads` (0: all); the error names the first bad element all
// the same.
void validate_scene(Scene& scene, const std::string& name, unsigned threads = 1);

}  // namespace cb
