// What makes the pictures readable, checked on their output: the bitmap font, the heat map's titles, light
// marker and numbered colour bar, and the SVG plots' log axes, ringed Pareto points, recommended point and
// labels that overlap nothing.
#include <array>
#include <gtest/gtest.h>
#include <png.h>

#include <cmath>
#include <cstdio>
#include <regex>
#include <set>

#include "bitmap_text.h"
#include "heatmap.h"
#include "load.h"
#include "plot_checks.h"
#include "svg_plot.h"

using cb::test::count_of;
using cb::test::expect_labels_clear;

namespace {

std::string data(const std::string& f) { return std::string(CB_SOURCE_DIR) + "/data/" + f; }

double luminance(cb::Colour c) { return 0.299 * c.r + 0.587 * c.g + 0.114 * c.b; }

// The image's pixels inside box (clipped), row by row.
std::vector<cb::Colour> crop(const cb::RgbImage& img, const cb::PixelBox& b) {
    std::vector<cb::Colour> out;
    for (int y = std::max(0, b.y); y < std::min<int>(int(img.height), b.y + b.h); ++y)
        for (int x = std::max(0, b.x); x < std::min<int>(int(img.width), b.x + b.w); ++x)
            out.push_back(img.get(uint32_t(x), uint32_t(y)));
    return out;
}

cb::RgbImage decode(const std::vector<uint8_t>& png, uint32_t width, uint32_t height) {
    png_image img{};
    img.version = PNG_IMAGE_VERSION;
    cb::RgbImage out;
    if (!png_image_begin_read_from_memory(&img, png.data(), png.size())) return out;
    img.format = PNG_FORMAT_RGB;
    out = cb::RgbImage(img.width, img.height, {});
    if (!png_image_finish_read(&img, nullptr, out.pixels.data(), 0, nullptr)) return {};
    EXPECT_EQ(out.width, width);
    EXPECT_EQ(out.height, height);
    return out;
}

}  // namespace

TEST(BitmapText, EveryGlyphIsDistinctAndSizedAsDocumented) {
    const std::string chars = "0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZ.,-:/()%+=<>?";
    std::vector<std::vector<uint8_t>> seen;
    for (char c : chars) {
        ASSERT_TRUE(cb::has_glyph(c)) << c;
        cb::RgbImage img(cb::glyph_columns, cb::glyph_rows, {255, 255, 255});
        cb::draw_text(img, 0, 0, std::string(1, c), 1, {0, 0, 0});
        for (size_t k = 0; k < seen.size(); ++k)
            EXPECT_NE(seen[k], img.pixels) << "glyph " << c << " looks like " << chars[k];
        seen.push_back(img.pixels);
        EXPECT_NE(img.pixels, std::vector<uint8_t>(img.pixels.size(), 255)) << "glyph " << c << " is blank";
    }
    EXPECT_TRUE(cb::has_glyph('k'));  // drawn as a capital
    EXPECT_FALSE(cb::has_glyph('#'));
    EXPECT_EQ(cb::text_width("", 2), 0);
    EXPECT_EQ(cb::text_width("AB", 1), 11);
    EXPECT_EQ(cb::text_width("AB", 3), 33);
    // Scaled text covers whole cells: at scale 2 every ink pixel of 'L' is a 2 x 2 block.
    cb::RgbImage big(10, 14, {255, 255, 255});
    cb::draw_text(big, 0, 0, "L", 2, {0, 0, 0});
    EXPECT_EQ(big.get(0, 0), (cb::Colour{0, 0, 0}));
    EXPECT_EQ(big.get(1, 13), (cb::Colour{0, 0, 0}));
    EXPECT_EQ(big.get(2, 0), (cb::Colour{255, 255, 255}));
    // Text past the image's edges is clipped, not written out of bounds.
    cb::RgbImage small(4, 4, {255, 255, 255});
    cb::draw_text_outlined(small, -3, 1, "HELLO", 2, {0, 0, 0}, {255, 0, 0});
    EXPECT_EQ(small.pixels.size(), 4u * 4 * 3);
}

// The default scene's heat map, small; with the light where the camera sees it, then out of view.
class HeatmapPicture : public ::testing::Test {
protected:
    static cb::Heatmap draw(bool light_in_view) {
        cb::Scene scene = cb::load_scene(data("default_scene.glb"));
        cb::HeatmapOptions o;
        o.size = 80;
        if (light_in_view) {  // above the middle of the ground, which the camera looks at
            o.has_light = true;
            o.light[0] = 0;
            o.light[1] = 6;
            o.light[2] = 0;
        }
        return cb::render_heatmap(scene, o);
    }
};

