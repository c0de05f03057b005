// The report (three files, one point per configuration, recommendation), the PNG writer and the heat map,
// and report.html as a browser renders it: headless Chromium with no network, a screenshot that is not
// blank, and a DOM whose plots have axes, labels and one point per configuration.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <filesystem>
#include <regex>
#include <sstream>

#include "png_writer.h"
#include "report.h"
#include "stats_helpers.h"

namespace fs = std::filesystem;
using namespace cb::test;

namespace {

std::string data(const std::string& f) { return std::string(CB_SOURCE_DIR) + "/data/" + f; }

size_t count_of(const std::string& text, const std::string& what) {
    size_t n = 0;
    for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + what.size())) ++n;
    return n;
}

// One report for every test here: the default scene (12 instances), 2 methods x 2 sizes x 2 box fitters =
// 8 configurations, with its heat map. ctest makes it once (the stats_report fixture in CMakeLists.txt);
// run alone, the first test that needs it makes it.
constexpr size_t configs = 8;
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

void expect_plots_complete(const std::string& page, size_t scenes) {
    std::vector<std::string> plots = plots_of(page);
    ASSERT_EQ(plots.size(), 2 * scenes);
    for (const std::string& p : plots) {
        EXPECT_EQ(count_of(p, "class=\"axis x-axis\""), 1u);
        EXPECT_EQ(count_of(p, "class=\"axis y-axis\""), 1u);
        EXPECT_EQ(count_of(p, "class=\"axis-label\""), 2u);
        EXPECT_GE(count_of(p, "class=\"tick\""), 4u);
        EXPECT_EQ(count_of(p, "class=\"point"), configs);  // "point" and "point pareto"
        EXPECT_GE(count_of(p, "class=\"point pareto\""), 1u);
        EXPECT_EQ(count_of(p, "class=\"pareto-front\""), 1u);
        EXPECT_NE(p.find("useless cluster tests per query"), std::string::npos);
    }
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
    std::string csv = slurp((d / "report.csv").string());
    EXPECT_EQ(count_of(csv, "\n"), configs + 1);
    EXPECT_EQ(count_of(csv, "default_scene,"), configs);
    std::string html = slurp((d / "report.html").string());
    expect_plots_complete(html, 1);
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
    o.runs = 1, o.query_runs = 2, o.view = 48;
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

TEST(Report, BadInputIsOneLineNamingTheFile) {
    fs::path out = fs::path(CB_TEST_OUTPUT) / "report_bad";
    CliRun r = run_cli("report " + (fs::path(CB_TEST_OUTPUT) / "missing.ply").string() + " -o " + out.string() + " -q");
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find("missing.ply"), std::string::npos) << r.err;
    EXPECT_EQ(count_of(r.err, "\n"), 1u) << r.err;
    EXPECT_EQ(run_cli("report " + data("small/cube.obj") + " -o " + out.string() + " --fine 0 -q").code, 2);
    EXPECT_EQ(run_cli("report " + data("small/cube.obj") + " -o " + out.string() + " --obb box -q").code, 2);
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
    // The report embedded the same kind of picture for its scene.
    EXPECT_GT(read_png((report_dir() / "heatmap-default_scene.png").string()).width, 2 * 96u);
}

// The browser test. Skips only when Chromium is not installed (scripts/install-deps.sh installs it).
TEST(ReportBrowser, RendersWithoutNetwork) {
    std::string chromium;
    for (const char* name : {"chromium", "chromium-browser"}) {
        std::istringstream path(std::getenv("PATH") ? std::getenv("PATH") : "");
        for (std::string dir; std::getline(path, dir, ':') && chromium.empty();)
            if (fs::exists(fs::path(dir) / name)) chromium = (fs::path(dir) / name).string();
    }
    if (chromium.empty())
        GTEST_SKIP() << "chromium is not installed (scripts/install-deps.sh installs it): browser test skipped";
    const fs::path& d = report_dir();
    fs::path shot = d / "screenshot.png", dom = d / "dom.html", profile = d / "chromium-profile";
    fs::remove(shot);
    // No network: every host name resolves to nothing and every request would go to a proxy that is not there.
    std::string flags =
        "--headless --no-sandbox --disable-gpu --no-first-run --disable-extensions --disable-sync "
        "--disable-background-networking --disable-component-update --disable-default-apps "
        "--host-resolver-rules=\"MAP * ~NOTFOUND\" --proxy-server=127.0.0.1:9 --user-data-dir=" +
        profile.string() + " ";
    std::string url = "file://" + fs::absolute(d / "report.html").string();
    CliRun s = run_program("timeout 120 " + chromium,
                           flags + "--window-size=1280,1600 --screenshot=" + shot.string() + " " + url);
    ASSERT_EQ(s.code, 0) << s.err;
    Rgb img = read_png(shot.string());
    ASSERT_EQ(img.width, 1280u) << "screenshot did not decode";
    EXPECT_GT(grey_variance(img), 200.0) << "the screenshot is blank";
    size_t coloured = 0;  // plot markers and heat map pixels: clearly not grey
    for (size_t i = 0; i < size_t(img.width) * img.height; ++i) {
        int r = img.pixels[i * 3], g = img.pixels[i * 3 + 1], b = img.pixels[i * 3 + 2];
        coloured += std::max({r, g, b}) - std::min({r, g, b}) > 60;
    }
    EXPECT_GT(coloured, 2000u);
    CliRun d2 = run_program("timeout 120 " + chromium, flags + "--dump-dom " + url);
    ASSERT_EQ(d2.code, 0) << d2.err;
    std::ofstream(dom) << d2.out;
    expect_plots_complete(d2.out, 1);
    EXPECT_NE(d2.out.find("Recommended default"), std::string::npos);
}
