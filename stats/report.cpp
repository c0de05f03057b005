#include "report.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>

#include "asset_file.h"
#include "asset_writer.h"
#include "bake.h"
#include "bake_file.h"
#include "baked_scene.h"
#include "camera.h"
#include "first_hits.h"
#include "heatmap.h"
#include "lights.h"
#include "load.h"
#include "runtime_cost.h"
#include "svg_plot.h"
#include "timing.h"
#include "world_box.h"

namespace cb {

std::string ConfigResult::name() const {
    return std::string(method_name(method)) + "/" + std::to_string(fine_size) + "/" + obb_method_name(obb) +
        (traversal == Traversal::scan ? "" : std::string("/") + traversal_name(traversal));
}

std::string cpu_model() {
    std::ifstream in("/proc/cpuinfo");
    std::string line;
    while (std::getline(in, line))
        if (line.rfind("model name", 0) == 0) {
            size_t colon = line.find(':');
            if (colon != std::string::npos) return line.substr(line.find_first_not_of(" \t", colon + 1));
        }
    return "unknown";
}

namespace {

double frame_of(const SceneReport&, const ConfigResult& c) { return c.frame_seconds; }

std::string scene_name(const std::string& file, const std::vector<SceneReport>& done) {
    std::string base = std::filesystem::path(file).stem().string(), name = base;
    for (int n = 2;; ++n) {
        bool taken = false;
        for (const SceneReport& s : done) taken |= s.name == name;
        if (!taken) return name;
        name = base + "-" + std::to_string(n);
    }
}

void recommend(Report& r) {
    if (r.scenes.empty() || r.scenes[0].configs.empty()) return;
    size_t n = r.scenes[0].configs.size();
    std::vector<double> score(n, 0), bake(n, 0), bytes(n, 0);
    for (const SceneReport& s : r.scenes) {
        double best = INFINITY;
        for (const ConfigResult& c : s.configs) best = std::min(best, frame_of(s, c));
        for (size_t i = 0; i < n; ++i) {
            score[i] += std::log(frame_of(s, s.configs[i]) / best) / double(r.scenes.size());
            bake[i] += s.configs[i].bake_seconds();
            bytes[i] += s.configs[i].bytes_per_triangle / double(r.scenes.size());
        }
    }
    size_t best = 0;
    for (size_t i = 1; i < n; ++i)
        if (score[i] < score[best]) best = i;
    // Frame times within 3% are a tie on a shared machine: the smaller asset wins, then the shorter bake.
    size_t pick = best;
    for (size_t i = 0; i < n; ++i)
        if (score[i] <= score[best] + std::log(1.03) &&
            (bytes[i] < bytes[pick] || (bytes[i] == bytes[pick] && bake[i] < bake[pick])))
            pick = i;
    size_t second = pick == 0 ? 1 : 0;  // the runner-up, to show how clear the choice is
    for (size_t i = 0; i < n; ++i)
        if (i != pick && score[i] < score[second]) second = i;
    std::string runner_up;
    if (n > 1) {
        char b[160];
        std::snprintf(b, sizeof b, "; next: %s at %.1f%%", r.scenes[0].configs[second].name().c_str(),
                      100 * (std::exp(score[second]) - 1));
        runner_up = b;
    }
    char buf[640];
    std::snprintf(buf, sizeof buf,
                  "lowest runtime cost: its frame time (per-light tree build plus one query per visible point of a "
                  "%ux%u view) is %.1f%% "
                  "above each scene's best, in geometric mean over %zu scene(s)%s%s; asset %.1f bytes per triangle; "
                  "bake time %.3f s in all",
                  r.options.frame_view, r.options.frame_view, 100 * (std::exp(score[pick]) - 1), r.scenes.size(),
                  pick != best ? " (within 3% of the fastest, with a smaller asset)" : "", runner_up.c_str(),
                  bytes[pick], bake[pick]);
    r.recommended = r.scenes[0].configs[pick].name();
    r.recommendation_reason = buf;
}

}  // namespace

Report run_report(const std::vector<std::string>& files, const ReportOptions& o,
                  const std::function<void(const std::string&)>& progress) {
    Report r;
    r.options = o;
    r.cpu = cpu_model();
    r.cores = std::thread::hardware_concurrency();
    for (const std::string& file : files) {
        Scene scene = load_scene(file, o.load);
        SceneReport s;
        s.file = file;
        s.name = scene_name(file, r.scenes);
        s.instances = scene.instances.size();
        for (const Instance& inst : scene.instances) s.triangles += scene.meshes[inst.mesh].triangle_count();
        double lo[3], hi[3];
        if (!world_box(scene, lo, hi)) throw std::runtime_error(file + ": no triangles to report on");
        s.lights = report_lights(lo, hi, o.lights);
        s.suns = report_suns(o.suns);
        // The query points: what the camera sees, found once (they do not depend on the clustering).
        ClusterOptions base;
        base.coarse_size = o.coarse_size;
        BoundsOptions auto_bounds;
        auto_bounds.mask = bounds_auto;
        std::vector<double> points =
            hit_points(first_hits(bake_in_memory(scene, base, auto_bounds, nullptr, {}, o.threads),
                                  default_camera(lo, hi, o.view, o.view), o.threads));
        s.points = points.size() / 3;

        size_t total = o.methods.size() * o.fine_sizes.size() * o.obbs.size() * o.traversals.size(), done = 0;
        // Runtime cost in rounds, every configuration once per round, so that a burst of load on a shared
        // machine hits them all alike; medians over the rounds. The counts are the same every round. That
        // needs every configuration's asset at once: past a memory budget, each is measured alone instead.
        std::vector<LoadedAsset> assets;
        std::vector<std::vector<double>> build_t(total), query_t(total);
        bool interleave = true;
        auto measure_round = [&](size_t i, const AssetView& view) {
            RuntimeCost cost = measure_runtime(view, s.lights, s.suns, points, 1, o.one_sided, s.configs[i].traversal);
            build_t[i].push_back(cost.build_seconds), query_t[i].push_back(cost.query_seconds);
            if (build_t[i].size() > 1) return;
            ConfigResult& c = s.configs[i];
            double q = double(std::max<uint64_t>(1, cost.queries));
            c.nodes_per_query = double(cost.stats.nodes_visited) / q;
            c.clusters_per_query = double(cost.stats.clusters_tested) / q;
            c.triangles_per_query = double(cost.stats.triangles_tested) / q;
            c.useless_per_query = cost.useless_per_query();
            c.shadowed_share = double(cost.shadowed) / q;
        };
        for (ClusterMethod method : o.methods)
            for (uint32_t fine : o.fine_sizes)
                for (ObbMethod obb : o.obbs) {
                    ConfigResult c;
                    c.method = method;
                    c.fine_size = fine;
                    c.obb = obb;
                    ClusterOptions co = base;
                    co.method = method;
                    co.fine_size = fine;
                    std::vector<double> cluster_t;
                    BakedScene baked;
                    baked.instances = scene.instances;
                    for (int run = 0; run < std::max(1, o.runs); ++run) {
                        BakeStats bs;
                        auto t0 = std::chrono::steady_clock::now();
                        baked.meshes = cluster_scene(scene, co, bs, {}, o.threads);
                        cluster_t.push_back(seconds_since(t0));
                    }
                    c.cluster_seconds = median(cluster_t);
                    // Each traversal: the bounds it reads fitted onto the same clusters (timed), its asset, and its
                    // runtime cost; the tightness figures are those of the boxes, the same for every traversal.
                    bool measured = false;
                    for (Traversal traversal : o.traversals) {
                        c.traversal = traversal;
                        if (progress)
                            progress(s.name + ": " + c.name() + " (" + std::to_string(++done) + "/" +
                                     std::to_string(total) + ")");
                        const bool metric = traversal == Traversal::mtsv_one || traversal == Traversal::mtsv_two;
                        BoundsOptions bo = auto_bounds;
                        bo.obb = obb;
                        if (metric) bo.mask |= bounds_sphere | bounds_capsule | bounds_slab;
                        std::vector<double> fit_t;
                        for (int run = 0; run < std::max(1, o.runs); ++run) {
                            BakeStats bs;
                            auto t0 = std::chrono::steady_clock::now();
                            fit_scene_bounds(baked.meshes, bo, o.threads, bs);
                            fit_t.push_back(seconds_since(t0));
                        }
                        c.fit_seconds = median(fit_t);
                        if (!measured) {
                            StatsOptions so = o.stats;
                            so.threads = o.threads;
                            so.suns = 0;  // the tightness figure is the point lights' shadow volumes
                            SceneStats st = cluster_statistics(baked.meshes, baked.instances, so);
                            c.fine_clusters = st.fine.clusters;
                            c.coarse_clusters = st.coarse.clusters;
                            c.obb_volume_relative = st.fine.obb_volume_relative;
                            c.useless_share = st.fine.useless_share;
                            measured = true;
                        }
                        LoadedAsset asset;
                        open_asset_copy(encode_asset(baked.meshes, baked.instances), asset);
                        uint64_t stored = 0;
                        for (const AssetMesh& m : baked.meshes) stored += m.triangles.size() / 3;
                        c.bytes_per_triangle = stored ? double(asset.size) / double(stored) : 0;
                        s.configs.push_back(c);
                        if (s.configs.size() == 1) interleave = double(asset.size) * double(total) <= o.memory_budget;
                        if (interleave) {
                            assets.push_back(std::move(asset));
                        } else {
                            for (int round = 0; round < std::max(1, o.query_runs); ++round)
                                measure_round(s.configs.size() - 1, asset.view);
                        }
                    }
                }
        for (int round = 0; interleave && round < std::max(1, o.query_runs); ++round) {
            if (progress)
                progress(s.name + ": runtime round " + std::to_string(round + 1) + "/" + std::to_string(o.query_runs));
            for (size_t i = 0; i < s.configs.size(); ++i) measure_round(i, assets[i].view);
        }
        for (size_t i = 0; i < s.configs.size(); ++i) {
            ConfigResult& c = s.configs[i];
            double query = median(query_t[i]);
            c.build_seconds = median(build_t[i]);
            c.queries_per_second = query > 0 ? double(s.points) / query : 0;
            // The sample stands for a frame_view frame: the same view, (frame_view / view)^2 times the points.
            double scale = double(o.frame_view) / double(o.view);
            c.frame_seconds = c.build_seconds + query * scale * scale;
        }
        assets.clear();
        if (o.heatmap) {
            if (progress) progress(s.name + ": heat map");
            HeatmapOptions ho;
            ho.clustering = base;
            ho.size = o.heatmap_size;
            ho.has_light = !s.lights.empty();  // else the heat map's own default light
            if (ho.has_light) std::copy(s.lights.begin(), s.lights.begin() + 3, ho.light);
            ho.one_sided = o.one_sided;
            Heatmap h = render_heatmap(scene, ho);
            s.heatmap_png = h.png;
            s.heatmap_width = h.width;
            s.heatmap_height = h.height;
            s.heatmap_caption = h.caption();
        }
        r.scenes.push_back(std::move(s));
    }
    recommend(r);
    return r;
}

namespace {

std::string fixed(double v, int digits) {
    if (!std::isfinite(v)) return "n/a";
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", digits, v);
    return buf;
}

// A figure of the configuration tables: its header in report.html and in the printed Markdown table (empty:
// not in that table), the figure, its printed form, and why it may be zero for every configuration.
struct Column {
    std::string html_header, text_header;
    double (*value)(const ConfigResult&);
    double scale;
    int digits;
    const char* suffix;
    const char* why_zero;
    std::string text(const ConfigResult& c) const { return fixed(value(c) * scale, digits) + suffix; }
};

const std::vector<Column>& columns() {
    static const std::vector<Column> all = {
        {"fine clusters", "fine clusters", [](const ConfigResult& c) { return double(c.fine_clusters); }, 1, 0, "", ""},
        {"asset bytes / triangle", "bytes / triangle", [](const ConfigResult& c) { return c.bytes_per_triangle; }, 1, 1,
         "", ""},
        {"", "bake ms", [](const ConfigResult& c) { return c.bake_seconds(); }, 1e3, 1, "", ""},
        {"cluster ms", "", [](const ConfigResult& c) { return c.cluster_seconds; }, 1e3, 1, "", ""},
        {"fit ms", "", [](const ConfigResult& c) { return c.fit_seconds; }, 1e3, 1, "", ""},
        {"fine OBB volume / scene box", "fine OBB vol / scene",
         [](const ConfigResult& c) { return c.obb_volume_relative; }, 1, 4, "", ""},
        {"useless share of shadow-volume samples", "useless volume share",
         [](const ConfigResult& c) { return c.useless_share; }, 100, 1, "%", ""},
        {"tree build ms", "build ms", [](const ConfigResult& c) { return c.build_seconds; }, 1e3, 2, "", ""},
        {"M queries/s", "M queries/s", [](const ConfigResult& c) { return c.queries_per_second; }, 1e-6, 3, "", ""},
        {"nodes / query", "", [](const ConfigResult& c) { return c.nodes_per_query; }, 1, 1, "",
         "the default traversal scans the clusters without a tree"},
        {"clusters / query", "clusters / query", [](const ConfigResult& c) { return c.clusters_per_query; }, 1, 2, "",
         ""},
        {"useless / query", "useless / query", [](const ConfigResult& c) { return c.useless_per_query; }, 1, 2, "", ""},
        {"triangles / query", "triangles / query", [](const ConfigResult& c) { return c.triangles_per_query; }, 1, 1,
         "", ""},
        {"in shadow", "", [](const ConfigResult& c) { return c.shadowed_share; }, 100, 1, "%",
         "no query point is in shadow of the lights"},
        {"frame ms", "frame ms", [](const ConfigResult& c) { return c.frame_seconds; }, 1e3, 2, "", ""},
    };
    return all;
}

// The columns of one table (HTML or text) that have a non-zero figure for some configuration of the scene:
// a column of zeros tells nothing. `dropped` gets the others.
std::vector<const Column*> shown_columns(const SceneReport& s, bool html, std::vector<const Column*>* dropped) {
    std::vector<const Column*> shown;
    for (const Column& col : columns()) {
        if ((html ? col.html_header : col.text_header).empty()) continue;
        bool any = false;
        for (const ConfigResult& c : s.configs) any = any || col.value(c) != 0;
        if (any)
            shown.push_back(&col);
        else if (dropped)
            dropped->push_back(&col);
    }
    return shown;
}

std::string base64(const std::vector<uint8_t>& bytes) {
    static const char* table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    for (size_t i = 0; i < bytes.size(); i += 3) {
        uint32_t v = uint32_t(bytes[i]) << 16 | (i + 1 < bytes.size() ? uint32_t(bytes[i + 1]) << 8 : 0) |
            (i + 2 < bytes.size() ? bytes[i + 2] : 0);
        out += table[v >> 18 & 63];
        out += table[v >> 12 & 63];
        out += i + 1 < bytes.size() ? table[v >> 6 & 63] : '=';
        out += i + 2 < bytes.size() ? table[v & 63] : '=';
    }
    return out;
}

// Which configurations are on each Pareto front: bake time vs useless tests, frame time vs useless tests.
struct Fronts {
    std::vector<bool> bake, frame;
};

// One point per configuration: x its bake or frame time in ms, y its useless tests per query, coloured by
// method, hollow for the second box fitter onward, shaped by traversal, labelled with its fine size.
std::vector<PlotPoint> plot_points(const SceneReport& s, const ReportOptions& o, bool frame,
                                   const std::string& recommended = "") {
    std::vector<PlotPoint> pts;
    for (const ConfigResult& c : s.configs) {
        PlotPoint p;
        p.x = frame ? frame_of(s, c) * 1e3 : c.bake_seconds() * 1e3;
        p.y = c.useless_per_query;
        p.label = c.name();
        p.tag = std::to_string(c.fine_size);
        p.colour = int(std::find(o.methods.begin(), o.methods.end(), c.method) - o.methods.begin());
        p.hollow = std::find(o.obbs.begin(), o.obbs.end(), c.obb) != o.obbs.begin();
        p.shape = int(std::find(o.traversals.begin(), o.traversals.end(), c.traversal) - o.traversals.begin());
        p.recommended = c.name() == recommended;
        pts.push_back(p);
    }
    return pts;
}

Fronts fronts(const SceneReport& s, const ReportOptions& o) {
    Fronts f;
    f.bake.assign(s.configs.size(), false), f.frame.assign(s.configs.size(), false);
    for (size_t i : pareto_front(plot_points(s, o, false))) f.bake[i] = true;
    for (size_t i : pareto_front(plot_points(s, o, true))) f.frame[i] = true;
    return f;
}

std::string join_methods(const ReportOptions& o) {
    std::string m;
    for (ClusterMethod x : o.methods) m += (m.empty() ? "" : ",") + std::string(method_name(x));
    return m;
}
std::string join_fine(const ReportOptions& o) {
    std::string m;
    for (uint32_t x : o.fine_sizes) m += (m.empty() ? "" : ",") + std::to_string(x);
    return m;
}
std::string join_obbs(const ReportOptions& o) {
    std::string m;
    for (ObbMethod x : o.obbs) m += (m.empty() ? "" : ",") + std::string(obb_method_name(x));
    return m;
}

}  // namespace

std::string report_table(const Report& r) {
    std::string out;
    char buf[512];
    for (const SceneReport& s : r.scenes) {
        Fronts f = fronts(s, r.options);
        std::snprintf(buf, sizeof buf,
                      "%s: %llu triangles, %llu query points (%ux%u view; frame ms for %ux%u), %u light(s), "
                      "%u sun(s)\n\n",
                      s.file.c_str(), (unsigned long long)s.triangles, (unsigned long long)s.points, r.options.view,
                      r.options.view, r.options.frame_view, r.options.frame_view, r.options.lights, r.options.suns);
        out += buf;
        std::vector<const Column*> shown = shown_columns(s, false, nullptr);
        out += "| config |";
        for (const Column* col : shown) out += " " + col->text_header + " |";
        out += " Pareto |\n|---|";
        for (size_t k = 0; k <= shown.size(); ++k) out += "---|";
        out += "\n";
        for (size_t i = 0; i < s.configs.size(); ++i) {
            const ConfigResult& c = s.configs[i];
            std::string pareto = std::string(f.bake[i] ? "bake" : "") + (f.bake[i] && f.frame[i] ? "+" : "") +
                (f.frame[i] ? "frame" : "");
            out += "| " + c.name();
            if (c.name() == r.recommended) out += " (recommended)";
            out += " |";
            for (const Column* col : shown) out.append(" ").append(col->text(c)).append(" |");
            out.append(" ").append(pareto).append(" |\n");
        }
        out += "\n";
    }
    if (!r.recommended.empty()) out += "recommended default: " + r.recommended + " (" + r.recommendation_reason + ")\n";
    return out;
}

nlohmann::json report_json(const Report& r) {
    const ReportOptions& o = r.options;
    nlohmann::json j;
    j["tool"] = tool_version();
    j["machine"] = {{"cpu", r.cpu}, {"cores", r.cores}};
    j["options"] = {{"methods", nlohmann::json::array()},
                    {"fine_sizes", o.fine_sizes},
                    {"obbs", nlohmann::json::array()},
                    {"coarse_size", o.coarse_size},
                    {"runs", o.runs},
                    {"query_runs", o.query_runs},
                    {"view", o.view},
                    {"frame_view", o.frame_view},
                    {"lights", o.lights},
                    {"suns", o.suns},
                    {"one_sided", o.one_sided},
                    {"stats_lights", o.stats.lights},
                    {"stats_samples", o.stats.samples},
                    {"threads", o.threads}};
    for (ClusterMethod m : o.methods) j["options"]["methods"].push_back(method_name(m));
    for (ObbMethod m : o.obbs) j["options"]["obbs"].push_back(obb_method_name(m));
    for (Traversal t : o.traversals) j["options"]["traversals"].push_back(traversal_name(t));
    j["recommended"] = r.recommended;
    j["recommendation_reason"] = r.recommendation_reason;
    j["scenes"] = nlohmann::json::array();
    for (const SceneReport& s : r.scenes) {
        Fronts f = fronts(s, o);
        nlohmann::json js = {{"file", s.file},           {"name", s.name},
                             {"triangles", s.triangles}, {"instances", s.instances},
                             {"points", s.points},       {"lights", s.lights},
                             {"suns", s.suns},           {"configs", nlohmann::json::array()}};
        for (size_t i = 0; i < s.configs.size(); ++i) {
            const ConfigResult& c = s.configs[i];
            auto num = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
            js["configs"].push_back({{"name", c.name()},
                                     {"method", method_name(c.method)},
                                     {"fine_size", c.fine_size},
                                     {"obb", obb_method_name(c.obb)},
                                     {"traversal", traversal_name(c.traversal)},
                                     {"fine_clusters", c.fine_clusters},
                                     {"coarse_clusters", c.coarse_clusters},
                                     {"bytes_per_triangle", c.bytes_per_triangle},
                                     {"cluster_seconds", c.cluster_seconds},
                                     {"fit_seconds", c.fit_seconds},
                                     {"bake_seconds", c.bake_seconds()},
                                     {"fine_obb_volume_relative", num(c.obb_volume_relative)},
                                     {"useless_volume_share", num(c.useless_share)},
                                     {"build_seconds", c.build_seconds},
                                     {"queries_per_second", c.queries_per_second},
                                     {"nodes_per_query", c.nodes_per_query},
                                     {"clusters_per_query", c.clusters_per_query},
                                     {"useless_per_query", c.useless_per_query},
                                     {"triangles_per_query", c.triangles_per_query},
                                     {"shadowed_share", c.shadowed_share},
                                     {"frame_seconds", frame_of(s, c)},
                                     {"pareto_bake", bool(f.bake[i])},
                                     {"pareto_frame", bool(f.frame[i])}});
        }
        if (!s.heatmap_png.empty())
            js["heatmap"] = {{"file", "heatmap-" + s.name + ".png"}, {"caption", s.heatmap_caption}};
        j["scenes"].push_back(js);
    }
    return j;
}

namespace {

// RFC 4180: a field with a comma, quote or line break is quoted, its quotes doubled.
std::string csv_field(const std::string& s) {
    if (s.find_first_of(",\"\r\n") == std::string::npos) return s;
    std::string out = "\"";
    for (char c : s) out += c == '"' ? "\"\"" : std::string(1, c);
    return out + "\"";
}

}  // namespace

std::string report_csv(const Report& r) {
    std::string out =
        "scene,method,fine_size,obb,traversal,fine_clusters,coarse_clusters,bytes_per_triangle,cluster_seconds,fit_"
        "seconds,fine_"
        "obb_volume_relative,"
        "useless_volume_share,build_seconds,queries_per_second,nodes_per_query,clusters_per_query,useless_per_query,"
        "triangles_per_query,shadowed_share,frame_seconds,pareto_bake,pareto_frame\n";
    char buf[640];
    for (const SceneReport& s : r.scenes) {
        Fronts f = fronts(s, r.options);
        for (size_t i = 0; i < s.configs.size(); ++i) {
            const ConfigResult& c = s.configs[i];
            out += csv_field(s.name) + ",";
            std::snprintf(
                buf, sizeof buf,
                "%s,%u,%s,%s,%llu,%llu,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%d,%d\n",
                method_name(c.method), c.fine_size, obb_method_name(c.obb), traversal_name(c.traversal),
                (unsigned long long)c.fine_clusters, (unsigned long long)c.coarse_clusters, c.bytes_per_triangle,
                c.cluster_seconds, c.fit_seconds, c.obb_volume_relative, c.useless_share, c.build_seconds,
                c.queries_per_second, c.nodes_per_query, c.clusters_per_query, c.useless_per_query,
                c.triangles_per_query, c.shadowed_share, frame_of(s, c), int(f.bake[i]), int(f.frame[i]));
            out += buf;
        }
    }
    return out;
}

std::string report_html(const Report& r) {
    const ReportOptions& o = r.options;
    std::string h =
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>clusterbake "
        "report</title>\n<style>\n"
        "body{font-family:sans-serif;margin:24px;color:#222;max-width:1240px}\n"
        "table{border-collapse:collapse;font-size:13px;margin:8px 0 24px}\n"
        "th,td{border:1px solid #ccc;padding:3px 7px;text-align:right}\nth{background:#f0f0f0}\n"
        "td:first-child,th:first-child{text-align:left}\ntr.recommended td{background:#fff6d5;font-weight:bold}\n"
        ".plots{display:flex;flex-wrap:wrap;gap:16px}\n.plot{border:1px solid #ddd}\n"
        "figure{margin:8px 0}\nfigcaption{font-size:13px;color:#444;max-width:900px}\n"
        ".heatmap img{image-rendering:pixelated}\n"
        "</style>\n</head>\n<body>\n<h1>clusterbake: speed against error</h1>\n";
    h += "<p>Each configuration (clustering method / fine size / box fitter) is baked in memory, timed (median of " +
        std::to_string(o.runs) +
        " runs), and its shadow trees (runtime, <code>cb::InstanceShadow</code>) built and queried for every "
        "camera-visible "
        "point. <b>Useless cluster tests</b> per query are tests of a cluster whose triangles did not block the "
        "point's "
        "segment to the light: the cost of loose volumes. <b>Frame</b> time is one light's tree build plus one query "
        "per visible point of a " +
        std::to_string(o.frame_view) + " x " + std::to_string(o.frame_view) +
        " view (the sample's query time scaled by the pixel count), "
        "on one thread; runtime timings are the median of " +
        std::to_string(o.query_runs) +
        " rounds that each measure every configuration once. "
        "Lower is better on every axis. In the plots, the dashed line joins the Pareto front (the configurations "
        "no other beats on both axes), whose points are ringed; the gold ring marks the recommended default; an "
        "axis whose values span more than a decade is logarithmic.</p>\n";
    if (!r.recommended.empty())
        h += "<p class=\"recommendation\"><b>Recommended default: " + html_escape(r.recommended) + "</b> &mdash; " +
            html_escape(r.recommendation_reason) + ".</p>\n";
    h += "<h2>Machine and options</h2>\n<table class=\"machine\">\n";
    auto row = [&](const std::string& k, const std::string& v) {
        h += "<tr><th>" + html_escape(k) + "</th><td>" + html_escape(v) + "</td></tr>\n";
    };
    row("CPU", r.cpu);
    row("cores (hardware threads)", std::to_string(r.cores));
    row("methods", join_methods(o));
    row("fine sizes", join_fine(o));
    row("box fitters", join_obbs(o));
    row("coarse size", std::to_string(o.coarse_size));
    row("bake runs (median)", std::to_string(o.runs));
    row("runtime rounds (median)", std::to_string(o.query_runs));
    row("view (query points)", std::to_string(o.view) + " x " + std::to_string(o.view));
    row("frame time for a view of", std::to_string(o.frame_view) + " x " + std::to_string(o.frame_view));
    row("lights", std::to_string(o.lights));
    row("suns", std::to_string(o.suns));
    row("occluders", o.one_sided ? "one-sided" : "two-sided");
    row("shadow-volume samples",
        std::to_string(o.stats.lights) + " lights x " + std::to_string(o.stats.samples) + " points per cluster");
    row("bake threads", o.threads ? std::to_string(o.threads) : "all");
    h += "</table>\n";
    std::vector<std::string> colours, styles;
    for (ClusterMethod m : o.methods) colours.push_back(method_name(m));
    for (ObbMethod m : o.obbs) styles.push_back(std::string("obb ") + obb_method_name(m));
    std::vector<std::string> shapes;  // one traversal needs no legend entry
    if (o.traversals.size() > 1)
        for (Traversal t : o.traversals) shapes.push_back(std::string("traversal ") + traversal_name(t));
    for (const SceneReport& s : r.scenes) {
        Fronts f = fronts(s, o);
        h += "<section class=\"scene\" data-scene=\"" + html_escape(s.name) + "\">\n<h2>" + html_escape(s.name) +
            "</h2>\n";
        h += "<p>" + html_escape(s.file) + ": " + std::to_string(s.triangles) + " triangles in the scene, " +
            std::to_string(s.instances) + " instance(s), " + std::to_string(s.points) +
            " camera-visible query points, " + std::to_string(s.lights.size() / 3) + " light(s), " +
            std::to_string(s.suns.size() / 3) + " sun(s).</p>\n<div class=\"plots\">\n";
        Plot bake{s.name + ": bake time against error", "bake time per configuration (ms)",
                  "useless cluster tests per query", plot_points(s, o, false, r.recommended)};
        Plot frame{s.name + ": runtime cost against error",
                   "frame time: build + queries of a " + std::to_string(o.frame_view) + "x" +
                       std::to_string(o.frame_view) + " view, one light (ms)",
                   "useless cluster tests per query", plot_points(s, o, true, r.recommended)};
        h += svg_scatter(bake, colours, styles, shapes) + svg_scatter(frame, colours, styles, shapes) + "</div>\n";
        if (!s.heatmap_png.empty()) {
            // A small picture is shown at twice its size, its pixels kept square, so its labels read.
            uint32_t zoom = s.heatmap_width < 400 ? 2 : 1;
            h += "<figure class=\"heatmap\"><img alt=\"heat map of useless cluster tests\" width=\"" +
                std::to_string(zoom * s.heatmap_width) + "\" height=\"" + std::to_string(zoom * s.heatmap_height) +
                "\" src=\"data:image/png;base64," + base64(s.heatmap_png) + "\"><figcaption>" +
                html_escape(s.heatmap_caption) + "</figcaption></figure>\n";
        }
        std::vector<const Column*> dropped, shown = shown_columns(s, true, &dropped);
        h += "<table class=\"configs\">\n<tr><th>configuration</th>";
        for (const Column* col : shown) h += "<th>" + html_escape(col->html_header) + "</th>";
        h += "<th>Pareto</th></tr>\n";
        for (size_t i = 0; i < s.configs.size(); ++i) {
            const ConfigResult& c = s.configs[i];
            std::string pareto = std::string(f.bake[i] ? "bake " : "") + (f.frame[i] ? "frame" : "");
            h += std::string("<tr") + (c.name() == r.recommended ? " class=\"recommended\"" : "") + "><td>" +
                html_escape(c.name()) + "</td>";
            for (const Column* col : shown) h += "<td>" + col->text(c) + "</td>";
            h += "<td>" + pareto + "</td></tr>\n";
        }
        h += "</table>\n";
        if (!dropped.empty()) {
            h += "<p class=\"dropped-columns\">Not shown, as zero for every configuration:";
            for (size_t k = 0; k < dropped.size(); ++k)
                h += std::string(k ? ";" : "") + " " + html_escape(dropped[k]->html_header) +
                    (*dropped[k]->why_zero ? std::string(" (") + dropped[k]->why_zero + ")" : "");
            h += ".</p>\n";
        }
        h += "</section>\n";
    }
    h += "</body>\n</html>\n";
    return h;
}

void write_report(const Report& r, const std::string& dir) {
    std::filesystem::create_directories(dir);
    auto bytes = [](const std::string& s) { return std::vector<uint8_t>(s.begin(), s.end()); };
    std::filesystem::path d(dir);
    write_file_atomic((d / "report.html").string(), bytes(report_html(r)));
    write_file_atomic((d / "report.json").string(), bytes(report_json(r).dump(2) + "\n"));
    write_file_atomic((d / "report.csv").string(), bytes(report_csv(r)));
    for (const SceneReport& s : r.scenes)
        if (!s.heatmap_png.empty()) write_file_atomic((d / ("heatmap-" + s.name + ".png")).string(), s.heatmap_png);
}

}  // namespace cb