TEST_F(HeatmapPicture, PanelsAreTitledWithMethodAndMean) {
    cb::Heatmap h = draw(false);
    cb::RgbImage img = decode(h.png, h.width, h.height);
    ASSERT_EQ(img.width, h.width);
    const cb::HeatmapLayout& L = h.layout;
    const char* methods[2] = {"K-MEANS", "VCO"};
    for (int panel = 0; panel < 2; ++panel) {
        std::string title;
        for (const std::string& line : L.title_lines[panel]) title += line + " ";
        char mean[32];
        std::snprintf(mean, sizeof mean, "MEAN %.2f", h.mean_useless[panel]);
        EXPECT_EQ(title.find(methods[panel]), 0u) << title;
        EXPECT_NE(title.find(mean), std::string::npos) << title;
        // The title's pixels are exactly its lines in the font, ink on paper, above the panel.
        const cb::PixelBox& t = L.titles[panel];
        EXPECT_LE(t.y + t.h, L.panels[panel].y);
        cb::RgbImage expected(uint32_t(t.w), uint32_t(t.h), {255, 255, 255});
        for (size_t i = 0; i < L.title_lines[panel].size(); ++i)
            cb::draw_text(expected, 0, int(i) * (cb::glyph_rows + 2) * L.text_scale, L.title_lines[panel][i],
                          L.text_scale, {20, 20, 20});
        std::vector<cb::Colour> drawn = crop(img, t), wanted = crop(expected, {0, 0, t.w, t.h});
        EXPECT_EQ(drawn, wanted) << "panel " << panel << " title does not read " << title;
        std::set<std::tuple<int, int, int>> colours;
        for (cb::Colour c : drawn) colours.insert({c.r, c.g, c.b});
        EXPECT_EQ(colours.size(), 2u) << "a title is ink on paper";
    }
    EXPECT_NE(crop(img, L.titles[0]), crop(img, L.titles[1]));
}

TEST_F(HeatmapPicture, ColourBarRunsDarkToBrightAndIsNumbered) {
    cb::Heatmap h = draw(false);
    cb::RgbImage img = decode(h.png, h.width, h.height);
    ASSERT_EQ(img.width, h.width);
    const cb::PixelBox& bar = h.layout.colour_bar;
    ASSERT_GT(bar.w, 40);
    EXPECT_GT(bar.y, h.layout.panels[0].y + h.layout.panels[0].h);
    uint32_t mid = uint32_t(bar.y + bar.h / 2);
    double last = -1;
    for (int x = bar.x; x < bar.x + bar.w; ++x) {
        double l = luminance(img.get(uint32_t(x), mid));
        EXPECT_GE(l, last - 1e-9) << "the bar darkens at x " << x;
        last = l;
    }
    EXPECT_LT(luminance(img.get(uint32_t(bar.x), mid)), 20);
    EXPECT_GT(luminance(img.get(uint32_t(bar.x + bar.w - 1), mid)), 220);
    // Numbered from 0 to the scale's top, increasing, each number drawn under the bar.
    const std::vector<int>& ticks = h.layout.tick_values;
    ASSERT_GE(ticks.size(), 2u);
    EXPECT_EQ(ticks.front(), 0);
    EXPECT_EQ(ticks.back(), int(h.scale_max));
    EXPECT_TRUE(std::is_sorted(ticks.begin(), ticks.end()));
    const int s = h.layout.text_scale;
    for (int v : ticks) {
        int x = bar.x + int(std::lround(double(v) / h.scale_max * (bar.w - 1)));
        size_t ink = 0;
        for (cb::Colour c : crop(img, {x - 6 * s, bar.y + bar.h + 3 * s, 12 * s, cb::glyph_rows * s}))
            ink += luminance(c) < 100;
        EXPECT_GT(ink, 3u) << "no number under tick " << v;
    }
}

