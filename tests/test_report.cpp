// The report (three files, one point per configuration, recommendation, no column of zeros), the PNG
// writer and the heat map, on the default scene and the shared city model; and report.html as a browser
// renders it: headless Chromium with no network, a screenshot that is not blank, kept in the build tree's
// test-artifacts folder for a person to look at, and a DOM whose plots have axes, labels and one point per
// configuration.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdlib>
#include <iostream>
#include <map>
#include <filesystem>
#include <regex>
#include <set>
#include <sstream>

#include "asset_file.h"
#include "baked_scene.h"
#include "first_hits.h"
#include "lights.h"
#include "plot_checks.h"
#include "png_writer.h"
#include "report.h"
#include "runtime_cost.h"
#include "scene_query.h"
#include "stats_helpers.h"
#include "svg_plot.h"

namespace fs = std::filesystem;
using namespace cb::test;

namespace {

std::string data(const std::string& f) { return std::string(CB_SOURCE_DIR) + "/data/" + f; }

// One report for every test here: the default scene (12 instances), 2 methods x 2 sizes x 2 box fitters x 2
// traversals = 16 configurations, with its heat map. ctest makes it once (the stats_report fixture in CMakeLists.txt);
// run alone, the first test that needs it makes it.
constexpr size_t configs = 16;  // CB_REPORT_OPTIONS: 2 methods x 2 fine sizes x 2 box fitters x 2 traversals
const fs::path& report_dir() {
    static fs::path dir = [] {
        fs::path d = fs::path(CB_TEST_OUTPUT) / "report";
        if (fs::exists(d / "report.json")) return d;
        CliRun r = run_cli("report " + data("default_scene.glb") + " -o " + d.string() + " " + CB_REPORT_OPTIONS);
        EXPECT_EQ(r.code, 0) << r.err;
        return d;
    }();
    return dir;
}

// Each <svg class="plot"> ... </svg> of a page.
std::vector<std::string> plots_of(const std::string& page) {
    std::vector<std::string> out;
    for (size_t at = page.find("<svg class=\"plot\""); at != std::string::npos;
         at = page.find("<svg class=\"plot\"", at + 1))
        out.push_back(page.substr(at, page.find("</svg>", at) - at));
    return out;
}

// Every plot of the page complete: axes (log where its values span decades), one point per configuration,
// the Pareto front ringed, the recommended configuration ringed in gold, labels that overlap nothing.
void expect_plots_complete(const std::string& page, size_t scenes, size_t points = configs) {
    std::vector<std::string> plots = plots_of(page);
    ASSERT_EQ(plots.size(), 2 * scenes);
    for (const std::string& p : plots) {
        EXPECT_EQ(count_of(p, "class=\"axis x-axis"), 1u);
        EXPECT_EQ(count_of(p, "class=\"axis y-axis"), 1u);
        EXPECT_EQ(count_of(p, "class=\"axis-label\""), 2u);
        EXPECT_GE(count_of(p, "class=\"tick\""), 3u);
        EXPECT_EQ(count_of(p, "class=\"point"), points);  // "point", "point pareto", "point pareto recommended"
        EXPECT_GE(count_of(p, "class=\"pareto-ring\""), 1u);
        EXPECT_EQ(count_of(p, "class=\"pareto-front\""), 1u);
        EXPECT_EQ(count_of(p, "class=\"recommended-ring\""), 1u);
        EXPECT_NE(p.find("useless cluster tests per query</text>"), std::string::npos);
        EXPECT_GE(expect_labels_clear(p), 1u);
    }
}

// Each plot's x values as the page's JSON has them, and whether the plot drew a log x axis: they agree.
void expect_log_axes_where_values_span_decades(const std::string& page, const nlohmann::json& report) {
    std::vector<std::string> plots = plots_of(page);
    ASSERT_EQ(plots.size(), 2 * report["scenes"].size());
    for (size_t i = 0; i < plots.size(); ++i) {
        std::vector<double> xs;
        for (const auto& c : report["scenes"][i / 2]["configs"])
            xs.push_back(1e3 * c[i % 2 ? "frame_seconds" : "bake_seconds"].get<double>());
        bool log = plots[i].find("class=\"axis x-axis log\"") != std::string::npos;
        EXPECT_EQ(log, cb::wants_log_axis(xs)) << "plot " << i;
        double lo = *std::min_element(xs.begin(), xs.end()), hi = *std::max_element(xs.begin(), xs.end());
        if (hi > 100 * lo) {
            EXPECT_TRUE(log) << "plot " << i << ": x from " << lo << " to " << hi;
        }
    }
}

// The <th> texts of a page's configuration tables.
std::vector<std::string> table_headers(const std::string& page) {
    std::vector<std::string> out;
    for (size_t at = page.find("<table class=\"configs\">"); at != std::string::npos;
         at = page.find("<table class=\"configs\">", at + 1)) {
        size_t row_end = page.find("</tr>", at);
        for (size_t th = page.find("<th>", at); th < row_end; th = page.find("<th>", th + 1))
            out.push_back(page.substr(th + 4, page.find("</th>", th) - th - 4));
    }
    return out;
}

// Where the checks a person would make leave their pictures: the build tree's test-artifacts folder.
fs::path artifact(const std::string& name) {
    fs::path dir = fs::path(CB_TEST_ARTIFACTS);
    fs::create_directories(dir);
    return dir / name;
}

// The shared city model's report (3dfier's test area: terrain, water, roads, buildings), made once for the
// tests that need it: three methods, two fine sizes, one box fitter, with its heat map. Empty when the shared
// data is absent. Made in a folder of its own and renamed into place, as tests may ask for it at once.
fs::path city_report() {
    static fs::path dir = [] {
        fs::path city = fs::path(CB_SHARED_DATA) / "hard/3dfier_testarea/testarea.obj";
        fs::path d = fs::path(CB_TEST_OUTPUT) / "report-city";
        if (!fs::exists(city)) return fs::path();
        if (fs::exists(d / "report.json")) return d;
        fs::path mine = d.string() + "." + std::to_string(getpid());
        CliRun r = run_cli("report " + city.string() + " -o " + mine.string() +
                           " --method kmeans,vco,morton --fine 8,32 --obb refined --runs 1 --query-runs 1 --view 64"
                           " --heatmap --heatmap-size 128 -q");
        EXPECT_EQ(r.code, 0) << r.err;
        std::error_code taken;
        fs::rename(mine, d, taken);  // another test made it first: use that one
        if (taken) fs::remove_all(mine);
        return d;
    }();
    return dir;
}

}  // namespace

