// What the subcommands share: the exit code of bad input, the clustering and box-fitter options of
// `cluster`, `bake` and `stats`, the checks of options and outputs made before any work, and the parsers
// whose errors are one line on stderr.
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

#include "asset_file.h"
#include "bake_file.h"
#include "bounds.h"
#include "cluster.h"
#include "progress.h"
#include "scene_query.h"

namespace cb::cli {

constexpr int exit_bad_input = 2;  // a file that does not load or is not valid
constexpr int exit_usage = 2;      // an option or argument the command cannot take, found before any work

struct ClusterArgs {
    std::string file, out, method = "kmeans";
    cb::ClusterOptions options;
    cb::LoadOptions load;
    bool json = false, quiet = false;
    bool fit = false;  // bake: fit bounds too
    bool if_changed = false, force = false;
    std::string bounds = "auto", obb = "refined";
    double capsule_ratio = 2.0;
};

// What a command trusts its scene files with (--allow-outside-files, --memory-budget): every command
// that loads scenes takes them.
void add_load_flags(CLI::App* c, cb::LoadOptions& load);

// The clustering options (--method, --coarse, --fine, --threads and the methods' own) of cluster, bake, stats.
void add_clustering_flags(CLI::App* c, ClusterArgs& a);

// What add_clustering_flags adds but --threads: the options that shape the clusters.
const std::vector<std::string>& cluster_shape_flags();

// When an option of another clustering method than `method` was given (--cache is vco's, --seed, --k0,
// --iterations, --presplit and --coarse-morton k-means'), or --presplit with --coarse-morton: "NAME does
// nothing here: WHY"; otherwise empty. refuse_unused_by_method prints it as refuse_given does, and says
// whether it did.
std::string unused_by_method_error(const CLI::App* c, ClusterMethod method);
bool refuse_unused_by_method(const CLI::App* c, ClusterMethod method);

// The help text of --threads: the same default, all hardware threads, in every command.
std::string threads_help(const std::string& what);

// The first of `names` given on the command line, or empty.
std::string first_given(const CLI::App* c, const std::vector<std::string>& names);

// When one of `names` was given: "clusterbake: NAME does nothing here: WHY" on stderr, and true. A command
// refuses what it would ignore, so that no option is silently dropped.
bool refuse_given(const CLI::App* c, const std::vector<std::string>& names, const std::string& why);

// Why `path` cannot be an output file (it exists and is not a regular file, or its folder does not
// exist), or empty.
std::string output_file_error(const std::string& path);

// Makes the output folder `path`; why it cannot be one (it exists and is not a folder, cannot be made, or
// cannot be written into), or empty.
std::string output_folder_error(const std::string& path);

// "clusterbake: ERROR" on stderr when `error` is not empty; true when it is empty.
bool usage_ok(const std::string& error);

// Why `file` cannot be the scene `command` reads (it is an asset, whose clusters are already made), or empty.
std::string scene_input_error(const std::string& file, const std::string& command);

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

// What a bake (bake, stats) draws on `line` once it has taken a second: the share of the clustering done,
// then of the bounds fitting, each stage with its own time left.
BakeProgress bake_progress(ProgressLine& line);

// "X,Y,Z", three finite numbers; otherwise a one-line error and false.
bool parse_light(const std::string& text, double* light);

// The asset file read and opened; otherwise its one-line error on stderr.
bool load_asset(const std::string& file, LoadedAsset& out);

// The assets a query or a picture is over, and the level they make.
struct LoadedLevel {
    std::vector<LoadedAsset> assets;
    LevelInput level;  // views into `assets`: moving a LoadedAsset keeps its view valid, copying is refused
};

// An asset file (every baked instance as baked), or a level file (io/level_file.h) with every asset it
// names opened once; otherwise a one-line error naming the file and the entry on stderr.
bool load_level(const std::string& file, LoadedLevel& out);

// This process's peak resident memory in bytes so far (Linux: VmHWM, which counts only this program's
// image, not its parent's before exec); 0 where unknown.
uint64_t peak_resident_bytes();

}  // namespace cb::cli
