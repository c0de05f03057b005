// clusterbake info: load scene files and print what they hold.
#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>

#include "args.h"
#include "bake_file.h"
#include "commands.h"
#include "load.h"
#include "scene_info.h"

namespace cb::cli {
namespace {

int run_info(const std::vector<std::string>& files, bool json, const cb::LoadOptions& load) {
    int status = 0;
    nlohmann::json all = nlohmann::json::array();
    for (const std::string& file : files) {
        auto start = std::chrono::steady_clock::now();
        try {
            cb::Scene scene = cb::load_scene(file, load);
            double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
            cb::SceneInfo info = cb::describe(scene);
            if (json) {
                nlohmann::json j = {{"tool", cb::tool_version()}, {"file", file}};
                j.update(cb::to_json(info));
                j["load_ms"] = ms;
                all.push_back(j);
                continue;
            }
            std::printf("%s\n", file.c_str());
            std::printf("  meshes %llu, primitives %llu (%llu Draco, %llu points/lines skipped), instances %llu\n",
                        (unsigned long long)info.meshes, (unsigned long long)info.primitives,
                        (unsigned long long)info.draco_primitives, (unsigned long long)info.skipped_primitives,
                        (unsigned long long)info.instances);
            std::printf("  triangles %llu unique, %llu in scene; vertices %llu unique, %llu in scene\n",
                        (unsigned long long)info.unique_triangles, (unsigned long long)info.scene_triangles,
                        (unsigned long long)info.unique_vertices, (unsigned long long)info.scene_vertices);
            std::printf("  degenerate triangles %llu (kept)\n", (unsigned long long)info.degenerate_triangles);
            if (info.polygons.total)
                std::printf("  polygons %llu (%llu concave, %llu not simple, %llu degenerate)\n",
                            (unsigned long long)info.polygons.total, (unsigned long long)info.polygons.concave,
                            (unsigned long long)info.polygons.not_simple, (unsigned long long)info.polygons.degenerate);
            if (info.instanced_nodes)
                std::printf("  EXT_mesh_gpu_instancing: %llu instances from %llu nodes\n",
                            (unsigned long long)info.gpu_instances, (unsigned long long)info.instanced_nodes);
            if (info.meshopt_views)
                std::printf("  EXT_meshopt_compression: %llu bufferViews decoded\n",
                            (unsigned long long)info.meshopt_views);
            if (!info.extensions.empty()) {
                std::string line;
                for (const cb::ExtensionUse& e : info.extensions)
                    line += (line.empty() ? "" : ", ") + cb::extension_text(e);
                std::printf("  extensions: %s\n", line.c_str());
            }
            for (const std::string& w : info.warnings) std::printf("  warning: %s\n", w.c_str());
            if (info.unreferenced_meshes)
                std::printf("  meshes not used by the scene %llu (not loaded)\n",
                            (unsigned long long)info.unreferenced_meshes);
            if (info.empty_bounds)
                std::printf("  world bounds: empty\n");
            else
                std::printf("  world bounds: min (%.9g, %.9g, %.9g) max (%.9g, %.9g, %.9g)\n", info.world_min[0],
                            info.world_min[1], info.world_min[2], info.world_max[0], info.world_max[1],
                            info.world_max[2]);
            std::printf("  load time %.2f ms\n", ms);
        } catch (const cb::LoadError& e) {
            std::fprintf(stderr, "%s\n", e.what());
            if (json) all.push_back({{"tool", cb::tool_version()}, {"file", file}, {"error", e.what()}});
            status = exit_bad_input;
        }
    }
    if (json) std::cout << all.dump(2) << "\n";
    return status;
}

}  // namespace

Command add_info(CLI::App& app) {
    struct Args {
        std::vector<std::string> files;
        bool json = false, quiet = false;
        cb::LoadOptions load;
    };
    auto a = std::make_shared<Args>();
    CLI::App* c = app.add_subcommand("info", "Load scene files and print counts, bounds and load time");
    c->add_option("files", a->files, "Scene files (.gltf .glb .obj .ply .off .stl)")->required();
    c->add_flag("--json", a->json, "Print a JSON array, one object per file");
    c->add_flag("-q,--quiet", a->quiet, "No progress on stderr (info prints none; errors are always printed)");
    add_load_flags(c, a->load);
    return {c, [a] { return run_info(a->files, a->json, a->load); }};
}

}  // namespace cb::cli