TEST(Png, RoundTripsThroughLibpng) {
    const uint32_t w = 37, h = 11;
    std::vector<uint8_t> rgb(w * h * 3);
    for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = uint8_t(i * 7 + i / 5);
    std::vector<uint8_t> png = cb::encode_png_rgb(rgb.data(), w, h);
    fs::path file = fs::path(CB_TEST_OUTPUT) / "roundtrip.png";
    fs::create_directories(file.parent_path());
    std::ofstream(file, std::ios::binary).write(reinterpret_cast<const char*>(png.data()), std::streamsize(png.size()));
    Rgb back = read_png(file.string());
    ASSERT_EQ(back.width, w);
    ASSERT_EQ(back.height, h);
    EXPECT_EQ(back.pixels, rgb);
}

TEST(Report, WritesThreeFilesWithOnePointPerConfiguration) {
    const fs::path& d = report_dir();
    std::string printed = slurp((d / "printed.txt").string());
    if (!printed.empty()) {
        EXPECT_NE(printed.find("recommended default: "), std::string::npos) << printed;
    }
    for (const char* f : {"report.html", "report.json", "report.csv", "heatmap-default_scene.png"})
        EXPECT_TRUE(fs::exists(d / f)) << f;
    nlohmann::json j = nlohmann::json::parse(slurp((d / "report.json").string()));
    ASSERT_EQ(j["scenes"].size(), 1u);
    const auto& scene = j["scenes"][0];
    ASSERT_EQ(scene["configs"].size(), configs);
    EXPECT_GT(scene["points"].get<int>(), 500);
    std::set<std::string> names;
    for (const auto& c : scene["configs"]) {
        names.insert(c["name"].get<std::string>());
        EXPECT_GT(c["queries_per_second"].get<double>(), 0);
        EXPECT_GT(c["bake_seconds"].get<double>(), 0);
        EXPECT_GE(c["useless_per_query"].get<double>(), 0);
        EXPECT_LE(c["useless_per_query"].get<double>(), c["clusters_per_query"].get<double>());
        EXPECT_GT(c["fine_obb_volume_relative"].get<double>(), 0);
    }
    EXPECT_EQ(names.size(), configs);
    EXPECT_TRUE(names.count(j["recommended"].get<std::string>()));
    EXPECT_EQ(j["machine"]["cores"].get<unsigned>() > 0, true);
    EXPECT_EQ(j["tool"].get<std::string>().rfind("clusterbake ", 0), 0u);
    // The sweep CB_REPORT_OPTIONS asked for with bake's flag names: --method, --fine, --obb.
    EXPECT_EQ(j["options"]["methods"], nlohmann::json::array({"kmeans", "vco"}));
    EXPECT_EQ(j["options"]["fine_sizes"], nlohmann::json::array({8, 16}));
    // The default traversals: the scan and the metric tree, each configuration twice, with the same answers.
    EXPECT_EQ(j["options"]["traversals"], nlohmann::json::array({"scan", "mtsv-one"}));
    std::map<std::string, double> shadowed;
    for (const auto& c : scene["configs"]) {
        std::string name = c["name"].get<std::string>();
        const bool metric = c["traversal"] == "mtsv-one";
        EXPECT_EQ(metric, name.size() > 9 && name.substr(name.size() - 9) == "/mtsv-one") << name;
        if (metric) name.resize(name.size() - 9);
        auto [at, fresh] = shadowed.emplace(name, c["shadowed_share"].get<double>());
        if (!fresh) {
            EXPECT_EQ(at->second, c["shadowed_share"].get<double>()) << name;
        }
        if (metric) {
            EXPECT_GT(c["bytes_per_triangle"].get<double>(), 0);
        }
    }
    EXPECT_EQ(shadowed.size(), configs / 2);
    std::string csv = slurp((d / "report.csv").string());
    EXPECT_EQ(count_of(csv, "\n"), configs + 1);
    EXPECT_EQ(count_of(csv, "default_scene,"), configs);
    std::string html = slurp((d / "report.html").string());
    expect_plots_complete(html, 1);
    for (const std::string& p : plots_of(html)) {  // the metric tree's points are squares, the scan's circles
        const std::string points = p.substr(0, p.find("<g class=\"legend\">"));
        EXPECT_EQ(count_of(points, "<path class=\"marker\""), configs / 2);
        EXPECT_NE(p.find(">traversal scan</text>"), std::string::npos);
        EXPECT_NE(p.find(">traversal mtsv-one</text>"), std::string::npos);
    }
    // Self-contained: no scripts, nothing fetched (the SVG namespace is a name, never loaded).
    EXPECT_EQ(html.find("<script"), std::string::npos);
    EXPECT_EQ(std::regex_search(html, std::regex("(src|href)=\"(https?:)?//")), false);
    EXPECT_NE(html.find("src=\"data:image/png;base64,"), std::string::npos);
    EXPECT_NE(html.find(j["recommended"].get<std::string>()), std::string::npos);
}

