// Counts and bounds of a loaded scene, as `clusterbake info` prints them.
#pragma once

#include <array>
#include <cstdint>

#include <nlohmann/json_fwd.hpp>

#include "scene.h"

namespace cb {

struct SceneInfo {
    uint64_t meshes = 0, primitives = 0, skipped_primitives = 0, draco_primitives = 0, instances = 0;
    uint64_t unique_triangles = 0, unique_vertices = 0;  // each mesh counted once
    uint64_t scene_triangles = 0, scene_vertices = 0;    // each mesh counted per instance
    uint64_t degenerate_triangles = 0;                   // unique, kept in the meshes
    uint64_t unreferenced_meshes = 0;
    PolygonCounts polygons;  // OBJ, OFF and PLY faces of more than three vertices, by shape
    std::array<double, 3> world_min{0, 0, 0}, world_max{0, 0, 0};  // exact over every instanced vertex
    bool empty_bounds = true;
};

SceneInfo describe(const Scene& scene);

nlohmann::json to_json(const SceneInfo& info);

}  // namespace cb
