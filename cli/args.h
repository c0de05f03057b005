// What the subcommands share: the exit code of bad input, the clustering and box-fitter options of
// `cluster`, `bake` and `stats`, and the parsers whose errors are one line on stderr.
#pragma once

#include <CLI/CLI.hpp>

#include <string>

#include "asset_file.h"
#include "bounds.h"
#include "cluster.h"

namespace cb::cli {

constexpr int exit_bad_input = 2;  // a file that does not load or is not valid
constexpr int exit_usage = 2;      // an option or argument the command cannot take, found before any work

struct ClusterArgs {
    std::string file, out, method = "kmeans";
    cb::ClusterOptions options;
    bool json = false, quiet = false;
    bool fit = false;  // bake: fit bounds too
    std::string bounds = "auto", obb = "refined";
    double capsule_ratio = 2.0;
};

// The clustering options (--method, --coarse, --fine, --threads and the methods' own) of cluster, bake, stats.
void add_clustering_flags(CLI::App* c, ClusterArgs& a);

// The box fitter's name; otherwise a one-line error and false.
bool parse_obb(const std::string& text, ObbMethod& out);

// The clustering method and box fitter named on the command line (bake, cluster, stats); one-line errors.
bool parse_clustering(const ClusterArgs& a, ClusterOptions& clustering, BoundsOptions& bounds);

// "X,Y,Z", three finite numbers; otherwise a one-line error and false.
bool parse_light(const std::string& text, double* light);

// The asset file read and opened; otherwise its one-line error on stderr.
bool load_asset(const std::string& file, LoadedAsset& out);

}  // namespace cb::cli