TEST(Report, OverTheMemoryBudgetConfigurationsAreMeasuredOneAtATime) {
    cb::ReportOptions o;
    o.methods = {cb::ClusterMethod::kmeans, cb::ClusterMethod::vco};
    o.fine_sizes = {16};
    o.obbs = {cb::ObbMethod::pca};
    o.traversals = {cb::Traversal::scan};
    o.runs = 1;
    o.query_runs = 2;
    o.view = 48;
    cb::Report rounds = cb::run_report({data("default_scene.glb")}, o);
    o.memory_budget = 0;
    cb::Report alone = cb::run_report({data("default_scene.glb")}, o);
    ASSERT_EQ(alone.scenes.at(0).configs.size(), 2u);
    for (size_t i = 0; i < 2; ++i) {
        const cb::ConfigResult &a = rounds.scenes[0].configs[i], &b = alone.scenes[0].configs[i];
        EXPECT_GT(b.queries_per_second, 0);
        EXPECT_GT(b.frame_seconds, 0);
        // Traversal counts do not depend on timing: the same either way.
        EXPECT_EQ(a.clusters_per_query, b.clusters_per_query);
        EXPECT_EQ(a.useless_per_query, b.useless_per_query);
        EXPECT_EQ(a.triangles_per_query, b.triangles_per_query);
    }
}

