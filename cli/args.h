// What the subcommands share: the exit code of bad input, the clustering and box-fitter options of
// `cluster`, `bake` and `stats`, and the parsers whose errors are one line on stderr.
#pragma once

#include <CLI/CLI.hpp>

#include <string>

#include "asset_file.h"
#include "bake_file.h"
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
    bool if_changed = false, force = false;
    std::string bounds = "auto", obb = "refined";
    double capsule_ratio = 2.0;
};

// The clustering options (--method, --coarse, --fine, --threads and the methods' own) of cluster, bake, stats.
void add_clustering_flags(CLI::App* c, ClusterArgs& a);

// The bounding volume options of bake and batch: --bounds, --obb, --capsule-ratio.
void add_bounds_flags(CLI::App* c, ClusterArgs& a);

// The box fitter's name; otherwise a one-line error and false.
bool parse_obb(const std::string& text, ObbMethod& out);

// The clustering method, ranges and box fitter named on the command line (bake, cluster, stats): what is
// wrong with them in one line, or empty. parse_clustering prints the line ("clusterbake: ...") instead.
std::string clustering_error(const ClusterArgs& a, ClusterOptions& clustering, BoundsOptions& bounds);
bool parse_clustering(const ClusterArgs& a, ClusterOptions& clustering, BoundsOptions& bounds);

// The clustering and bounds options of a bake (clustering_error, then --bounds when fitting), the same way.
// Leaves the input and output paths empty.
std::string request_error(const ClusterArgs& a, BakeRequest& out);
bool parse_request(const ClusterArgs& a, BakeRequest& out);

// "X,Y,Z", three finite numbers; otherwise a one-line error and false.
bool parse_light(const std::string& text, double* light);

// The asset file read and opened; otherwise its one-line error on stderr.
bool load_asset(const std::string& file, LoadedAsset& out);

}  // namespace cb::cli
