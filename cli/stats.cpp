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
#include "progress.h"

namespace cb::cli {
namespace {

// The volume kinds an asset stores at both levels.
uint32_t stored_kinds(const cb::AssetView& view) {
    uint32_t mask = 0;
    const cb::LevelBounds& fine = view.fine_bounds;
    const cb::LevelBounds& coarse = view.coarse_bounds;
    if (fine.obbs && coarse.obbs) mask |= cb::bounds_obb;
    if (fine.spheres && coarse.spheres) mask |= cb::bounds_sphere;
    if (fine.capsules && coarse.capsules) mask |= cb::bounds_capsule;
    if (fine.cones && coarse.cones) mask |= cb::bounds_cone;
    if (fine.slabs && coarse.slabs) mask |= cb::bounds_slab;
    return mask;
}

// An asset's clusters are taken as they are: the options that make clusters do nothing, --obb only shapes
// the volumes fitted here (those the asset does not store) and --capsule-ratio only capsules fitted here.
// True when one of them was given in vain, after saying so.
bool refuse_unused_on_asset(const CLI::App* c, const std::string& file) {
    const std::string why = file + " is an asset, ";
    std::vector<std::string> shape_flags;
    for (const cb::BakeOption& o : cb::bake_options())
        if (cb::shapes_clusters(o)) shape_flags.push_back(o.flag);
    if (refuse_given(c, shape_flags, why + "clustered when it was baked")) return true;
    if (refuse_given(c, {"--allow-outside-files", "--memory-budget"}, why + "not a scene: nothing is loaded or baked"))
        return true;
    if (first_given(c, {"--obb", "--capsule-ratio"}).empty()) return false;
    cb::LoadedAsset asset;
    std::string error;
    if (!cb::read_asset_file(file, asset, error)) return false;  // load_baked reports it
    uint32_t kinds = stored_kinds(asset.view);
    return (kinds == cb::bounds_all && refuse_given(c, {"--obb"}, why + "which stores every volume kind")) ||
        ((kinds & cb::bounds_capsule) && refuse_given(c, {"--capsule-ratio"}, why + "which stores capsules"));
}

nlohmann::json stats_json(const ClusterArgs& a, const cb::SceneStats& s, const cb::ClusterOptions& clustering,
                          bool asset, const std::string& note) {
    nlohmann::json j = cb::to_json(s);
    j["tool"] = cb::tool_version();
    j["file"] = a.file;
    if (asset) {
        j["input"] = "asset";
        if (!note.empty()) j["note"] = note;
        return j;
    }
    j["input"] = "scene";
    j["method"] = cb::method_name(clustering.method);
    j["coarse_size"] = clustering.coarse_size;
    j["fine_size"] = clustering.fine_size;
    j["obb"] = given_or_default(a.flags, "--obb");
    return j;
}

int run_stats(const CLI::App* c, const ClusterArgs& a, cb::StatsOptions so) {
    // Every rule first; an asset's own refusals replace those of a scene's clustering method.
    bool asset = cb::is_asset_file(a.file);
    cb::BakeRequest request;
    std::string error = apply_flags(a.flags, request);
    if (error.empty() && !asset) error = cb::ignored_option_error(given_flags(a.flags), request);
    if (!usage_ok(error) || (asset && refuse_unused_on_asset(c, a.file))) return exit_usage;
    const cb::ClusterOptions& clustering = request.clustering;
    cb::BoundsOptions bounds = request.bounds;
    bounds.mask = cb::bounds_all;
    so.threads = request.threads;
    ProgressLine progress(!a.quiet);
    progress.stage((asset ? "reading " : "clustering and fitting ") + a.file);
    cb::BakedScene baked;
    std::string note;
    try {
        baked = cb::load_baked(a.file, clustering, bounds, &note, bake_progress(progress), a.load, request.threads);
    } catch (const std::runtime_error& e) {
        progress.clear();
        std::fprintf(stderr, "%s\n", e.what());
        return exit_bad_input;
    }
    progress.stage("measuring the clusters of " + a.file);
    cb::SceneStats s = cb::cluster_statistics(baked.meshes, baked.instances, so);
    progress.clear();
    if (a.json) {
        std::cout << stats_json(a, s, clustering, asset, note).dump(2) << "\n";
        return 0;
    }
    if (asset)
        std::printf("%s: asset%s%s\n", a.file.c_str(), note.empty() ? "" : "; ", note.c_str());
    else
        std::printf("%s: method %s, coarse %u, fine %u, obb %s\n", a.file.c_str(), cb::method_name(clustering.method),
                    clustering.coarse_size, clustering.fine_size, given_or_default(a.flags, "--obb").c_str());
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
    add_bake_flags(c, a->clustering.flags, stats_takes);  // for an asset, --obb shapes the volumes it does not store
    add_load_flags(c, a->clustering.load);
    c->add_option("--sample-lights", a->options.lights, "Random light positions per mesh (default 8)");
    c->add_option("--sample-suns", a->options.suns, "Random sun directions per mesh (default 8)");
    c->add_option("--samples", a->options.samples,
                  "Points sampled in each cluster's shadow volume per light and sun (default 32)");
    c->add_option("--light-seed", a->options.seed, "Seed of the lights and samples (default 1)");
    c->add_option("--acmr-cache", a->options.acmr_cache, "FIFO cache size for the ACMR (default 32)");
    c->add_flag("--json", a->clustering.json, "Print the statistics as JSON");
    c->add_flag("-q,--quiet", a->clustering.quiet, "No progress on stderr");
    return {c, [a, c] { return run_stats(c, a->clustering, a->options); }};
}

}  // namespace cb::cli
