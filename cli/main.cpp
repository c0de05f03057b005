// clusterbake command line: parses arguments, calls the libraries, prints. No algorithm lives here.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cstring>
#include <cstdio>
#include <fstream>
#include <iostream>

#include "bake.h"
#include "load.h"
#include "scene_info.h"

namespace {

constexpr int exit_bad_input = 2;

int run_info(const std::vector<std::string>& files, bool json) {
    int status = 0;
    nlohmann::json all = nlohmann::json::array();
    for (const std::string& file : files) {
        auto start = std::chrono::steady_clock::now();
        try {
            cb::Scene scene = cb::load_scene(file);
            double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
            cb::SceneInfo info = cb::describe(scene);
            if (json) {
                nlohmann::json j = cb::to_json(info);
                j["file"] = file;
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
            if (json) all.push_back({{"file", file}, {"error", e.what()}});
            status = exit_bad_input;
        }
    }
    if (json) std::cout << all.dump(2) << "\n";
    return status;
}

double seconds_since(std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

struct ClusterArgs {
    std::string file, out, method = "kmeans";
    cb::ClusterOptions options;
    bool json = false, quiet = false;
    bool fit = false;  // bake: fit bounds too
    std::string bounds = "auto", obb = "refined";
    double capsule_ratio = 2.0;
};

// `cluster` (geometry and hierarchy only) and `bake` (with bounds) share this.
int run_bake(const ClusterArgs& a) {
    cb::ClusterOptions options = a.options;
    if (!cb::parse_method(a.method, options.method)) {
        std::fprintf(stderr, "clusterbake: unknown method '%s' (kmeans, vco, morton)\n", a.method.c_str());
        return 1;
    }
    cb::BoundsOptions bounds;
    bounds.capsule_ratio = a.capsule_ratio;
    if (a.fit && !cb::parse_bounds_mask(a.bounds, bounds.mask)) {
        std::fprintf(stderr, "clusterbake: --bounds takes auto, all or a list of obb,sphere,capsule,cone,slab (got '%s')\n",
                     a.bounds.c_str());
        return 1;
    }
    const std::pair<const char*, cb::ObbMethod> obb_methods[] = {{"refined", cb::ObbMethod::refined}, {"pca", cb::ObbMethod::pca},
                                                                 {"pca-area", cb::ObbMethod::pca_area}, {"cgal", cb::ObbMethod::cgal_optimal}};
    bool known_obb = false;
    for (const auto& [name, m] : obb_methods)
        if (a.obb == name) bounds.obb = m, known_obb = true;
    if (!known_obb) {
        std::fprintf(stderr, "clusterbake: --obb takes refined, pca, pca-area or cgal (got '%s')\n", a.obb.c_str());
        return 1;
    }
    auto t0 = std::chrono::steady_clock::now();
    cb::Scene scene;
    try {
        scene = cb::load_scene(a.file);
    } catch (const cb::LoadError& e) {
        std::fprintf(stderr, "%s\n", e.what());
        return exit_bad_input;
    }
    double load_s = seconds_since(t0);

    // Progress for long runs only, on stderr, overwritten in place.
    uint64_t total = 0;
    for (const cb::Mesh& m : scene.meshes) total += m.triangle_count();
    bool show = !a.quiet && total >= 1'000'000;
    cb::BakeStats stats;
    std::vector<cb::AssetMesh> meshes = cb::cluster_scene(scene, options, stats, [&](size_t m, size_t mc, size_t c, size_t cc) {
        if (show) std::fprintf(stderr, "\rclustering mesh %zu/%zu: chunk %zu/%zu   ", m + 1, mc, c, cc);
    });
    if (show) std::fprintf(stderr, "\n");
    if (a.fit) cb::fit_scene_bounds(meshes, bounds, options.threads, stats);

    auto t1 = std::chrono::steady_clock::now();
    std::vector<uint8_t> bytes = cb::encode_asset(meshes, scene.instances);
    cb::write_file_atomic(a.out, bytes);
    double write_s = seconds_since(t1);

    double tps = stats.cluster_seconds > 0 ? double(stats.triangles) / stats.cluster_seconds : 0;
    if (a.json) {
        nlohmann::json j = {{"file", a.file},
                            {"output", a.out},
                            {"method", cb::method_name(options.method)},
                            {"coarse_size", options.coarse_size},
                            {"fine_size", options.fine_size},
                            {"meshes", scene.meshes.size()},
                            {"instances", scene.instances.size()},
                            {"triangles", stats.triangles},
                            {"coarse_clusters", stats.coarse_clusters},
                            {"fine_clusters", stats.fine_clusters},
                            {"fine_min", stats.fine_min},
                            {"fine_max", stats.fine_max},
                            {"fine_below_half", stats.fine_below_half},
                            {"coarse_min", stats.coarse_min},
                            {"coarse_max", stats.coarse_max},
                            {"load_seconds", load_s},
                            {"cluster_seconds", stats.cluster_seconds},
                            {"write_seconds", write_s},
                            {"triangles_per_second", tps},
                            {"asset_bytes", bytes.size()},
                            {"bytes_per_triangle", stats.triangles ? double(bytes.size()) / double(stats.triangles) : 0.0}};
        if (a.fit) {
            j["bounds"] = a.bounds;
            j["fit_seconds"] = stats.fit_seconds;
            if (bounds.mask & cb::bounds_cone) j["valid_cones"] = stats.valid_cones;
            if (bounds.mask & cb::bounds_capsule) j["capsules"] = stats.capsules;
        }
        if (options.method == cb::ClusterMethod::vco) {
            j["acmr_before"] = stats.acmr_before;
            j["acmr_after"] = stats.acmr_after;
        }
        std::cout << j.dump(2) << "\n";
        return 0;
    }
    std::printf("%s -> %s\n", a.file.c_str(), a.out.c_str());
    std::printf("  method %s, coarse %u, fine %u: %llu triangles in %llu meshes (%zu instances)\n",
                cb::method_name(options.method), options.coarse_size, options.fine_size,
                (unsigned long long)stats.triangles, (unsigned long long)scene.meshes.size(), scene.instances.size());
    std::printf("  coarse clusters %llu (%u..%u triangles), fine clusters %llu (%u..%u triangles, %llu below half)\n",
                (unsigned long long)stats.coarse_clusters, stats.coarse_min, stats.coarse_max,
                (unsigned long long)stats.fine_clusters, stats.fine_min, stats.fine_max,
                (unsigned long long)stats.fine_below_half);
    if (options.method == cb::ClusterMethod::vco)
        std::printf("  ACMR (FIFO %u) %.3f -> %.3f\n", options.vco_cache_size, stats.acmr_before, stats.acmr_after);
    if (a.fit) {
        std::printf("  bounds %s (obb %s): fitted in %.3f s", a.bounds.c_str(), a.obb.c_str(), stats.fit_seconds);
        unsigned long long clusters = stats.fine_clusters + stats.coarse_clusters;
        if (bounds.mask & cb::bounds_cone)
            std::printf("; %llu of %llu clusters have a valid cone", (unsigned long long)stats.valid_cones, clusters);
        if (bounds.mask & cb::bounds_capsule)
            std::printf("; %llu of %llu are capsules", (unsigned long long)stats.capsules, clusters);
        std::printf("\n");
    }
    std::printf("  load %.3f s, cluster %.3f s (%.2f M triangles/s), write %.3f s, asset %zu bytes (%.1f per triangle)\n",
                load_s, stats.cluster_seconds, tps / 1e6, write_s, bytes.size(),
                stats.triangles ? double(bytes.size()) / double(stats.triangles) : 0.0);
    return 0;
}

int run_validate(const std::string& file) {
    std::ifstream in(file, std::ios::binary);
    if (!in) {
        std::fprintf(stderr, "%s: cannot open\n", file.c_str());
        return exit_bad_input;
    }
    std::vector<char> raw((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    // The view needs 8-byte alignment for the instance doubles: copy into storage that has it.
    std::vector<uint64_t> aligned((raw.size() + 7) / 8);
    std::memcpy(aligned.data(), raw.data(), raw.size());
    cb::AssetView view;
    cb::AssetError e = cb::open_asset(aligned.data(), raw.size(), &view);
    if (e != cb::AssetError::ok) {
        std::fprintf(stderr, "%s: %s\n", file.c_str(), cb::asset_error_text(e));
        return exit_bad_input;
    }
    std::printf("%s: valid clusterbake asset v%u, %zu bytes\n", file.c_str(), cb::asset_version, raw.size());
    std::printf("  meshes %u, instances %u, vertices %u, triangles %u, fine clusters %u, coarse clusters %u\n",
                view.mesh_count, view.instance_count, view.vertex_count, view.triangle_count, view.fine_count,
                view.coarse_count);
    for (auto [name, level] : {std::pair{"fine", &view.fine_bounds}, std::pair{"coarse", &view.coarse_bounds}}) {
        std::string kinds;
        if (level->obbs) kinds += " obb";
        if (level->spheres) kinds += " sphere";
        if (level->capsules) kinds += " capsule";
        if (level->cones) kinds += " cone";
        if (level->slabs) kinds += " slab";
        std::printf("  %s bounds:%s\n", name, kinds.empty() ? " none" : kinds.c_str());
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"clusterbake: clusters triangle scenes, fits bounding volumes and bakes a compact asset"};
    app.require_subcommand(1);

    std::vector<std::string> info_files;
    bool info_json = false;
    CLI::App* info = app.add_subcommand("info", "Load scene files and print counts, bounds and load time");
    info->add_option("files", info_files, "Scene files (.gltf .glb .obj .ply .off .stl)")->required();
    info->add_flag("--json", info_json, "Print a JSON array, one object per file");

    ClusterArgs ca, ba;
    ba.fit = true;
    auto clustering_options = [](CLI::App* c, ClusterArgs& a) {
        c->add_option("file", a.file, "Scene file")->required();
        c->add_option("-o,--output", a.out, "Output asset (.cbk); written atomically")->required();
        c->add_option("--method", a.method, "kmeans (default), vco or morton");
        c->add_option("--coarse", a.options.coarse_size, "Triangles per coarse cluster (default 2048)");
        c->add_option("--fine", a.options.fine_size, "Maximum triangles per fine cluster (default 16)");
        c->add_option("--threads", a.options.threads, "Worker threads, 0 = all (output is identical for any count)");
        c->add_option("--seed", a.options.seed, "Seed of k-means++ (default 1)");
        c->add_option("--k0", a.options.kmeans_branching, "k-means children per node (default 8)");
        c->add_option("--iterations", a.options.kmeans_max_iterations, "Cap on Lloyd iterations per node (default 16)");
        c->add_flag("--coarse-from-tree", a.options.kmeans_coarse_from_tree,
                    "kmeans: take the coarse level from the top of the k-means tree instead of Morton chunks");
        c->add_option("--cache", a.options.vco_cache_size, "vco: vertex cache size (default 32)");
        c->add_flag("--json", a.json, "Print the summary as JSON");
        c->add_flag("-q,--quiet", a.quiet, "No progress on stderr");
    };
    CLI::App* cluster = app.add_subcommand("cluster", "Cluster every mesh into coarse and fine clusters and write an asset (no bounds)");
    clustering_options(cluster, ca);
    CLI::App* bake = app.add_subcommand("bake", "Load, cluster, fit bounding volumes and write the asset");
    clustering_options(bake, ba);
    bake->add_option("--bounds", ba.bounds,
                     "auto (what the shadow runtime reads: obb,cone), all, or a list of obb,sphere,capsule,cone,slab");
    bake->add_option("--obb", ba.obb, "refined (default), pca, pca-area, or cgal (CGAL's optimum: slow)");
    bake->add_option("--capsule-ratio", ba.capsule_ratio, "Fit a capsule when the box's longest side is this many times each other (default 2)");

    std::string validate_file;
    CLI::App* validate = app.add_subcommand("validate", "Check an asset's structure, ranges and checksum");
    validate->add_option("file", validate_file, "Asset file")->required();

    CLI11_PARSE(app, argc, argv);

    try {
        if (*info) return run_info(info_files, info_json);
        if (*cluster) return run_bake(ca);
        if (*bake) return run_bake(ba);
        if (*validate) return run_validate(validate_file);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "clusterbake: %s\n", e.what());
        return 1;
    }
    return 0;
}