TEST(Report, SunsCountAsTheirExactReferenceCounts) {
    // The runtime cost over suns, beside a light or alone: the sun's traversal on the camera's points, its
    // shadowed count that of the exact reference for each sun.
    cb::Scene scene = cb::load_scene(data("default_scene.glb"));
    cb::BoundsOptions bounds;
    bounds.mask = cb::bounds_auto;
    cb::BakedScene baked = cb::bake_in_memory(scene, {}, bounds);
    cb::LoadedAsset asset;
    ASSERT_EQ(cb::open_asset_copy(cb::encode_asset(baked.meshes, baked.instances), asset), cb::AssetError::ok);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (const cb::Instance& inst : scene.instances) {
        const cb::Mesh& m = scene.meshes[inst.mesh];
        for (size_t v = 0; v < m.vertex_count(); ++v) {
            auto p =
                cb::transform_point(inst.world, m.positions[v * 3], m.positions[v * 3 + 1], m.positions[v * 3 + 2]);
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], p[k]);
                hi[k] = std::max(hi[k], p[k]);
            }
        }
    }
    const std::vector<double> points = cb::hit_points(cb::first_hits(baked, cb::default_camera(lo, hi, 96, 96)));
    const size_t n = points.size() / 3;
    ASSERT_GT(n, 1000u);
    auto reference_count = [&](const double* light, bool sun) {
        cb::SceneQueryOptions o;
        o.reference = true;
        o.sun = sun;
        const std::vector<uint8_t> s = cb::query_scene(asset.view, light, points.data(), n, o).shadowed;
        return uint64_t(std::count(s.begin(), s.end(), uint8_t(1)));
    };
    const std::vector<double> suns = cb::report_suns(2), lights = cb::report_lights(lo, hi, 1);
    const uint64_t high = reference_count(&suns[0], true), low = reference_count(&suns[3], true);
    EXPECT_GT(high, 0u);
    EXPECT_GT(low, high);  // the low sun's shadows are longer
    const cb::RuntimeCost alone = cb::measure_runtime(asset.view, {}, suns, points, 1);
    EXPECT_EQ(alone.lights, 2u);
    EXPECT_EQ(alone.queries, 2 * n);
    EXPECT_EQ(alone.shadowed, high + low);
    const cb::RuntimeCost beside = cb::measure_runtime(asset.view, lights, suns, points, 1, true);
    cb::SceneQueryOptions one_sided;
    one_sided.reference = true;
    one_sided.one_sided = true;
    uint64_t expected = 0;
    for (const double* light : {&lights[0], &suns[0], &suns[3]}) {
        one_sided.sun = light != &lights[0];
        const std::vector<uint8_t> s = cb::query_scene(asset.view, light, points.data(), n, one_sided).shadowed;
        expected += uint64_t(std::count(s.begin(), s.end(), uint8_t(1)));
    }
    EXPECT_EQ(beside.lights, 3u);
    EXPECT_EQ(beside.shadowed, expected);

    // Through the command line: suns alone, and no light at all refused.
    fs::path out = fs::path(CB_TEST_OUTPUT) / "report_suns";
    const std::string quick =
        " --method kmeans --fine 16 --obb refined --traversal scan --runs 1 --query-runs 1 --view 24 -q --json";
    CliRun r = run_cli("report " + data("default_scene.glb") + " -o " + out.string() + quick + " --lights 0 --suns 2");
    ASSERT_EQ(r.code, 0) << r.err;
    nlohmann::json j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["options"]["suns"], 2);
    EXPECT_EQ(j["scenes"][0]["suns"].size(), 6u);
    EXPECT_EQ(j["scenes"][0]["lights"].size(), 0u);
    EXPECT_GT(j["scenes"][0]["configs"][0]["queries_per_second"].get<double>(), 0);
    EXPECT_GT(j["scenes"][0]["configs"][0]["shadowed_share"].get<double>(), 0);
    CliRun none = run_cli("report " + data("default_scene.glb") + " -o " + out.string() + quick + " --lights 0");
    EXPECT_EQ(none.code, 2);
    EXPECT_NE(none.err.find("nothing lights the queries"), std::string::npos) << none.err;
    fs::remove_all(out);
}

