// What the subcommands share: the exit code of bad input, the bake options' flags (from the table of
// bake_options.h) of `cluster`, `bake`, `batch`, `stats` and `heatmap`, the checks of options and outputs
// made before any work, and the parsers whose errors are one line on stderr.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>
#include <string>
#include <vector>

#include "asset_file.h"
#include "bake_file.h"
#include "bake_options.h"
#include "bounds.h"
#include "cluster.h"
#include "progress.h"
#include "scene_query.h"

namespace cb::cli {

constexpr int exit_bad_input = 2;  // a file that does not load or is not valid
constexpr int exit_usage = 2;      // an option or argument the command cannot take, found before any work

// The bake options (bake_options.h) a command takes, each as its text on the command line.
struct BakeFlags {
    std::vector<std::string> values = std::vector<std::string>(cb::bake_options().size());
    std::vector<const CLI::Option*> options = std::vector<const CLI::Option*>(cb::bake_options().size(), nullptr);
};

struct ClusterArgs {
    std::string file, out;
    BakeFlags flags;
    cb::LoadOptions load;
    bool json = false, quiet = false;
    bool fit = false;  // bake: fit bounds too
    bool if_changed = false, force = false;
};

// What a command trusts its scene files with (--allow-outside-files, --memory-budget): every command
// that loads scenes takes them.
void add_load_flags(CLI::App* c, cb::LoadOptions& load);

// The options of the table that `takes` accepts, as flags of `c` with their help and default.
void add_bake_flags(CLI::App* c, BakeFlags& f, const std::function<bool(const cb::BakeOption&)>& takes);

// Which options of the table a command takes: cluster (every one but the bounds'), bake and batch (every
// one), stats (cluster's and the two that shape volumes fitted here, --obb and --capsule-ratio).
bool cluster_takes(const cb::BakeOption& o);
bool bake_takes(const cb::BakeOption& o);
bool stats_takes(const cb::BakeOption& o);

// The flags of the table given on the command line, in the table's order.
std::vector<std::string> given_flags(const BakeFlags& f);

// The text given for `flag`, or its default in the table.
std::string given_or_default(const BakeFlags& f, const std::string& flag);

// The options given applied onto `r` in the table's order, then checked (request_options_error): the
// one-line error, or empty.
std::string apply_flags(const BakeFlags& f, cb::BakeRequest& r);

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

// The request of a bake, cluster or stats command line (`fit`, `if_changed` and `load` from `a`, the
// options from its flags), checked before any work: the rules, then the options that would change
// nothing. The one-line error, or empty; parse_request prints it ("clusterbake: ...") instead. Leaves the
// input and output paths empty.
std::string request_error(const ClusterArgs& a, cb::BakeRequest& out);
bool parse_request(const ClusterArgs& a, cb::BakeRequest& out);

// What a bake (bake, stats) draws on `line` once it has taken a second: the share of the clustering done,
// then of the bounds fitting, each stage with its own time left.
BakeProgress bake_progress(ProgressLine& line);

// "X,Y,Z", three finite numbers; otherwise a one-line error and false.
bool parse_light(const std::string& text, double* light);

// The direction toward a sun, --sun "X,Y,Z": three finite numbers, not all zero; otherwise a one-line error and
// false.
bool parse_sun(const std::string& text, double* toward);

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
