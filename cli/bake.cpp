// clusterbake cluster and bake: load a scene, cluster it (and fit bounds: bake), write the asset.
#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include "args.h"
#include "bake_file.h"
#include "commands.h"
#include "load.h"
#include "progress.h"

namespace cb::cli {
namespace {

// What is wrong with the output path, found before any work, as "OUT: problem"; empty when nothing is. A
// scene file's name for an asset is a trap (a later load of it fails, or a source is overwritten), allowed
// with --force.
std::string output_problem(const std::string& out, bool force) {
    std::string error = output_file_error(out);
    if (error.empty() && !force && cb::format_from_path(out) != cb::FileFormat::unknown)
        error = out + ": named like a scene file; an asset is not one (name it .cbk, or --force)";
    return error;
}

// `cluster` (geometry and hierarchy only) and `bake` (with bounds) share this.
int run_bake(const ClusterArgs& a) {
    cb::BakeRequest request;
    if (!parse_request(a, request)) return exit_usage;
    if (a.force && a.if_changed) {
        std::fprintf(stderr, "clusterbake: --force and --if-changed contradict each other\n");
        return exit_usage;
    }
    request.input = a.file;
    request.output = a.out;
    if (!usage_ok(output_problem(a.out, a.force))) return exit_usage;

    // The memory budget as a hard limit on this process too, as for each file of a batch: a file bakes
    // alone exactly when it bakes in a batch.
    cb::limit_process_memory(request.load.memory_budget, request.threads);

    // Progress once a bake has taken a second, on a terminal only: one line redrawn in place on stderr.
    ProgressLine line(!a.quiet);
    cb::BakeResult r = cb::bake_file(request, bake_progress(line));
    line.clear();
    if (r.status == cb::BakeStatus::failed) {
        std::fprintf(stderr, "%s\n", r.error.c_str());
        return exit_bad_input;
    }
    if (!r.warning.empty()) std::fprintf(stderr, "clusterbake: warning: %s\n", r.warning.c_str());
    const cb::ClusterOptions& options = request.clustering;
    const cb::BoundsOptions& bounds = request.bounds;
    const cb::BakeStats& stats = r.stats;
    // What every bake reports, up to date or not; a bake adds what it measured.
    nlohmann::json j = {{"tool", cb::tool_version()},
                        {"file", a.file},
                        {"output", a.out},
                        {"status", cb::status_name(r.status)},
                        {"input_bytes", r.input_bytes},
                        {"triangles", r.triangles},
                        {"fine_clusters", r.fine_clusters},
                        {"coarse_clusters", r.coarse_clusters},
                        {"asset_bytes", r.output_bytes},
                        {"seconds", r.seconds}};
    if (r.status == cb::BakeStatus::up_to_date) {
        if (a.json)
            std::cout << j.dump(2) << "\n";
        else if (!a.quiet)
            std::printf("%s -> %s: up to date (same input bytes, options and tool)\n", a.file.c_str(), a.out.c_str());
        return 0;
    }
    double load_s = r.load_seconds, write_s = r.write_seconds;
    size_t asset_bytes = r.output_bytes;
    double tps = stats.cluster_seconds > 0 ? double(stats.triangles) / stats.cluster_seconds : 0;
    if (a.json) {
        j.update({{"method", cb::method_name(options.method)},
                  {"coarse_size", options.coarse_size},
                  {"fine_size", options.fine_size},
                  {"meshes", r.meshes},
                  {"instances", r.instances},
                  {"fine_min", stats.fine_min},
                  {"fine_max", stats.fine_max},
                  {"fine_below_half", stats.fine_below_half},
                  {"coarse_min", stats.coarse_min},
                  {"coarse_max", stats.coarse_max},
                  {"load_seconds", load_s},
                  {"cluster_seconds", stats.cluster_seconds},
                  {"write_seconds", write_s},
                  {"triangles_per_second", tps},
                  {"bytes_per_triangle", stats.triangles ? double(asset_bytes) / double(stats.triangles) : 0.0}});
        if (a.fit) {
            j["bounds"] = given_or_default(a.flags, "--bounds");
            j["fit_seconds"] = stats.fit_seconds;
            if (bounds.mask & cb::bounds_cone) j["valid_cones"] = stats.valid_cones;
            if (bounds.mask & cb::bounds_capsule) j["capsules"] = stats.capsules;
        }
        if (options.method == cb::ClusterMethod::vco) {
            j["acmr_before"] = stats.acmr_before;
            j["acmr_after"] = stats.acmr_after;
        }
        if (uint64_t peak = peak_resident_bytes()) j["peak_resident_bytes"] = peak;
        std::cout << j.dump(2) << "\n";
        return 0;
    }
    std::printf("%s -> %s\n", a.file.c_str(), a.out.c_str());
    std::printf("  method %s, coarse %u, fine %u: %llu triangles in %llu meshes (%llu instances)\n",
                cb::method_name(options.method), options.coarse_size, options.fine_size,
                (unsigned long long)stats.triangles, (unsigned long long)r.meshes, (unsigned long long)r.instances);
    std::printf("  coarse clusters %llu (%u..%u triangles), fine clusters %llu (%u..%u triangles, %llu below half)\n",
                (unsigned long long)stats.coarse_clusters, stats.coarse_min, stats.coarse_max,
                (unsigned long long)stats.fine_clusters, stats.fine_min, stats.fine_max,
                (unsigned long long)stats.fine_below_half);
    if (options.method == cb::ClusterMethod::vco)
        std::printf("  ACMR (FIFO %u) %.3f -> %.3f\n", options.vco_cache_size, stats.acmr_before, stats.acmr_after);
    if (a.fit) {
        std::printf("  bounds %s (obb %s): fitted in %.3f s", given_or_default(a.flags, "--bounds").c_str(),
                    given_or_default(a.flags, "--obb").c_str(), stats.fit_seconds);
        unsigned long long clusters = stats.fine_clusters + stats.coarse_clusters;
        if (bounds.mask & cb::bounds_cone)
            std::printf("; %llu of %llu clusters have a valid cone", (unsigned long long)stats.valid_cones, clusters);
        if (bounds.mask & cb::bounds_capsule)
            std::printf("; %llu of %llu are capsules", (unsigned long long)stats.capsules, clusters);
        std::printf("\n");
    }
    std::printf(
        "  load %.3f s, cluster %.3f s (%.2f M triangles/s), write %.3f s, asset %zu bytes (%.1f per triangle)\n",
        load_s, stats.cluster_seconds, tps / 1e6, write_s, asset_bytes,
        stats.triangles ? double(asset_bytes) / double(stats.triangles) : 0.0);
    return 0;
}

// The input, the output and the clustering options, common to both.
void add_common(CLI::App* c, ClusterArgs& a) {
    c->add_option("file", a.file, "Scene file")->required();
    c->add_option("-o,--output", a.out, "Output asset (.cbk); written atomically")->required();
    add_bake_flags(c, a.flags, a.fit ? bake_takes : cluster_takes);
    add_load_flags(c, a.load);
    c->add_option("--files-root", a.load.root,
                  "External files a scene names must lie inside this folder (default: the scene's own folder)");
    c->add_flag("--if-changed", a.if_changed,
                "Keep the output when it was made from the same input bytes, options and tool version");
    c->add_flag("--force", a.force,
                "Bake even when the output is up to date (the default without --if-changed), and even to an output "
                "named like a scene file");
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
    return {c, [a] { return run_bake(*a); }};
}

}  // namespace cb::cli