TEST(Report, BadInputIsOneLineNamingTheFile) {
    fs::path out = fs::path(CB_TEST_OUTPUT) / "report_bad";
    CliRun r = run_cli("report " + (fs::path(CB_TEST_OUTPUT) / "missing.ply").string() + " -o " + out.string() + " -q");
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find("missing.ply"), std::string::npos) << r.err;
    EXPECT_EQ(count_of(r.err, "\n"), 1u) << r.err;
    EXPECT_EQ(run_cli("report " + data("small/cube.obj") + " -o " + out.string() + " --fine 0 -q").code, 2);
    EXPECT_EQ(run_cli("report " + data("small/cube.obj") + " -o " + out.string() + " --obb box -q").code, 2);
}

TEST(Report, ColumnsOfZerosAreLeftOut) {
    cb::Report r;
    r.options.methods = {cb::ClusterMethod::kmeans, cb::ClusterMethod::vco};
    r.options.fine_sizes = {8};
    r.options.obbs = {cb::ObbMethod::refined};
    cb::SceneReport s;
    s.file = "made-up.glb";
    s.name = "made-up";
    s.triangles = 100;
    s.instances = 1;
    s.points = 50;
    s.lights = {0, 10, 0};
    for (int i = 0; i < 2; ++i) {
        cb::ConfigResult c;
        c.method = i ? cb::ClusterMethod::vco : cb::ClusterMethod::kmeans;
        c.fine_size = 8;
        c.obb = cb::ObbMethod::refined;
        c.fine_clusters = 12 + i;
        c.coarse_clusters = 1;
        c.bytes_per_triangle = 15;
        c.cluster_seconds = 0.002 * (i + 1);
        c.fit_seconds = 0.001;
        c.obb_volume_relative = 0.4;
        c.useless_share = 0.3;
        c.build_seconds = 0.001;
        c.queries_per_second = 2e6;
        c.nodes_per_query = 0;
        c.clusters_per_query = 4;
        c.useless_per_query = 3 - i;
        c.triangles_per_query = 40;
        c.shadowed_share = 0;
        c.frame_seconds = 0.01 * (2 - i);
        s.configs.push_back(c);
    }
    r.scenes.push_back(s);
    r.recommended = "vco/8/refined";
    auto has = [](const std::vector<std::string>& v, const std::string& x) {
        return std::find(v.begin(), v.end(), x) != v.end();
    };
    std::string html = cb::report_html(r);
    std::vector<std::string> headers = table_headers(html);
    EXPECT_FALSE(has(headers, "nodes / query"));  // the default traversal walks no tree
    EXPECT_FALSE(has(headers, "in shadow"));
    EXPECT_TRUE(has(headers, "clusters / query"));
    EXPECT_TRUE(has(headers, "frame ms"));
    EXPECT_NE(html.find("<p class=\"dropped-columns\">"), std::string::npos);
    EXPECT_NE(html.find("nodes / query (the default traversal"), std::string::npos);
    // Every row has as many cells as the header.
    size_t row = html.find("<tr class=\"recommended\">");
    ASSERT_NE(row, std::string::npos);
    std::string cells = html.substr(row, html.find("</tr>", row) - row);
    EXPECT_EQ(count_of(cells, "<td>"), headers.size());
    expect_plots_complete(html, 1, 2);

    // One non-zero figure keeps its column; the printed table follows the same rule.
    r.scenes[0].configs[1].nodes_per_query = 1.5;
    r.scenes[0].configs[0].useless_share = r.scenes[0].configs[1].useless_share = 0;
    headers = table_headers(cb::report_html(r));
    EXPECT_TRUE(has(headers, "nodes / query"));
    EXPECT_FALSE(has(headers, "useless share of shadow-volume samples"));
    std::string table = cb::report_table(r);
    EXPECT_EQ(table.find("useless volume share"), std::string::npos) << table;
    EXPECT_NE(table.find("| useless / query |"), std::string::npos) << table;
    EXPECT_NE(table.find("| vco/8/refined (recommended) |"), std::string::npos) << table;
}

