// clusterbake command line: parses arguments, calls the libraries, prints. No algorithm lives here.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <thread>

#include <cb_cpsv.h>
#include <cb_shadow.h>

#include "bake.h"
#include "cluster_stats.h"
#include "heatmap.h"
#include "report.h"
#include "load.h"
#include "scene_info.h"
#include "stats_input.h"

namespace {

constexpr int exit_bad_input = 2;

int run_info(const std::vector<std::string>& files, bool json) {
    int status = 0;
    nlohmann::json all = nlohmann::json::array();
    for (const std::string& file : files) {
        auto start = std::chrono::steady_clock::now();
        try {
            cb::Scene scene = cb::load_scene(file);
            double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
            cb::SceneInfo info = cb::describe(scene);
            if (json) {
                nlohmann::json j = cb::to_json(info);
                j["file"] = file;
                j["load_ms"] = ms;
                all.push_back(j);
                continue;
            }
            std::printf("%s\n", file.c_str());
            std::printf("  meshes %llu, primitives %llu (%llu Draco, %llu points/lines skipped), instances %llu\n",
                        (unsigned long long)info.meshes, (unsigned long long)info.primitives,
                        (unsigned long long)info.draco_primitives, (unsigned long long)info.skipped_primitives,
                        (unsigned long long)info.instances);
            std::printf("  triangles %llu unique, %llu in scene; vertices %llu unique, %llu in scene\n",
                        (unsigned long long)info.unique_triangles, (unsigned long long)info.scene_triangles,
                        (unsigned long long)info.unique_vertices, (unsigned long long)info.scene_vertices);
            std::printf("  degenerate triangles %llu (kept)\n", (unsigned long long)info.degenerate_triangles);
            if (info.unreferenced_meshes)
                std::printf("  meshes not used by the scene %llu (not loaded)\n",
                            (unsigned long long)info.unreferenced_meshes);
            if (info.empty_bounds)
                std::printf("  world bounds: empty\n");
            else
                std::printf("  world bounds: min (%.9g, %.9g, %.9g) max (%.9g, %.9g, %.9g)\n", info.world_min[0],
                            info.world_min[1], info.world_min[2], info.world_max[0], info.world_max[1],
                            info.world_max[2]);
            std::printf("  load time %.2f ms\n", ms);
        } catch (const cb::LoadError& e) {
            std::fprintf(stderr, "%s\n", e.what());
            if (json) all.push_back({{"file", file}, {"error", e.what()}});
            status = exit_bad_input;
        }
    }
    if (json) std::cout << all.dump(2) << "\n";
    return status;
}

double seconds_since(std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

struct ClusterArgs {
    std::string file, out, method = "kmeans";
    cb::ClusterOptions options;
    bool json = false, quiet = false;
    bool fit = false;  // bake: fit bounds too
    std::string bounds = "auto", obb = "refined";
    double capsule_ratio = 2.0;
};

bool parse_obb(const std::string& text, cb::ObbMethod& out) {
    const std::pair<const char*, cb::ObbMethod> obb_methods[] = {{"refined", cb::ObbMethod::refined}, {"pca", cb::ObbMethod::pca},
                                                                 {"pca-area", cb::ObbMethod::pca_area}, {"cgal", cb::ObbMethod::cgal_optimal}};
    for (const auto& [name, m] : obb_methods)
        if (text == name) return out = m, true;
    std::fprintf(stderr, "clusterbake: --obb takes refined, pca, pca-area or cgal (got '%s')\n", text.c_str());
    return false;
}

// The clustering method and box fitter named on the command line (bake, cluster, stats); one-line errors.
bool parse_clustering(const ClusterArgs& a, cb::ClusterOptions& clustering, cb::BoundsOptions& bounds) {
    clustering = a.options;
    if (!cb::parse_method(a.method, clustering.method)) {
        std::fprintf(stderr, "clusterbake: unknown method '%s' (kmeans, vco, morton)\n", a.method.c_str());
        return false;
    }
    bounds.capsule_ratio = a.capsule_ratio;
    return parse_obb(a.obb, bounds.obb);
}

// `cluster` (geometry and hierarchy only) and `bake` (with bounds) share this.
int run_bake(const ClusterArgs& a) {
    cb::ClusterOptions options;
    cb::BoundsOptions bounds;
    if (!parse_clustering(a, options, bounds)) return 1;
    if (a.fit && !cb::parse_bounds_mask(a.bounds, bounds.mask)) {
        std::fprintf(stderr, "clusterbake: --bounds takes auto, all or a list of obb,sphere,capsule,cone,slab (got '%s')\n",
                     a.bounds.c_str());
        return 1;
    }
    auto t0 = std::chrono::steady_clock::now();
    cb::Scene scene;
    try {
        scene = cb::load_scene(a.file);
    } catch (const cb::LoadError& e) {
        std::fprintf(stderr, "%s\n", e.what());
        return exit_bad_input;
    }
    double load_s = seconds_since(t0);

    // Progress for long runs only, on stderr, overwritten in place.
    uint64_t total = 0;
    for (const cb::Mesh& m : scene.meshes) total += m.triangle_count();
    bool show = !a.quiet && total >= 1'000'000;
    cb::BakeStats stats;
    std::vector<cb::AssetMesh> meshes = cb::cluster_scene(scene, options, stats, [&](size_t m, size_t mc, size_t c, size_t cc) {
        if (show) std::fprintf(stderr, "\rclustering mesh %zu/%zu: chunk %zu/%zu   ", m + 1, mc, c, cc);
    });
    if (show) std::fprintf(stderr, "\n");
    if (a.fit) cb::fit_scene_bounds(meshes, bounds, options.threads, stats);

    auto t1 = std::chrono::steady_clock::now();
    std::vector<uint8_t> bytes = cb::encode_asset(meshes, scene.instances);
    cb::write_file_atomic(a.out, bytes);
    double write_s = seconds_since(t1);

    double tps = stats.cluster_seconds > 0 ? double(stats.triangles) / stats.cluster_seconds : 0;
    if (a.json) {
        nlohmann::json j = {{"file", a.file},
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
    std::printf("  load %.3f s, cluster %.3f s (%.2f M triangles/s), write %.3f s, asset %zu bytes (%.1f per triangle)\n",
                load_s, stats.cluster_seconds, tps / 1e6, write_s, bytes.size(),
                stats.triangles ? double(bytes.size()) / double(stats.triangles) : 0.0);
    return 0;
}

// An asset file read into 8-byte aligned storage (the view's instance doubles need it) and opened.
struct LoadedAsset {
    std::vector<uint64_t> storage;
    size_t size = 0;
    cb::AssetView view;
};

bool load_asset(const std::string& file, LoadedAsset& out) {
    std::ifstream in(file, std::ios::binary);
    if (!in) {
        std::fprintf(stderr, "%s: cannot open\n", file.c_str());
        return false;
    }
    std::vector<char> raw((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    out.size = raw.size();
    out.storage.assign((raw.size() + 7) / 8, 0);
    std::memcpy(out.storage.data(), raw.data(), raw.size());
    cb::AssetError e = cb::open_asset(out.storage.data(), out.size, &out.view);
    if (e != cb::AssetError::ok) {
        std::fprintf(stderr, "%s: %s\n", file.c_str(), cb::asset_error_text(e));
        return false;
    }
    return true;
}

int run_validate(const std::string& file) {
    LoadedAsset asset;
    if (!load_asset(file, asset)) return exit_bad_input;
    const cb::AssetView& view = asset.view;
    std::printf("%s: valid clusterbake asset v%u, %zu bytes\n", file.c_str(), cb::asset_version, asset.size);
    std::printf("  meshes %u, instances %u, vertices %u, triangles %u, fine clusters %u, coarse clusters %u\n",
                view.mesh_count, view.instance_count, view.vertex_count, view.triangle_count, view.fine_count,
                view.coarse_count);
    if (view.mesh_flags) {
        uint32_t closed = 0;
        for (uint32_t m = 0; m < view.mesh_count; ++m) closed += view.mesh_flags[m] & cb::mesh_closed ? 1 : 0;
        size_t sided = 0;
        for (size_t t = 0; t < view.triangle_count; ++t) sided += view.double_sided(t);
        std::printf("  closed meshes %u of %u (one-sided shadows equal two-sided ones outside them); double-sided triangles %zu\n",
                    closed, view.mesh_count, sided);
    }
    for (auto [name, level] : {std::pair{"fine", &view.fine_bounds}, std::pair{"coarse", &view.coarse_bounds}}) {
        std::string kinds;
        if (level->obbs) kinds += " obb";
        if (level->spheres) kinds += " sphere";
        if (level->capsules) kinds += " capsule";
        if (level->cones) kinds += " cone";
        if (level->slabs) kinds += " slab";
        std::printf("  %s bounds:%s\n", name, kinds.empty() ? " none" : kinds.c_str());
    }
    return 0;
}

// "X,Y,Z", three finite numbers; otherwise a one-line error and false.
bool parse_light(const std::string& text, double* light) {
    char extra;
    if (std::sscanf(text.c_str(), "%lf,%lf,%lf%c", &light[0], &light[1], &light[2], &extra) == 3 && std::isfinite(light[0]) &&
        std::isfinite(light[1]) && std::isfinite(light[2]))
        return true;
    std::fprintf(stderr, "clusterbake: --light takes X,Y,Z (got '%s')\n", text.c_str());
    return false;
}

struct QueryArgs {
    std::string asset, light, points, out, fine = "scan";
    bool binary = false, stats = false, reference = false, one_sided = false;
    unsigned threads = 1;
};

// Points from text lines "x y z" (blank lines and # comments skipped) or raw little-endian float32 triples.
bool read_points(const QueryArgs& a, std::vector<double>& pts) {
    std::ifstream in(a.points, std::ios::binary);
    if (!in) {
        std::fprintf(stderr, "%s: cannot open\n", a.points.c_str());
        return false;
    }
    if (a.binary) {
        std::vector<char> raw((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        if (raw.size() % 12 != 0) {
            std::fprintf(stderr, "%s: %zu bytes is not a whole number of float32 triples\n", a.points.c_str(), raw.size());
            return false;
        }
        for (size_t i = 0; i < raw.size(); i += 4) {
            float f;
            std::memcpy(&f, raw.data() + i, 4);
            pts.push_back(f);
        }
    } else {
        std::string line;
        for (size_t n = 1; std::getline(in, line); ++n) {
            size_t hash = line.find('#');
            if (hash != std::string::npos) line.resize(hash);
            if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
            double x, y, z;
            char extra;
            if (std::sscanf(line.c_str(), "%lf %lf %lf %c", &x, &y, &z, &extra) != 3) {
                std::fprintf(stderr, "%s: line %zu: expected 'x y z'\n", a.points.c_str(), n);
                return false;
            }
            pts.insert(pts.end(), {x, y, z});
        }
    }
    for (size_t i = 0; i < pts.size(); ++i)
        if (!std::isfinite(pts[i])) {
            std::fprintf(stderr, "%s: point %zu: coordinate is not finite\n", a.points.c_str(), i / 3);
            return false;
        }
    return true;
}

int run_query(const QueryArgs& a) {
    double light[3];
    if (!parse_light(a.light, light)) return 1;
    LoadedAsset asset;
    if (!load_asset(a.asset, asset)) return exit_bad_input;
    std::vector<double> pts;
    if (!read_points(a, pts)) return exit_bad_input;

    // One clustered shadow tree per instance for this light (unless --reference).
    auto build_start = std::chrono::steady_clock::now();
    std::vector<cb::ClusterShadowTree> trees(a.reference ? 0 : asset.view.instance_count);
    size_t nodes = 0, always = 0, skipped = 0;
    unsigned thread_count = a.threads ? a.threads : std::max(1u, std::thread::hardware_concurrency());
    using cb::Traversal;
    cb::ShadowBuildOptions options;
    options.traversal = a.fine == "trees" ? Traversal::trees : a.fine == "one-tree" ? Traversal::one_tree : Traversal::scan;
    options.one_sided = a.one_sided;
    options.threads = thread_count;
    // The scan's bounds, once per mesh however many instances it has.
    const std::vector<cb::ScanBounds> bounds = options.traversal == Traversal::scan && !trees.empty() ? cb::make_scan_bounds(asset.view)
                                                                                                     : std::vector<cb::ScanBounds>{};
    options.bounds = bounds.empty() ? nullptr : bounds.data();
    for (uint32_t i = 0; i < trees.size(); ++i) {
        trees[i].build(asset.view, i, light, options);
        skipped += trees[i].skipped_clusters();
        nodes += trees[i].node_count();
        always += trees[i].always_tested();
    }
    double build_seconds = seconds_since(build_start);

    // The trees are const: threads take contiguous slices of the points' order by direction from the light
    // (the order a batch takes them in, so that each slice's tiles are as close as one batch's), each with
    // its own scratch and counts; the reference takes slices of the points as given.
    auto start = std::chrono::steady_clock::now();
    size_t n = pts.size() / 3;
    std::vector<uint8_t> shadow(n);
    std::vector<cb::QueryStats> counts(thread_count);
    std::vector<uint32_t> order;
    if (!a.reference) {
        order.resize(n);
        std::vector<uint32_t> sort_scratch(cb::batch_order_scratch_size(n));
        cb::batch_order(light, pts.data(), n, order.data(), sort_scratch.data());
    }
    auto slice = [&](unsigned t) {
        size_t first = n * t / thread_count, last = n * (t + 1) / thread_count;
        if (a.reference) {
            for (size_t i = first; i < last; ++i)
                shadow[i] = cb::occluded_reference(asset.view, &pts[i * 3], light, a.one_sided, &counts[t]);
        } else {
            std::vector<uint32_t> own(cb::ordered_scratch_size(trees.data(), trees.size()));
            cb::occluded_ordered(trees.data(), trees.size(), pts.data(), order.data() + first, last - first, shadow.data(), own.data(),
                                 &counts[t]);
        }
    };
    std::vector<std::thread> pool;
    for (unsigned t = 1; t < thread_count; ++t) pool.emplace_back(slice, t);
    slice(0);
    for (std::thread& t : pool) t.join();
    cb::QueryStats stats;
    for (const cb::QueryStats& c : counts) {
        stats.nodes_visited += c.nodes_visited, stats.clusters_tested += c.clusters_tested;
        stats.triangles_tested += c.triangles_tested, stats.touching += c.touching;
    }
    double seconds = seconds_since(start);
    std::string answers;
    answers.reserve(n * 2);
    size_t shadowed = 0;
    for (uint8_t s : shadow) answers += s ? "1\n" : "0\n", shadowed += s;
    std::fwrite(answers.data(), 1, answers.size(), stdout);
    if (a.stats) {
        if (!a.reference)
            std::fprintf(stderr, "build %.3f s: %zu trees, %zu nodes, %zu clusters tested for every point (light inside or level "
                         "with their box), %zu skipped (one-sided, light in their front cone)\n",
                         build_seconds, trees.size(), nodes, always, skipped);
        std::fprintf(stderr, "%zu queries, %zu in shadow, %.3f s (%.0f queries/s); per query %.1f clusters and %.1f triangles "
                     "tested\n",
                     n, shadowed, seconds, n / std::max(seconds, 1e-9), n ? double(stats.clusters_tested) / double(n) : 0.0,
                     n ? double(stats.triangles_tested) / double(n) : 0.0);
        if (a.reference)
            std::fprintf(stderr, "%llu queries with a touching contact\n", (unsigned long long)stats.touching);
    }
    return 0;
}

std::vector<std::string> split_commas(const std::string& text) {
    std::vector<std::string> out;
    size_t start = 0;
    while (start <= text.size()) {
        size_t comma = text.find(',', start);
        if (comma == std::string::npos) comma = text.size();
        out.push_back(text.substr(start, comma - start));
        start = comma + 1;
    }
    return out;
}

struct ReportArgs {
    std::vector<std::string> files;
    std::string out, methods = "kmeans,vco,morton", fine = "8,16,24,32", obbs = "refined,pca";
    cb::ReportOptions options;
    bool quiet = false;
};

// Each comma-separated item of `text` through parse(item, value) into `out`; at the first bad item, a
// one-line error that starts with `what` and names it, and false.
template <class T, class Parse>
bool parse_list(const std::string& text, const char* what, Parse parse, std::vector<T>& out) {
    for (const std::string& item : split_commas(text)) {
        T value{};
        if (!parse(item, value)) {
            std::fprintf(stderr, "clusterbake: %s (got '%s')\n", what, item.c_str());
            return false;
        }
        out.push_back(value);
    }
    return true;
}

int run_report(ReportArgs a) {
    cb::ReportOptions& o = a.options;
    o.methods.clear(), o.fine_sizes.clear(), o.obbs.clear();
    auto fine_size = [](const std::string& f, uint32_t& v) {  // the asset's 8-bit local indices, as for bake
        char* end = nullptr;
        unsigned long n = std::strtoul(f.c_str(), &end, 10);
        v = uint32_t(n);
        return !f.empty() && !*end && n >= 1 && n <= 85;
    };
    if (!parse_list(a.methods, "--methods takes a list of kmeans, vco, morton", cb::parse_method, o.methods) ||
        !parse_list(a.fine, "--fine takes a list of sizes from 1 to 85", fine_size, o.fine_sizes) ||
        !parse_list(a.obbs, "--obb takes a list of refined, pca, pca-area, cgal", cb::parse_obb_method, o.obbs))
        return 1;
    if (o.runs < 1 || o.query_runs < 1 || o.view < 1 || o.frame_view < 1 || o.lights < 1) {
        std::fprintf(stderr, "clusterbake: --runs, --query-runs, --view, --frame-view and --lights must be at least 1\n");
        return 1;
    }
    cb::Report r;
    try {
        r = cb::run_report(a.files, o, [&](const std::string& msg) {
            if (!a.quiet) std::fprintf(stderr, "\r%-70s", msg.c_str());
        });
        if (!a.quiet) std::fprintf(stderr, "\n");
        cb::write_report(r, a.out);
    } catch (const std::runtime_error& e) {
        if (!a.quiet) std::fprintf(stderr, "\n");
        std::fprintf(stderr, "%s\n", e.what());
        return exit_bad_input;
    }
    std::fputs(cb::report_table(r).c_str(), stdout);
    std::printf("wrote %s/report.html, report.json, report.csv\n", a.out.c_str());
    return 0;
}

struct HeatmapArgs {
    std::string file, out, light, obb = "refined";
    cb::HeatmapOptions options;
};

int run_heatmap(HeatmapArgs a) {
    if (!a.light.empty()) {
        if (!parse_light(a.light, a.options.light)) return 1;
        a.options.has_light = true;
    }
    if (!parse_obb(a.obb, a.options.obb)) return 1;
    if (a.options.size < 8 || a.options.size > 4096) {
        std::fprintf(stderr, "clusterbake: --size takes 8 to 4096\n");
        return 1;
    }
    cb::Heatmap h;
    try {
        h = cb::render_heatmap(cb::load_scene(a.file), a.options);
        if (h.png.empty()) throw std::runtime_error(a.file + ": no triangles to draw");
        cb::write_file_atomic(a.out, h.png);
    } catch (const std::runtime_error& e) {
        std::fprintf(stderr, "%s\n", e.what());
        return exit_bad_input;
    }
    std::printf("%s -> %s (%ux%u)\n  %s\n", a.file.c_str(), a.out.c_str(), h.width, h.height, h.caption().c_str());
    return 0;
}

int run_stats(const ClusterArgs& a, cb::StatsOptions so) {
    cb::ClusterOptions clustering;
    cb::BoundsOptions bounds;
    if (!parse_clustering(a, clustering, bounds)) return 1;
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

int main(int argc, char** argv) {
    CLI::App app{"clusterbake: clusters triangle scenes, fits bounding volumes and bakes a compact asset"};
    app.require_subcommand(1);

    std::vector<std::string> info_files;
    bool info_json = false;
    CLI::App* info = app.add_subcommand("info", "Load scene files and print counts, bounds and load time");
    info->add_option("files", info_files, "Scene files (.gltf .glb .obj .ply .off .stl)")->required();
    info->add_flag("--json", info_json, "Print a JSON array, one object per file");

    ClusterArgs ca, ba;
    ba.fit = true;
    auto clustering_flags = [](CLI::App* c, ClusterArgs& a) {
        c->add_option("--method", a.method, "kmeans (default), vco or morton");
        c->add_option("--coarse", a.options.coarse_size, "Triangles per coarse cluster (default 2048)");
        // 85 triangles have at most 255 distinct corners: every cluster fits the asset's 8-bit local indices.
        c->add_option("--fine", a.options.fine_size, "Maximum triangles per fine cluster, 1 to 85 (default 16)")
            ->check(CLI::Range(1, 85));
        c->add_option("--threads", a.options.threads, "Worker threads, 0 = all (output is identical for any count)");
        c->add_option("--seed", a.options.seed, "Seed of k-means++ (default 1)");
        c->add_option("--k0", a.options.kmeans_branching, "k-means children per node (default 8)");
        c->add_option("--iterations", a.options.kmeans_max_iterations, "Cap on Lloyd iterations per node (default 16)");
        c->add_flag_callback("--coarse-morton", [&a] { a.options.kmeans_coarse_from_tree = false; },
                             "kmeans: Morton chunks as the coarse level instead of the top of the k-means trees");
        c->add_option("--presplit", a.options.kmeans_presplit,
                      "kmeans: triangles per Morton chunk the trees grow in, in parallel (default 65536; 0: one tree)");
        c->add_option("--cache", a.options.vco_cache_size, "vco: vertex cache size (default 32)");
    };
    auto clustering_options = [&](CLI::App* c, ClusterArgs& a) {
        c->add_option("file", a.file, "Scene file")->required();
        c->add_option("-o,--output", a.out, "Output asset (.cbk); written atomically")->required();
        clustering_flags(c, a);
        c->add_flag("--json", a.json, "Print the summary as JSON");
        c->add_flag("-q,--quiet", a.quiet, "No progress on stderr");
    };
    CLI::App* cluster = app.add_subcommand("cluster", "Cluster every mesh into coarse and fine clusters and write an asset (no bounds)");
    clustering_options(cluster, ca);
    CLI::App* bake = app.add_subcommand("bake", "Load, cluster, fit bounding volumes and write the asset");
    clustering_options(bake, ba);
    bake->add_option("--bounds", ba.bounds,
                     "auto (what the shadow runtime reads: obb,cone), all, or a list of obb,sphere,capsule,cone,slab");
    bake->add_option("--obb", ba.obb, "refined (default), pca, pca-area, or cgal (CGAL's optimum: slow)");
    bake->add_option("--capsule-ratio", ba.capsule_ratio, "Fit a capsule when the box's longest side is this many times each other (default 2)");

    ClusterArgs sa;
    cb::StatsOptions so;
    CLI::App* stats = app.add_subcommand(
        "stats", "Cluster-quality statistics per level (coarse, fine) of a scene baked in memory, or of an asset");
    stats->add_option("file", sa.file, "Scene file, or an asset (.cbk): its clusters and stored volumes as they are")->required();
    clustering_flags(stats, sa);
    stats->add_option("--obb", sa.obb, "refined (default), pca, pca-area, or cgal (CGAL's optimum: slow)");
    stats->add_option("--capsule-ratio", sa.capsule_ratio, "Fit a capsule when the box's longest side is this many times each other (default 2)");
    stats->add_option("--lights", so.lights, "Random light positions per mesh (default 8)");
    stats->add_option("--samples", so.samples, "Points sampled in each cluster's shadow volume per light (default 32)");
    stats->add_option("--light-seed", so.seed, "Seed of the lights and samples (default 1)");
    stats->add_option("--acmr-cache", so.acmr_cache, "FIFO cache size for the ACMR (default 32)");
    stats->add_flag("--json", sa.json, "Print the statistics as JSON");

    ReportArgs ra;
    CLI::App* report = app.add_subcommand(
        "report", "Sweep clustering method x fine size x box fitter: bake time, tightness and runtime cost; writes DIR/report.html, .json, .csv");
    report->add_option("files", ra.files, "Scene files")->required();
    report->add_option("-o,--output", ra.out, "Output folder (created)")->required();
    report->add_option("--methods", ra.methods, "Comma list of kmeans, vco, morton (default all three)");
    report->add_option("--fine", ra.fine, "Comma list of fine sizes (default 8,16,24,32)");
    report->add_option("--obb", ra.obbs, "Comma list of box fitters: refined, pca, pca-area, cgal (default refined,pca)");
    report->add_option("--coarse", ra.options.coarse_size, "Triangles per coarse cluster (default 2048)");
    report->add_option("--runs", ra.options.runs, "Bake timings are the median of this many runs (default 3)");
    report->add_option("--query-runs", ra.options.query_runs,
                       "Runtime timings are the median of this many rounds, each measuring every configuration once (default 7)");
    report->add_option("--view", ra.options.view, "Camera resolution; its visible points are the queries (default 128)");
    report->add_option("--frame-view", ra.options.frame_view,
                       "Frame time is for a view of this resolution: build + its visible points' queries (default 1024)");
    report->add_option("--lights", ra.options.lights, "Lights around each scene (default 2)");
    report->add_flag("--one-sided", ra.options.one_sided, "Query with one-sided occluders");
    report->add_option("--samples", ra.options.stats.samples, "Shadow-volume samples per cluster and light (default 8)");
    report->add_option("--sample-lights", ra.options.stats.lights, "Random lights for the shadow-volume samples (default 4)");
    report->add_option("--threads", ra.options.threads, "Bake threads, 0 = all (queries run on one thread)");
    report->add_flag("--heatmap", ra.options.heatmap, "Also draw each scene's heat map of useless cluster tests (k-means beside VCO)");
    report->add_option("--heatmap-size", ra.options.heatmap_size, "Heat map panel size in pixels (default 256)");
    report->add_flag("-q,--quiet", ra.quiet, "No progress on stderr");

    HeatmapArgs ha;
    CLI::App* heatmap = app.add_subcommand(
        "heatmap", "PNG heat map of useless cluster tests per pixel for a camera and a light: k-means (left) beside VCO (right)");
    heatmap->add_option("file", ha.file, "Scene file")->required();
    heatmap->add_option("-o,--output", ha.out, "Output PNG (written atomically)")->required();
    heatmap->add_option("--size", ha.options.size, "Panel size in pixels (default 256)");
    heatmap->add_option("--light", ha.light, "Light position X,Y,Z (default: above the scene, as the report's first light)");
    heatmap->add_option("--fine", ha.options.clustering.fine_size, "Maximum triangles per fine cluster, 1 to 85 (default 16)")
        ->check(CLI::Range(1, 85));
    heatmap->add_option("--coarse", ha.options.clustering.coarse_size, "Triangles per coarse cluster (default 2048)");
    heatmap->add_option("--obb", ha.obb, "refined (default), pca, pca-area, or cgal");
    heatmap->add_flag("--one-sided", ha.options.one_sided, "One-sided occluders");
    heatmap->add_option("--threads", ha.options.clustering.threads, "Worker threads, 0 = all");

    std::string validate_file;
    CLI::App* validate = app.add_subcommand("validate", "Check an asset's structure, ranges and checksum");
    validate->add_option("file", validate_file, "Asset file")->required();

    QueryArgs qa;
    CLI::App* query = app.add_subcommand(
        "query", "Answer point-light shadow queries (exact; two-sided occluders unless --one-sided): one 0/1 line per point on stdout");
    query->add_option("asset", qa.asset, "Asset (.cbk)")->required();
    query->add_option("--light", qa.light, "Light position X,Y,Z in world space")->required();
    query->add_option("--points", qa.points, "Points: text lines 'x y z', or float32 triples with --binary")->required();
    query->add_flag("--binary", qa.binary, "Points file holds raw little-endian float32 x, y, z triples");
    query->add_flag("--one-sided", qa.one_sided, "One-sided occluders: a triangle blocks only when the light is behind it "
                                                  "(double-sided glTF primitives stay two-sided)");
    query->add_flag("--stats", qa.stats, "Print build and query time and traversal counts on stderr");
    query->add_flag("--reference", qa.reference, "Use the reference traversal (every cluster box the segment may touch) "
                                                  "instead of the clustered shadow volumes; same answers");
    query->add_option("--threads", qa.threads, "Build and query threads, 0 = all (default 1); the answers do not depend on it");
    query->add_option("--fine", qa.fine, "How queries find the clusters: 'scan' (default: no per-light tree; the coarse clusters' "
                                         "spheres, then the entered ones' fine spheres), 'trees' (per light, a tree over the coarse "
                                         "clusters and one per coarse cluster over its fine clusters) or 'one-tree' (one tree over "
                                         "the fine clusters); same answers")
        ->check(CLI::IsMember({"scan", "trees", "one-tree"}));

    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e) == 0 ? 0 : 1;  // --help is a success; every bad option is exit code 1
    }

    try {
        if (*info) return run_info(info_files, info_json);
        if (*cluster) return run_bake(ca);
        if (*bake) return run_bake(ba);
        if (*validate) return run_validate(validate_file);
        if (*stats) return run_stats(sa, so);
        if (*report) return run_report(ra);
        if (*heatmap) return run_heatmap(ha);
        if (*query) return run_query(qa);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "clusterbake: %s\n", e.what());
        return 1;
    }
    return 0;
}
