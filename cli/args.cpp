#include "args.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>

#include "level_file.h"

namespace cb::cli {

void add_load_flags(CLI::App* c, cb::LoadOptions& load) {
    c->add_flag("--allow-outside-files", load.allow_outside_files,
                "Read the external files a scene names (glTF buffers) anywhere, not only inside its folder (a "
                "batch's: inside its input root); scenes are untrusted input, see docs/SECURITY.md");
    c->add_option("--memory-budget", load.memory_budget,
                  "Bytes one scene may take to load and bake, with a unit: 512MB, 8GB (default 4GB, which a "
                  "10 M-triangle scene fits); a scene that needs more fails cleanly")
        ->transform(CLI::AsSizeValue(false));
}

void add_clustering_flags(CLI::App* c, ClusterArgs& a) {
    c->add_option("--method", a.method, "kmeans (default), vco or morton");
    c->add_option("--coarse", a.options.coarse_size, "Triangles per coarse cluster (default 2048)");
    // 85 triangles have at most 255 distinct corners: every cluster fits the asset's 8-bit local indices.
    c->add_option("--fine", a.options.fine_size, "Maximum triangles per fine cluster, 1 to 85 (default 16)")
        ->check(CLI::Range(1, 85));
    c->add_option("--threads", a.options.threads, threads_help("the output is identical for any count"));
    c->add_option("--seed", a.options.seed, "Seed of k-means++ (default 1)");
    c->add_option("--k0", a.options.kmeans_branching, "k-means children per node (default 8)");
    c->add_option("--iterations", a.options.kmeans_max_iterations, "Cap on Lloyd iterations per node (default 16)");
    c->add_flag_callback(
        "--coarse-morton", [&a] { a.options.kmeans_coarse_from_tree = false; },
        "kmeans: Morton chunks as the coarse level instead of the top of the k-means trees");
    c->add_option("--presplit", a.options.kmeans_presplit,
                  "kmeans: triangles per Morton chunk the trees grow in, in parallel (default 65536; 0: one tree)");
    c->add_option("--cache", a.options.vco_cache_size, "vco: vertex cache size (default 32)");
}

const std::vector<std::string>& cluster_shape_flags() {
    static const std::vector<std::string> names = {"--method",     "--coarse", "--fine",     "--seed",         "--k0",
                                                   "--iterations", "--cache",  "--presplit", "--coarse-morton"};
    return names;
}

std::string unused_by_method_error(const CLI::App* c, cb::ClusterMethod method) {
    const std::string name = cb::method_name(method);
    auto unused = [&](const std::vector<std::string>& names, const std::string& why) {
        const std::string given = first_given(c, names);
        return given.empty() ? given : given + " does nothing here: " + why;
    };
    std::string error;
    if (method != cb::ClusterMethod::vco) error = unused({"--cache"}, "an option of vco, and the method is " + name);
    if (error.empty() && method != cb::ClusterMethod::kmeans)
        error = unused({"--seed", "--k0", "--iterations", "--presplit", "--coarse-morton"},
                       "an option of kmeans, and the method is " + name);
    if (error.empty() && !first_given(c, {"--coarse-morton"}).empty())
        error = unused({"--presplit"}, "with --coarse-morton no k-means tree grows in presplit chunks");
    return error;
}

bool refuse_unused_by_method(const CLI::App* c, cb::ClusterMethod method) {
    return !usage_ok(unused_by_method_error(c, method));
}

std::string threads_help(const std::string& what) {
    return "Worker threads, 0 = all hardware threads (default); " + what;
}

std::string first_given(const CLI::App* c, const std::vector<std::string>& names) {
    for (const std::string& name : names) {
        const CLI::Option* option = c->get_option_no_throw(name);
        if (option && option->count() > 0) return name;
    }
    return {};
}

bool refuse_given(const CLI::App* c, const std::vector<std::string>& names, const std::string& why) {
    std::string name = first_given(c, names);
    if (name.empty()) return false;
    std::fprintf(stderr, "clusterbake: %s does nothing here: %s\n", name.c_str(), why.c_str());
    return true;
}

std::string output_file_error(const std::string& path) {
    namespace fs = std::filesystem;
    std::error_code ec;
    fs::file_status status = fs::status(path, ec);
    if (fs::exists(status) && !fs::is_regular_file(status)) return path + ": exists and is not a regular file";
    std::string folder = fs::path(path).parent_path().string();
    if (folder.empty()) folder = ".";
    if (!fs::is_directory(folder, ec)) return path + ": folder " + folder + " does not exist";
    if (access(folder.c_str(), W_OK | X_OK) != 0) return path + ": cannot write into folder " + folder;
    return {};
}

std::string output_folder_error(const std::string& path) {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (fs::exists(path, ec) && !fs::is_directory(path, ec)) return path + ": exists and is not a folder";
    fs::create_directories(path, ec);
    if (ec) return path + ": cannot make the folder (" + ec.message() + ")";
    if (access(path.c_str(), W_OK | X_OK) != 0) return path + ": cannot write into the folder";
    return {};
}

bool usage_ok(const std::string& error) {
    if (!error.empty()) std::fprintf(stderr, "clusterbake: %s\n", error.c_str());
    return error.empty();
}

std::string scene_input_error(const std::string& file, const std::string& command) {
    if (!cb::is_asset_file(file)) return {};
    return file + ": is a clusterbake asset; " + command +
        " clusters a scene file itself (.gltf .glb .obj .ply .off .stl)";
}

void add_bounds_flags(CLI::App* c, ClusterArgs& a) {
    c->add_option("--bounds", a.bounds,
                  "auto (what the shadow runtime reads: obb,cone), all, or a list of obb,sphere,capsule,cone,slab");
    c->add_option("--obb", a.obb, "refined (default), pca, pca-area, or cgal (CGAL's optimum: slow)");
    c->add_option("--capsule-ratio", a.capsule_ratio,
                  "Fit a capsule when the box's longest side is this many times each other (default 2)");
}

bool parse_obb(const std::string& text, cb::ObbMethod& out) {
    if (cb::parse_obb_method(text, out)) return true;
    std::fprintf(stderr, "clusterbake: --obb takes refined, pca, pca-area or cgal (got '%s')\n", text.c_str());
    return false;
}

std::string clustering_error(const ClusterArgs& a, cb::ClusterOptions& clustering, cb::BoundsOptions& bounds) {
    clustering = a.options;
    // Ranges no algorithm can work with, refused before any work.
    if (clustering.coarse_size == 0) return "--coarse must be at least 1";
    if (clustering.coarse_size < clustering.fine_size) return "--coarse must be at least --fine";
    if (clustering.kmeans_branching < 2) return "--k0 must be at least 2 (children per k-means node)";
    if (clustering.vco_cache_size < 3) return "--cache must be at least 3 (a triangle's corners)";
    if (!(a.capsule_ratio >= 1 && std::isfinite(a.capsule_ratio)))
        return "--capsule-ratio must be a finite number of at least 1";
    if (!cb::parse_method(a.method, clustering.method))
        return "unknown method '" + a.method + "' (kmeans, vco, morton)";
    bounds.capsule_ratio = a.capsule_ratio;
    if (!cb::parse_obb_method(a.obb, bounds.obb))
        return "--obb takes refined, pca, pca-area or cgal (got '" + a.obb + "')";
    return {};
}

bool parse_clustering(const ClusterArgs& a, cb::ClusterOptions& clustering, cb::BoundsOptions& bounds) {
    std::string error = clustering_error(a, clustering, bounds);
    if (!error.empty()) std::fprintf(stderr, "clusterbake: %s\n", error.c_str());
    return error.empty();
}

std::string request_error(const ClusterArgs& a, cb::BakeRequest& out) {
    out = cb::BakeRequest{};
    out.fit = a.fit;
    out.if_changed = a.if_changed;
    out.load = a.load;
    std::string error = clustering_error(a, out.clustering, out.bounds);
    if (error.empty() && a.fit && !cb::parse_bounds_mask(a.bounds, out.bounds.mask))
        error = "--bounds takes auto, all or a list of obb,sphere,capsule,cone,slab (got '" + a.bounds + "')";
    return error;
}

bool parse_request(const ClusterArgs& a, cb::BakeRequest& out) {
    std::string error = request_error(a, out);
    if (!error.empty()) std::fprintf(stderr, "clusterbake: %s\n", error.c_str());
    return error.empty();
}

bool parse_light(const std::string& text, double* light) {
    char extra;
    if (std::sscanf(text.c_str(), "%lf,%lf,%lf%c", &light[0], &light[1], &light[2], &extra) == 3 &&
        std::isfinite(light[0]) && std::isfinite(light[1]) && std::isfinite(light[2]))
        return true;
    std::fprintf(stderr, "clusterbake: --light takes X,Y,Z (got '%s')\n", text.c_str());
    return false;
}

bool load_asset(const std::string& file, cb::LoadedAsset& out) {
    std::string error;
    if (cb::read_asset_file(file, out, error)) return true;
    std::fprintf(stderr, "%s\n", error.c_str());
    return false;
}

bool load_level(const std::string& file, LoadedLevel& out) {
    out = LoadedLevel{};
    if (!cb::is_level_file(file)) {
        out.assets.emplace_back();
        if (!load_asset(file, out.assets.back())) return false;
        cb::place_baked(out.level, out.assets.back().view);
        return true;
    }
    std::vector<cb::LevelEntry> entries;
    std::string error;
    if (!cb::read_level_file(file, entries, error)) {
        std::fprintf(stderr, "%s\n", error.c_str());
        return false;
    }
    // Each asset opened once, in the order the entries first name it; the views are taken once all are in.
    std::vector<std::string> paths;
    std::vector<size_t> asset_of(entries.size());
    for (size_t i = 0; i < entries.size(); ++i) {
        const std::string path = std::filesystem::path(entries[i].asset).lexically_normal().string();
        asset_of[i] = size_t(std::find(paths.begin(), paths.end(), path) - paths.begin());
        if (asset_of[i] < paths.size()) continue;
        paths.push_back(path);
        out.assets.emplace_back();
        if (!cb::read_asset_file(path, out.assets.back(), error)) {
            std::fprintf(stderr, "%s: instances[%zu]: %s\n", file.c_str(), i, error.c_str());
            return false;
        }
    }
    for (size_t i = 0; i < entries.size(); ++i) {
        const cb::Transform& m = entries[i].transform;  // column-major 4x4; the runtime takes its top 3 rows
        const double matrix[12] = {m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10], m[12], m[13], m[14]};
        cb::place_baked(out.level, out.assets[asset_of[i]].view, matrix);
    }
    return true;
}