TEST(Report, BakeTimesOverDecadesGetALogAxis) {
    cb::Report r;
    r.options.methods = {cb::ClusterMethod::kmeans, cb::ClusterMethod::morton};
    r.options.fine_sizes = {8, 32};
    r.options.obbs = {cb::ObbMethod::refined};
    cb::SceneReport s;
    s.file = "city.obj";
    s.name = "city";
    s.lights = {0, 10, 0};
    // As on the shared city model: morton bakes in about a millisecond, k-means in over a second.
    const double bake[4] = {1.4, 0.6, 0.0011, 0.0009}, frame[4] = {0.02, 0.025, 0.03, 0.028};
    for (int i = 0; i < 4; ++i) {
        cb::ConfigResult c;
        c.method = i < 2 ? cb::ClusterMethod::kmeans : cb::ClusterMethod::morton;
        c.fine_size = i % 2 ? 32 : 8;
        c.obb = cb::ObbMethod::refined;
        c.cluster_seconds = bake[i];
        c.frame_seconds = frame[i];
        c.useless_per_query = 2 + i;
        c.clusters_per_query = 8;
        c.queries_per_second = 1e6;
        s.configs.push_back(c);
    }
    r.scenes.push_back(s);
    r.recommended = "kmeans/8/refined";
    std::string html = cb::report_html(r);
    std::vector<std::string> plots = plots_of(html);
    ASSERT_EQ(plots.size(), 2u);
    EXPECT_NE(plots[0].find("class=\"axis x-axis log\""), std::string::npos) << "bake times 0.9 to 1400 ms";
    EXPECT_EQ(plots[1].find("x-axis log"), std::string::npos) << "frame times 20 to 30 ms";
    expect_plots_complete(html, 1, 4);
    expect_log_axes_where_values_span_decades(html, cb::report_json(r));
}

TEST(Report, SharedCityModel) {
    fs::path d = city_report();
    if (d.empty()) GTEST_SKIP() << "../shared/data is absent: the city model's report is not checked";
    nlohmann::json j = nlohmann::json::parse(slurp((d / "report.json").string()));
    ASSERT_EQ(j["scenes"].size(), 1u);
    ASSERT_EQ(j["scenes"][0]["configs"].size(), 12u);  // 3 methods x 2 sizes x 1 fitter x 2 traversals
    std::string html = slurp((d / "report.html").string());
    expect_plots_complete(html, 1, 12);
    expect_log_axes_where_values_span_decades(html, j);
    bool any_nodes = false;
    for (const auto& c : j["scenes"][0]["configs"]) any_nodes = any_nodes || c["nodes_per_query"].get<double>() != 0;
    std::vector<std::string> headers = table_headers(html);
    EXPECT_EQ(std::find(headers.begin(), headers.end(), "nodes / query") != headers.end(), any_nodes);
    fs::path heatmap = artifact("heatmap-testarea.png");
    fs::copy_file(d / "heatmap-testarea.png", heatmap, fs::copy_options::overwrite_existing);
    std::cout << "heat map kept for a look: " << heatmap.string() << "\n";
    EXPECT_GT(read_png(heatmap.string()).width, 2 * 128u);
}

TEST(Heatmap, CommandWritesWhatItPrints) {
    fs::path out = fs::path(CB_TEST_OUTPUT) / "heatmap.png";
    CliRun r = run_cli("heatmap " + data("default_scene.glb") + " -o " + out.string() + " --size 80 --json");
    ASSERT_EQ(r.code, 0) << r.err;
    nlohmann::json j = nlohmann::json::parse(r.out);
    Rgb img = read_png(out.string());
    EXPECT_EQ(img.width, j["width"].get<uint32_t>());
    EXPECT_EQ(img.height, j["height"].get<uint32_t>());
    EXPECT_GT(img.width, 2 * 80u);
    EXPECT_GT(img.height, 80u + 20);  // titles above, the numbered colour bar below
    EXPECT_GT(grey_variance(img), 100.0);
    CliRun text = run_cli("heatmap " + data("default_scene.glb") + " -o " + out.string() + " --size 80");
    EXPECT_NE(text.out.find("k-means (left)"), std::string::npos);
    EXPECT_NE(text.out.find("cyan: the light"), std::string::npos);
    // The report embedded the same kind of picture for its scene; a copy is kept for a person to look at.
    fs::path embedded = report_dir() / "heatmap-default_scene.png";
    EXPECT_GT(read_png(embedded.string()).width, 2 * 96u);
    fs::copy_file(embedded, artifact("heatmap-default_scene.png"), fs::copy_options::overwrite_existing);
    fs::copy_file(out, artifact("heatmap-default_scene-80.png"), fs::copy_options::overwrite_existing);
    std::cout << "heat maps kept for a look: " << artifact("heatmap-default_scene.png").string() << ", "
              << artifact("heatmap-default_scene-80.png").string() << "\n";
}

