// clusterbake cluster and bake: load a scene, cluster it (and fit bounds: bake), write the asset.
#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>

#include "args.h"
#include "bake.h"
#include "commands.h"
#include "load.h"
#include "timing.h"

namespace cb::cli {
namespace {

// `cluster` (geometry and hierarchy only) and `bake` (with bounds) share this.
int run_bake(const ClusterArgs& a) {
    cb::ClusterOptions options;
    cb::BoundsOptions bounds;
    if (!parse_clustering(a, options, bounds)) return exit_usage;
    if (a.fit && !cb::parse_bounds_mask(a.bounds, bounds.mask)) {
        std::fprintf(stderr,
                     "clusterbake: --bounds takes auto, all or a list of obb,sphere,capsule,cone,slab (got '%s')\n",
                     a.bounds.c_str());
        return exit_usage;
    }
    auto t0 = std::chrono::steady_clock::now();
    cb::Scene scene;
    try {
        scene = cb::load_scene(a.file);
    } catch (const cb::LoadError& e) {
        std::fprintf(stderr, "%s\n", e.what());
        return exit_bad_input;
    }
    double load_s = cb::seconds_since(t0);

    // Progress for long runs only, on stderr, overwritten in place.
    uint64_t total = 0;
    for (const cb::Mesh& m : scene.meshes) total += m.triangle_count();
    bool show = !a.quiet && total >= 1'000'000;
    cb::BakeStats stats;
    std::vector<cb::AssetMesh> meshes =
        cb::cluster_scene(scene, options, stats, [&](size_t m, size_t mc, size_t c, size_t cc) {
            if (show) std::fprintf(stderr, "\rclustering mesh %zu/%zu: chunk %zu/%zu   ", m + 1, mc, c, cc);
        });
    if (show) std::fprintf(stderr, "\n");
    if (a.fit) cb::fit_scene_bounds(meshes, bounds, options.threads, stats);

    auto t1 = std::chrono::steady_clock::now();
    std::vector<uint8_t> bytes = cb::encode_asset(meshes, scene.instances);
    cb::write_file_atomic(a.out, bytes);
    double write_s = cb::seconds_since(t1);

    double tps = stats.cluster_seconds > 0 ? double(stats.triangles) / stats.cluster_seconds : 0;
    if (a.json) {
        nlohmann::json j = {
            {"file", a.file},
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
    std::printf(
        "  load %.3f s, cluster %.3f s (%.2f M triangles/s), write %.3f s, asset %zu bytes (%.1f per triangle)\n",
        load_s, stats.cluster_seconds, tps / 1e6, write_s, bytes.size(),
        stats.triangles ? double(bytes.size()) / double(stats.triangles) : 0.0);
    return 0;
}

// The input, the output and the clustering options, common to both.
void add_common(CLI::App* c, ClusterArgs& a) {
    c->add_option("file", a.file, "Scene file")->required();
    c->add_option("-o,--output", a.out, "Output asset (.cbk); written atomically")->required();
    add_clustering_flags(c, a);
    c->add_flag("--json", a.json, "Print the summary as JSON");
    c->add_flag("-q,--quiet", a.quiet, "No progress on stderr");
}

}  // namespace

Command add_cluster(CLI::App& app) {
    auto a = std::make_shared<ClusterArgs>();
    CLI::App* c = app.add_subcommand("cluster",
                                     "Cluster every mesh into coarse and fine clusters and write an asset (no bounds)");
    add_common(c, *a);
    return {c, [a] { return run_bake(*a); }};
}

Command add_bake(CLI::App& app) {
    auto a = std::make_shared<ClusterArgs>();
    a->fit = true;
    CLI::App* c = app.add_subcommand("bake", "Load, cluster, fit bounding volumes and write the asset");
    add_common(c, *a);
    c->add_option("--bounds", a->bounds,
                  "auto (what the shadow runtime reads: obb,cone), all, or a list of obb,sphere,capsule,cone,slab");
    c->add_option("--obb", a->obb, "refined (default), pca, pca-area, or cgal (CGAL's optimum: slow)");
    c->add_option("--capsule-ratio", a->capsule_ratio,
                  "Fit a capsule when the box's longest side is this many times each other (default 2)");
    return {c, [a] { return run_bake(*a); }};
}

}  // namespace cb::cli