TEST_F(HeatmapPicture, LightIsMarkedInBothPanels) {
    for (bool in_view : {false, true}) {
        cb::Heatmap h = draw(in_view);
        cb::RgbImage img = decode(h.png, h.width, h.height);
        ASSERT_EQ(img.width, h.width);
        EXPECT_EQ(h.layout.light_in_view, in_view);
        for (int panel = 0; panel < 2; ++panel) {
            const cb::PixelBox& mark = h.layout.light_marks[panel];
            const cb::PixelBox& p = h.layout.panels[panel];
            EXPECT_GE(mark.x, p.x - 2);
            EXPECT_LE(mark.x + mark.w, p.x + p.w + 2);
            size_t cyan = 0;
            for (cb::Colour c : crop(img, mark)) cyan += c == cb::Colour{0, 230, 255};
            EXPECT_GT(cyan, 10u) << (in_view ? "disc" : "arrow") << " in panel " << panel;
        }
        // The panels mark the same place.
        EXPECT_EQ(h.layout.light_marks[1].x - h.layout.light_marks[0].x, h.layout.panels[1].x - h.layout.panels[0].x);
    }
}

// A sun's heat map counts the sun's own traversal: not the point light its vector would name as a position,
// and on this scene no more useless tests than a light 10 km out in its direction (whose pyramids from the
// light are wider than the sun's prisms); marked where its direction vanishes, labelled as a sun.
TEST(HeatmapSun, CountsTheSunsTraversalAndIsMarked) {
    cb::Scene scene = cb::load_scene(data("default_scene.glb"));
    for (const std::array<double, 3>& toward :
         {std::array<double, 3>{1, 0.15, 0.4}, std::array<double, 3>{-0.5, 0.3, -1}}) {
        cb::HeatmapOptions o;
        o.size = 80;
        o.has_light = o.sun = true;
        std::copy(toward.begin(), toward.end(), o.light);
        const cb::Heatmap sun = cb::render_heatmap(scene, o);
        o.sun = false;  // the same three numbers as a position
        const cb::Heatmap near = cb::render_heatmap(scene, o);
        for (int k = 0; k < 3; ++k) o.light[k] = 1e4 * toward[k];
        const cb::Heatmap far = cb::render_heatmap(scene, o);
        EXPECT_TRUE(sun.sun);
        EXPECT_FALSE(far.sun);
        for (int panel = 0; panel < 2; ++panel) {
            EXPECT_GT(sun.mean_useless[panel], 0.05);
            EXPECT_NE(sun.mean_useless[panel], near.mean_useless[panel]);
            EXPECT_LE(sun.mean_useless[panel], far.mean_useless[panel] + 0.01);
            const cb::RgbImage img = decode(sun.png, sun.width, sun.height);
            size_t cyan = 0;
            for (cb::Colour c : crop(img, sun.layout.light_marks[panel])) cyan += c == cb::Colour{0, 230, 255};
            EXPECT_GT(cyan, 10u) << "panel " << panel;
        }
        EXPECT_NE(sun.caption().find("sun toward"), std::string::npos) << sun.caption();
        EXPECT_NE(sun.caption().find("cyan: the sun"), std::string::npos) << sun.caption();
    }
}

TEST(SvgPlot, LogAxisWhereValuesSpanDecades) {
    cb::Plot wide{"bake", "bake time (ms)", "useless cluster tests per query", {}};
    for (double x : {1.0, 2.5, 14.0, 90.0, 400.0, 1400.0}) wide.points.push_back({x, 3 + x / 1000, "c", "8"});
    std::string svg = cb::svg_scatter(wide, {"kmeans"}, {});
    EXPECT_EQ(count_of(svg, "class=\"axis x-axis log\""), 1u);
    EXPECT_EQ(count_of(svg, "class=\"axis y-axis\""), 1u);
    EXPECT_NE(svg.find("bake time (ms) (log scale)"), std::string::npos);
    // Three decades: numbered at the powers of ten only, so the numbers do not crowd.
    std::vector<std::string> ticks;
    std::regex tick("class=\"tick\" x=\"[-0-9.]+\" y=\"[0-9.]+\" font-size=\"11\" text-anchor=\"middle\">([^<]*)<");
    for (auto it = std::sregex_iterator(svg.begin(), svg.end(), tick); it != std::sregex_iterator(); ++it)
        ticks.push_back((*it)[1]);
    EXPECT_EQ(ticks, (std::vector<std::string>{"1", "10", "100", "1000"}));

    cb::Plot narrow = wide;
    for (auto& p : narrow.points) p.x = 10 + p.x / 100;  // 10 to 24: linear
    std::string lin = cb::svg_scatter(narrow, {"kmeans"}, {});
    EXPECT_EQ(count_of(lin, "x-axis log"), 0u);
    EXPECT_EQ(lin.find("(log scale)"), std::string::npos);
    EXPECT_TRUE(cb::wants_log_axis({0.9, 1400}));
    EXPECT_FALSE(cb::wants_log_axis({0, 1400}));  // zero has no place on a log axis
    EXPECT_TRUE(cb::wants_log_axis({50, 900}));
    EXPECT_FALSE(cb::wants_log_axis({50, 450}));
}