namespace {

std::string find_chromium() {
    for (const char* name : {"chromium", "chromium-browser"}) {
        std::istringstream path(std::getenv("PATH") ? std::getenv("PATH") : "");
        for (std::string dir; std::getline(path, dir, ':');)
            if (fs::exists(fs::path(dir) / name)) return (fs::path(dir) / name).string();
    }
    return "";
}

// Loads DIR/report.html in headless Chromium with no network: every host name resolves to nothing and
// every request would go to a proxy that is not there. Keeps a screenshot of the whole page in the
// test-artifacts folder as `shot_name` and names it on stdout; returns the page's DOM as rendered.
std::string render_report(const std::string& chromium, const fs::path& dir, const std::string& shot_name) {
    fs::path shot = artifact(shot_name), profile = dir / "chromium-profile";
    fs::remove(shot);
    std::string flags =
        "--headless --no-sandbox --disable-gpu --no-first-run --disable-extensions --disable-sync "
        "--disable-background-networking --disable-component-update --disable-default-apps "
        "--hide-scrollbars --host-resolver-rules=\"MAP * ~NOTFOUND\" --proxy-server=127.0.0.1:9 --user-data-dir=" +
        profile.string() + " ";
    std::string url = "file://" + fs::absolute(dir / "report.html").string();
    CliRun s = run_program("timeout 120 " + chromium,
                           flags + "--window-size=1280,2200 --screenshot=" + shot.string() + " " + url);
    EXPECT_EQ(s.code, 0) << s.err;
    std::cout << "screenshot kept for a look: " << shot.string() << "\n";
    Rgb img = read_png(shot.string());
    EXPECT_EQ(img.width, 1280u) << "screenshot did not decode";
    EXPECT_GT(grey_variance(img), 200.0) << "the screenshot is blank";
    size_t coloured = 0;  // plot markers and heat map pixels: clearly not grey
    for (size_t i = 0; i < size_t(img.width) * img.height; ++i) {
        int r = img.pixels[i * 3], g = img.pixels[i * 3 + 1], b = img.pixels[i * 3 + 2];
        coloured += std::max({r, g, b}) - std::min({r, g, b}) > 60;
    }
    EXPECT_GT(coloured, 2000u);
    CliRun dom = run_program("timeout 120 " + chromium, flags + "--dump-dom " + url);
    EXPECT_EQ(dom.code, 0) << dom.err;
    std::ofstream(dir / "dom.html") << dom.out;
    return dom.out;
}

}  // namespace

// The browser test. Skips only when Chromium is not installed (scripts/install-deps.sh installs it).
TEST(ReportBrowser, RendersWithoutNetwork) {
    std::string chromium = find_chromium();
    if (chromium.empty())
        GTEST_SKIP() << "chromium is not installed (scripts/install-deps.sh installs it): browser test skipped";
    std::string dom = render_report(chromium, report_dir(), "report-default_scene.png");
    expect_plots_complete(dom, 1);
    EXPECT_NE(dom.find("Recommended default"), std::string::npos);
}

TEST(ReportBrowser, SharedCityModel) {
    std::string chromium = find_chromium();
    if (chromium.empty())
        GTEST_SKIP() << "chromium is not installed (scripts/install-deps.sh installs it): browser test skipped";
    fs::path d = city_report();
    if (d.empty()) GTEST_SKIP() << "../shared/data is absent: the city model's report is not rendered";
    std::string dom = render_report(chromium, d, "report-testarea.png");
    expect_plots_complete(dom, 1, 12);
}
