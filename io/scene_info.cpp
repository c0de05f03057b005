#include "scene_info.h"

#include <algorithm>
#include <nlohmann/json.hpp>

namespace cb {

SceneInfo describe(const Scene& scene) {
    SceneInfo info;
    info.meshes = scene.meshes.size();
    info.primitives = scene.report.primitives;
    info.skipped_primitives = scene.report.skipped_primitives;
    info.draco_primitives = scene.report.draco_primitives;
    info.instances = scene.instances.size();
    info.degenerate_triangles = scene.report.degenerate_triangles;
    info.unreferenced_meshes = scene.report.unreferenced_meshes;
    info.polygons = scene.report.polygons;
    info.meshopt_views = scene.report.meshopt_views;
    info.instanced_nodes = scene.report.instanced_nodes;
    info.gpu_instances = scene.report.gpu_instances;
    info.extensions = scene.report.extensions;
    info.warnings = scene.report.warnings;
    for (const Mesh& m : scene.meshes) {
        info.unique_triangles += m.triangle_count();
        info.unique_vertices += m.vertex_count();
    }
    for (const Instance& inst : scene.instances) {
        const Mesh& m = scene.meshes[inst.mesh];
        info.scene_triangles += m.triangle_count();
        info.scene_vertices += m.vertex_count();
        for (size_t v = 0; v < m.vertex_count(); ++v) {
            const float* p = &m.positions[v * 3];
            auto w = transform_point(inst.world, p[0], p[1], p[2]);
            for (int k = 0; k < 3; ++k) {
                info.world_min[k] = info.empty_bounds ? w[k] : std::min(info.world_min[k], w[k]);
                info.world_max[k] = info.empty_bounds ? w[k] : std::max(info.world_max[k], w[k]);
            }
            info.empty_bounds = false;
        }
    }
    return info;
}

nlohmann::json to_json(const SceneInfo& i) {
    nlohmann::json j = {
        {"meshes", i.meshes},
        {"primitives", i.primitives},
        {"skipped_primitives", i.skipped_primitives},
        {"draco_primitives", i.draco_primitives},
        {"instances", i.instances},
        {"unique_triangles", i.unique_triangles},
        {"unique_vertices", i.unique_vertices},
        {"scene_triangles", i.scene_triangles},
        {"scene_vertices", i.scene_vertices},
        {"degenerate_triangles", i.degenerate_triangles},
        {"unreferenced_meshes", i.unreferenced_meshes},
        {"polygons", i.polygons.total},
        {"concave_polygons", i.polygons.concave},
        {"not_simple_polygons", i.polygons.not_simple},
        {"degenerate_polygons", i.polygons.degenerate},
        {"meshopt_views", i.meshopt_views},
        {"gpu_instancing_nodes", i.instanced_nodes},
        {"gpu_instances", i.gpu_instances},
        {"warnings", i.warnings},
    };
    nlohmann::json extensions = nlohmann::json::array();
    for (const ExtensionUse& e : i.extensions)
        extensions.push_back(
            {{"name", e.name}, {"required", e.required}, {"status", status_name(e.status)}, {"on", e.where}});
    j["extensions"] = extensions;
    if (i.empty_bounds)
        j["world_bounds"] = nullptr;
    else
        j["world_bounds"] = {{"min", i.world_min}, {"max", i.world_max}};
    return j;
}

const char* status_name(ExtensionUse::Status status) {
    switch (status) {
        case ExtensionUse::Status::applied: return "applied";
        case ExtensionUse::Status::no_geometry: return "no geometry";
        case ExtensionUse::Status::unsupported: return "unsupported";
    }
    return "?";
}

std::string extension_text(const ExtensionUse& use) {
    return use.name + " (" + (use.required ? "required, " : "") + status_name(use.status) + ")";
}

}  // namespace cb
