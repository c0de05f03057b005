// clusterbake stats: cluster-quality statistics of a scene baked in memory, or of an asset.
#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>
#include <memory>

#include "args.h"
#include "asset_file.h"
#include "baked_scene.h"
#include "cluster_stats.h"
#include "commands.h"

namespace cb::cli {
namespace {

int run_stats(const ClusterArgs& a, cb::StatsOptions so) {
    cb::ClusterOptions clustering;
    cb::BoundsOptions bounds;
    if (!parse_clustering(a, clustering, bounds)) return exit_usage;
    bounds.mask = cb::bounds_all;
    so.threads = clustering.threads;
    cb::BakedScene baked;
    std::string note;
    try {
        baked = cb::load_baked(a.file, clustering, bounds, &note);
    } catch (const std::runtime_error& e) {
        std::fprintf(stderr, "%s\n", e.what());
        return exit_bad_input;
    }
    cb::SceneStats s = cb::cluster_statistics(baked.meshes, baked.instances, so);
    bool asset = cb::is_asset_file(a.file);
    if (a.json) {
        nlohmann::json j = cb::to_json(s);
        j["file"] = a.file;
        if (asset) {
            j["input"] = "asset";
            if (!note.empty()) j["note"] = note;
        } else {
            j["input"] = "scene";
            j["method"] = cb::method_name(clustering.method);
            j["coarse_size"] = clustering.coarse_size;
            j["fine_size"] = clustering.fine_size;
            j["obb"] = a.obb;
        }
        std::cout << j.dump(2) << "\n";
        return 0;
    }
    if (asset)
        std::printf("%s: asset%s%s\n", a.file.c_str(), note.empty() ? "" : "; ", note.c_str());
    else
        std::printf("%s: method %s, coarse %u, fine %u, obb %s\n", a.file.c_str(), cb::method_name(clustering.method),
                    clustering.coarse_size, clustering.fine_size, a.obb.c_str());
    std::fputs(cb::to_text(s).c_str(), stdout);
    return 0;
}

}  // namespace

Command add_stats(CLI::App& app) {
    struct Args {
        ClusterArgs clustering;
        cb::StatsOptions options;
    };
    auto a = std::make_shared<Args>();
    CLI::App* c = app.add_subcommand(
        "stats", "Cluster-quality statistics per level (coarse, fine) of a scene baked in memory, or of an asset");
    c->add_option("file", a->clustering.file,
                  "Scene file, or an asset (.cbk): its clusters and stored volumes as they are")
        ->required();
    add_clustering_flags(c, a->clustering);
    c->add_option("--obb", a->clustering.obb, "refined (default), pca, pca-area, or cgal (CGAL's optimum: slow)");
    c->add_option("--capsule-ratio", a->clustering.capsule_ratio,
                  "Fit a capsule when the box's longest side is this many times each other (default 2)");
    c->add_option("--lights", a->options.lights, "Random light positions per mesh (default 8)");
    c->add_option("--samples", a->options.samples,
                  "Points sampled in each cluster's shadow volume per light (default 32)");
    c->add_option("--light-seed", a->options.seed, "Seed of the lights and samples (default 1)");
    c->add_option("--acmr-cache", a->options.acmr_cache, "FIFO cache size for the ACMR (default 32)");
    c->add_flag("--json", a->clustering.json, "Print the statistics as JSON");
    return {c, [a] { return run_stats(a->clustering, a->options); }};
}

}  // namespace cb::cli
