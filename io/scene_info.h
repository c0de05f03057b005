// Counts and bounds of a loaded scene, as `clusterbake info` prints them.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "scene.h"

namespace cb {

struct SceneInfo {
    uint64_t meshes = 0, primitives = 0, skipped_primitives = 0, draco_primitives = 0, instances = 0;
    uint64_t unique_triangles = 0, unique_vertices = 0;  // each mesh counted once
    uint64_t scene_triangles = 0, scene_vertices = 0;    // each mesh counted per instance
    uint64_t degenerate_triangles = 0;                   // unique, kept in the meshes
    uint64_t unreferenced_meshes = 0;
    uint64_t meshopt_views = 0, instanced_nodes = 0,
             gpu_instances = 0;            // glTF EXT_meshopt_compression, EXT_mesh_gpu_instancing
    std::vector<ExtensionUse> extensions;  // glTF: every extension the file names, and what the load did with it
    std::vector<std::string> warnings;     // what the load could not honour, one line each
    PolygonCounts polygons;                // OBJ, OFF and PLY faces of more than three vertices, by shape
    std::array<double, 3> world_min{0, 0, 0}, world_max{0, 0, 0};  // exact over every instanced vertex
    bool empty_bounds = true;
};

SceneInfo describe(const Scene& scene);

nlohmann::json to_json(const SceneInfo& info);

// "applied", "no geometry" or "unsupported".
const char* status_name(ExtensionUse::Status status);

// An extension as `info` lists it: "EXT_meshopt_compression (required, applied)".
std::string extension_text(const ExtensionUse& use);

}  // namespace cb