BakeProgress bake_progress(ProgressLine& line) {
    struct State {
        std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
        bool fitting = false;
    };
    auto state = std::make_shared<State>();
    auto late = [state] { return std::chrono::steady_clock::now() - state->start > std::chrono::seconds(1); };
    BakeProgress progress;
    progress.clustering = [&line, late](size_t m, size_t mc, size_t c, size_t cc) {
        if (!line.on() || !late()) return;
        const double fraction = (double(m) + (cc ? double(c) / double(cc) : 1.0)) / double(std::max<size_t>(mc, 1));
        line.show(fraction, "clustering mesh " + std::to_string(m + 1) + "/" + std::to_string(mc));
    };
    progress.bounds = [&line, state, late](size_t done, size_t total) {
        if (!line.on()) return;
        if (!state->fitting) line.restart(), state->fitting = true;  // the time left is the fitting's own
        if (!late()) return;
        line.show(total ? double(done) / double(total) : 1.0,
                  "fitting bounds: " + std::to_string(done / 1000) + "k of " + std::to_string(total / 1000) +
                      "k cluster triangles");
    };
    return progress;
}

uint64_t peak_resident_bytes() {
    std::FILE* f = std::fopen("/proc/self/status", "r");
    if (!f) return 0;
    char line[256];
    unsigned long long kb = 0;
    while (std::fgets(line, sizeof line, f))
        if (std::sscanf(line, "VmHWM: %llu kB", &kb) == 1) break;
    std::fclose(f);
    return uint64_t(kb) * 1024;
}

}  // namespace cb::cli