TEST(SvgPlot, ParetoPointsKeepTheirColourAndTheRecommendedIsMarked) {
    cb::Plot plot{"frame", "frame ms", "useless cluster tests per query", {}};
    plot.points.push_back({1, 5, "vco/8/pca", "8", 1, true});  // on the front, hollow, method colour 1
    plot.points.push_back({2, 2, "kmeans/16/refined", "16", 0, false, true});
    plot.points.push_back({3, 6, "morton/32/refined", "32", 2});
    std::string svg = cb::svg_scatter(plot, {"kmeans", "vco", "morton"}, {"obb refined", "obb pca"});
    std::string legend_free = svg.substr(0, svg.find("<g class=\"legend\">"));
    size_t vco = legend_free.find("data-config=\"vco/8/pca\"");
    ASSERT_NE(vco, std::string::npos);
    std::string vco_group = legend_free.substr(vco, legend_free.find("</g>", vco) - vco);
    EXPECT_NE(vco_group.find("pareto-ring"), std::string::npos);
    EXPECT_NE(vco_group.find("stroke=\"#d62728\""), std::string::npos) << "a Pareto point lost its colour";
    EXPECT_EQ(count_of(legend_free, "class=\"point pareto recommended\""), 1u);
    EXPECT_EQ(count_of(legend_free, "class=\"recommended-ring\""), 1u);
    EXPECT_EQ(count_of(legend_free, "class=\"point\""), 1u);  // morton: beaten on both axes
    EXPECT_NE(legend_free.find(">16, recommended</text>"), std::string::npos);
    EXPECT_NE(svg.find(">recommended</text>"), std::string::npos) << "the legend names the gold ring";
    EXPECT_NE(svg.find("useless cluster tests per query"), std::string::npos);
    EXPECT_EQ(expect_labels_clear(svg), 3u);
}

TEST(SvgPlot, ShapesTellATraversalApartAndKeepLabelsClear) {
    cb::Plot plot{"frame", "frame ms", "useless", {}};
    for (int i = 0; i < 12; ++i) {  // four shapes, close together: the labels keep clear of every one
        cb::PlotPoint p{10 + 0.05 * i, 3 + 0.01 * (i % 5), "config " + std::to_string(i), std::to_string(8 * i), i % 3};
        p.shape = i % 4;
        plot.points.push_back(p);
    }
    std::string svg = cb::svg_scatter(plot, {"a", "b", "c"}, {}, {"traversal scan", "traversal mtsv"});
    std::string legend_free = svg.substr(0, svg.find("<g class=\"legend\">"));
    EXPECT_EQ(count_of(legend_free, "<path class=\"marker\""), 9u);  // squares, diamonds, triangles
    EXPECT_EQ(count_of(legend_free, "class=\"point"), 12u);
    EXPECT_NE(svg.find(">traversal mtsv</text>"), std::string::npos) << "the legend names the shapes";
    EXPECT_EQ(cb::test::circles_of(legend_free).size(), 12u + cb::pareto_front(plot.points).size());
    EXPECT_GE(expect_labels_clear(svg), 6u);
}

TEST(SvgPlot, CrowdedLabelsNeverOverlap) {
    cb::Plot plot{"crowd", "x", "y", {}};
    // A tight clump, exact duplicates and a spread-out tail: the labels that fit are placed, apart.
    for (int i = 0; i < 24; ++i) {
        double x = i < 8 ? 10 + 0.01 * i : i < 12 ? 10.5 : 10 + i * 0.3, y = i < 12 ? 3 + 0.002 * i : 3 + (i % 5);
        std::string name = "config ";
        name += std::to_string(i);
        plot.points.push_back({x, y, name, std::to_string(8 * (1 + i % 4)), i % 3, i % 2 == 1});
    }
    plot.points[5].recommended = true;
    std::string svg = cb::svg_scatter(plot, {"a", "b", "c"}, {"s", "t"});
    size_t placed = expect_labels_clear(svg);
    EXPECT_GE(placed, 14u);
    EXPECT_LE(placed, 24u);
    EXPECT_NE(svg.find(", recommended</text>"), std::string::npos) << "the recommended point is labelled first";
    EXPECT_EQ(cb::svg_scatter(plot, {"a", "b", "c"}, {"s", "t"}), svg) << "placement is deterministic";
}
