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

void add_bake_flags(CLI::App* c, BakeFlags& f, const std::function<bool(const cb::BakeOption&)>& takes) {
    const std::vector<cb::BakeOption>& table = cb::bake_options();
    for (size_t i = 0; i < table.size(); ++i) {
        const cb::BakeOption& o = table[i];
        if (!takes(o)) continue;
        if (o.takes_value)
            f.options[i] = c->add_option(o.flag, f.values[i], o.help + " (default " + o.default_value + ")")
                               ->type_name(o.value_type);
        else
            f.options[i] = c->add_flag(o.flag, o.help);
    }
}

bool cluster_takes(const cb::BakeOption& o) { return o.use != cb::OptionUse::bounds; }

bool bake_takes(const cb::BakeOption&) { return true; }

bool stats_takes(const cb::BakeOption& o) {
    return cluster_takes(o) || std::string(o.flag) == "--obb" || std::string(o.flag) == "--capsule-ratio";
}

std::vector<std::string> given_flags(const BakeFlags& f) {
    std::vector<std::string> given;
    for (size_t i = 0; i < f.options.size(); ++i)
        if (f.options[i] && f.options[i]->count() > 0) given.push_back(cb::bake_options()[i].flag);
    return given;
}

std::string given_or_default(const BakeFlags& f, const std::string& flag) {
    const std::vector<cb::BakeOption>& table = cb::bake_options();
    for (size_t i = 0; i < table.size(); ++i) {
        if (flag != table[i].flag) continue;
        return f.options[i] && f.options[i]->count() > 0 ? f.values[i] : table[i].default_value;
    }
    return {};
}

std::string apply_flags(const BakeFlags& f, cb::BakeRequest& r) {
    const std::vector<cb::BakeOption>& table = cb::bake_options();
    for (size_t i = 0; i < table.size(); ++i) {
        if (!f.options[i] || f.options[i]->count() == 0) continue;
        std::string error = table[i].set(r, f.values[i]);
        if (!error.empty()) return error;
    }
    return cb::request_options_error(r);
}

std::string threads_help(const std::string& what) {
    return "Worker threads, 0 = all hardware threads; " + what + " (default 0)";
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

std::string request_error(const ClusterArgs& a, cb::BakeRequest& out) {
    out = cb::BakeRequest{};
    out.fit = a.fit;
    out.if_changed = a.if_changed;
    out.load = a.load;
    std::string error = apply_flags(a.flags, out);
    if (error.empty()) error = cb::ignored_option_error(given_flags(a.flags), out);
    return error;
}

bool parse_request(const ClusterArgs& a, cb::BakeRequest& out) { return usage_ok(request_error(a, out)); }

bool parse_light(const std::string& text, double* light) {
    char extra;
    if (std::sscanf(text.c_str(), "%lf,%lf,%lf%c", &light[0], &light[1], &light[2], &extra) == 3 &&
        std::isfinite(light[0]) && std::isfinite(light[1]) && std::isfinite(light[2]))
        return true;
    std::fprintf(stderr, "clusterbake: --light takes X,Y,Z (got '%s')\n", text.c_str());
    return false;
}

bool parse_sun(const std::string& text, double* toward) {
    char extra;
    if (std::sscanf(text.c_str(), "%lf,%lf,%lf%c", &toward[0], &toward[1], &toward[2], &extra) == 3 &&
        std::isfinite(toward[0]) && std::isfinite(toward[1]) && std::isfinite(toward[2]) &&
        (toward[0] != 0 || toward[1] != 0 || toward[2] != 0))
        return true;
    std::fprintf(stderr, "clusterbake: --sun takes X,Y,Z, the direction toward the sun, not all zero (got '%s')\n",
                 text.c_str());
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
        if (!state->fitting) {  // the time left is the fitting's own
            line.restart();
            state->fitting = true;
        }
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
