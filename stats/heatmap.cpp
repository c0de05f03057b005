#include "heatmap.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <detail/cb_math.h>

#include "asset_file.h"
#include "baked_scene.h"
#include "bitmap_text.h"
#include "camera.h"
#include "first_hits.h"
#include "lights.h"
#include "png_writer.h"
#include "runtime_cost.h"
#include "world_box.h"

namespace cb {
namespace {

using math::dot3;

const Colour paper{255, 255, 255}, ink{20, 20, 20}, no_surface{128, 128, 128};
const Colour light_colour{0, 230, 255};  // cyan: in no part of the ramp, so the marker never blends in

// A dark-to-bright ramp (black, purple, red, orange, pale yellow): readable in grey print too.
Colour ramp(double t) {
    static const double stops[5][3] = {{0, 0, 4}, {87, 16, 110}, {188, 55, 84}, {249, 142, 9}, {252, 255, 164}};
    t = std::clamp(t, 0.0, 1.0) * 4;
    int i = std::min(3, int(t));
    double f = t - i;
    uint8_t c[3];
    for (int k = 0; k < 3; ++k) c[k] = uint8_t(std::lround(stops[i][k] + f * (stops[i + 1][k] - stops[i][k])));
    return {c[0], c[1], c[2]};
}

void disc(RgbImage& img, double cx, double cy, double r, Colour c) {
    for (int y = int(std::floor(cy - r)); y <= int(std::ceil(cy + r)); ++y)
        for (int x = int(std::floor(cx - r)); x <= int(std::ceil(cx + r)); ++x)
            if ((x + 0.5 - cx) * (x + 0.5 - cx) + (y + 0.5 - cy) * (y + 0.5 - cy) <= r * r) img.set(x, y, c);
}

void line(RgbImage& img, double x0, double y0, double x1, double y1, double thickness, Colour c) {
    int steps = int(std::ceil(std::max(std::fabs(x1 - x0), std::fabs(y1 - y0)))) + 1;
    for (int i = 0; i <= steps; ++i) {
        double t = double(i) / steps;
        disc(img, x0 + t * (x1 - x0), y0 + t * (y1 - y0), thickness / 2, c);
    }
}

// Where a world point appears in the camera's image: pixel coordinates (x right, y down) when it is in
// front of the eye; behind it, only the direction (x, y) from the image centre means anything.
struct Projection {
    double x = 0, y = 0;
    bool in_front = false;
};

Projection project(const Camera& cam, const double* p) {
    double e[3] = {p[0] - cam.eye[0], p[1] - cam.eye[1], p[2] - cam.eye[2]};
    double depth = dot3(e, cam.forward), right = dot3(e, cam.right), up = dot3(e, cam.up);
    if (depth <= 0) return {right, -up, false};
    double aspect = double(cam.width) / double(std::max(1u, cam.height));
    double sx = right / (depth * cam.half_extent) / aspect, sy = up / (depth * cam.half_extent);
    return {(sx + 1) / 2 * cam.width, (1 - sy) / 2 * cam.height, true};
}

// The light in a panel at (ox, oy), n pixels square: a cyan disc where it appears, or, out of view, a cyan
// arrow at the panel's edge pointing its way; `label` ("LIGHT" or "SUN") beside either, on the panel's side.
// Returns the marker's box.
PixelBox mark_light(RgbImage& img, int ox, int oy, int n, const Projection& p, int s, const std::string& label) {
    double c = n / 2.0, lx, ly;  // the label's anchor, inside the panel
    PixelBox box;
    if (p.in_front && p.x >= 0 && p.x < n && p.y >= 0 && p.y < n) {
        double r = 3 * s + 1;
        disc(img, ox + p.x, oy + p.y, r + 1, ink);
        disc(img, ox + p.x, oy + p.y, r, light_colour);
        box = {ox + int(std::floor(p.x - r - 1)), oy + int(std::floor(p.y - r - 1)), int(2 * r + 3), int(2 * r + 3)};
        lx = p.x;
        ly = p.y;
    } else {
        double dx = p.in_front ? p.x - c : p.x, dy = p.in_front ? p.y - c : p.y;
        double reach = std::max({std::fabs(dx), std::fabs(dy), 1e-300}), inset = 2 * s + 2;
        dx /= reach;
        dy /= reach;  // now max(|dx|, |dy|) = 1: the tip lands on the inset border
        double tip_x = c + dx * (c - inset), tip_y = c + dy * (c - inset), len = std::hypot(dx, dy);
        double ux = dx / len, uy = dy / len, shaft = 8 * s + 6, head = 4 * s + 2;
        double tail_x = tip_x - ux * shaft, tail_y = tip_y - uy * shaft;
        double wing[2][2];
        for (int side = 0; side < 2; ++side) {
            double a = side ? 0.6 : -0.6;  // radians either side of the shaft
            wing[side][0] = tip_x - head * (ux * std::cos(a) - uy * std::sin(a));
            wing[side][1] = tip_y - head * (ux * std::sin(a) + uy * std::cos(a));
        }
        for (int pass = 0; pass < 2; ++pass) {  // a dark outline, then cyan over it
            double t = pass ? s + 1 : s + 3;
            Colour col = pass ? light_colour : ink;
            line(img, ox + tail_x, oy + tail_y, ox + tip_x, oy + tip_y, t, col);
            for (const auto& w : wing) line(img, ox + w[0], oy + w[1], ox + tip_x, oy + tip_y, t, col);
        }
        double x0 = std::min({tail_x, tip_x, wing[0][0], wing[1][0]}) - s - 2;
        double y0 = std::min({tail_y, tip_y, wing[0][1], wing[1][1]}) - s - 2;
        double x1 = std::max({tail_x, tip_x, wing[0][0], wing[1][0]}) + s + 2;
        double y1 = std::max({tail_y, tip_y, wing[0][1], wing[1][1]}) + s + 2;
        box = {ox + int(std::floor(x0)), oy + int(std::floor(y0)), int(std::ceil(x1 - x0)), int(std::ceil(y1 - y0))};
        lx = tail_x;
        ly = tail_y;
    }
    // The label on the side of the marker that faces the panel's centre, kept inside the panel.
    int w = text_width(label, s), h = glyph_rows * s, gap = 4 * s + 2;
    double tx = lx < c ? lx + gap : lx - gap - w, ty = ly < c ? ly + gap : ly - gap - h;
    tx = std::clamp(tx, double(s), double(n - w - s));
    ty = std::clamp(ty, double(s), double(n - h - s));
    draw_text_outlined(img, ox + int(tx), oy + int(ty), label, s, paper, ink);
    return box;
}

// Numbers under the colour bar: 0, steps of 1, 2 or 5 times a power of ten that leave room for each label,
// and `top` itself; a step too close to `top` for its label gives way to it.
std::vector<int> bar_ticks(int top, int bar_width, int s) {
    int room = text_width(std::to_string(top) + "+", s) + 4 * s;
    int most = std::max(1, bar_width / room);
    int step = 1;
    for (int decade = 1; step * most < top; decade *= 10)
        for (int m : {1, 2, 5})
            if (step * most < top) step = m * decade;
    std::vector<int> ticks;
    for (int v = 0; v < top; v += step)
        if (double(top - v) / top * bar_width >= room) ticks.push_back(v);
    ticks.push_back(top);
    return ticks;
}

}  // namespace

std::string Heatmap::caption() const {
    char buf[400];
    std::snprintf(
        buf, sizeof buf,
        "Useless cluster tests per pixel (%s %.4g, %.4g, %.4g): k-means (left) mean %.2f, VCO (right) mean %.2f "
        "over %llu pixels; colour bar from 0 (dark) to %u or more (bright); grey: no surface; cyan: the %s%s",
        sun ? "sun toward" : "light at", light[0], light[1], light[2], mean_useless[0], mean_useless[1],
        (unsigned long long)pixels, scale_max, sun ? "sun" : "light",
        layout.light_in_view ? "" : " (out of view: the arrows point to it)");
    return buf;
}

namespace {

// Lays out and draws the picture from the per-pixel counts (k-means, VCO; one per pixel that sees the
// scene, in pixel order), and encodes it.
void compose(Heatmap& h, const std::vector<uint32_t> counts[2], const std::vector<double>& hits, const Camera& cam,
             int n) {
    HeatmapLayout& L = h.layout;
    const int s = L.text_scale = n >= 200 ? 2 : 1, margin = 5 * s, gap = 8 * s, line_h = (glyph_rows + 2) * s;
    const int width = 2 * n + gap + 2 * margin, inner = width - 2 * margin;

    // Method and mean on one line above each panel when both panels' fit, else on two lines in both.
    const char* methods[2] = {"K-MEANS", "VCO"};
    std::string means[2];
    bool one_line = true;
    for (int panel = 0; panel < 2; ++panel) {
        char mean[48];
        std::snprintf(mean, sizeof mean, "MEAN %.2f", h.mean_useless[panel]);
        means[panel] = mean;
        one_line = one_line && text_width(std::string(methods[panel]) + "  " + mean, s) <= n;
    }
    for (int panel = 0; panel < 2; ++panel)
        L.title_lines[panel] = one_line ? std::vector<std::string>{std::string(methods[panel]) + "  " + means[panel]}
                                        : std::vector<std::string>{methods[panel], means[panel]};
    const size_t title_rows = one_line ? 1 : 2;
    const int panel_y = margin + int(title_rows) * line_h + s;
    const int bar_y = panel_y + n + 5 * s, bar_h = 8 * s, labels_y = bar_y + bar_h + 3 * s;
    const int caption_y = labels_y + line_h + 2 * s;

    // The caption under the numbers, as long as fits, and the key for grey beside it or under it.
    std::string caption = "USELESS CLUSTER TESTS PER PIXEL";
    for (const char* shorter : {"USELESS TESTS PER PIXEL", "USELESS TESTS"})
        if (text_width(caption, s) > inner) caption = shorter;
    const std::string key = "NO SURFACE";
    const int key_w = glyph_rows * s + 3 * s + text_width(key, s);
    const bool key_beside = text_width(caption, s) + 6 * s + key_w <= inner;
    const int key_y = key_beside ? caption_y : caption_y + line_h;
    const int height = key_y + glyph_rows * s + margin;

    h.width = uint32_t(width);
    h.height = uint32_t(height);
    RgbImage img(h.width, h.height, paper);
    for (int panel = 0; panel < 2; ++panel) {
        const int ox = margin + panel * (n + gap);
        L.panels[panel] = {ox, panel_y, n, n};
        size_t next = 0;
        for (int y = 0; y < n; ++y)
            for (int x = 0; x < n; ++x) {
                bool seen = !std::isnan(hits[(size_t(y) * n + x) * 3]);
                img.set(ox + x, panel_y + y, seen ? ramp(double(counts[panel][next++]) / h.scale_max) : no_surface);
            }
        const auto& lines = L.title_lines[panel];
        int title_w = 0;
        for (size_t i = 0; i < lines.size(); ++i) {
            draw_text(img, ox, margin + int(i) * line_h, lines[i], s, ink);
            title_w = std::max(title_w, text_width(lines[i], s));
        }
        L.titles[panel] = {ox, margin, title_w, int(lines.size() - 1) * line_h + glyph_rows * s};
    }
    // A sun shows where its direction vanishes: the projection of eye + toward, whatever toward's length.
    double at[3];
    for (int k = 0; k < 3; ++k) at[k] = h.sun ? cam.eye[k] + h.light[k] : h.light[k];
    Projection light = project(cam, at);
    L.light_in_view = light.in_front && light.x >= 0 && light.x < n && light.y >= 0 && light.y < n;
    for (int panel = 0; panel < 2; ++panel)
        L.light_marks[panel] = mark_light(img, L.panels[panel].x, panel_y, n, light, s, h.sun ? "SUN" : "LIGHT");

    // The colour bar, inset so the numbers at its ends stay in the picture.
    const int top = int(h.scale_max);
    const std::string top_label = std::to_string(top) + "+";
    const int left = margin + text_width("0", s) / 2, right = width - margin - text_width(top_label, s) / 2;
    L.colour_bar = {left, bar_y, right - left, bar_h};
    for (int x = left; x < right; ++x) img.fill(x, bar_y, 1, bar_h, ramp(double(x - left) / (right - left - 1)));
    L.tick_values = bar_ticks(top, right - left, s);
    for (int v : L.tick_values) {
        int x = left + int(std::lround(double(v) / top * (right - left - 1)));
        std::string label = v == top ? top_label : std::to_string(v);
        img.fill(x - s / 2, bar_y + bar_h, s, 2 * s, ink);
        draw_text(img, x - text_width(label, s) / 2, labels_y, label, s, ink);
    }
    draw_text(img, margin, caption_y, caption, s, ink);
    const int key_x = key_beside ? width - margin - key_w : margin;
    img.fill(key_x, key_y, glyph_rows * s, glyph_rows * s, ink);
    img.fill(key_x + 1, key_y + 1, glyph_rows * s - 2, glyph_rows * s - 2, no_surface);
    draw_text(img, key_x + glyph_rows * s + 3 * s, key_y, key, s, ink);
    h.png = encode_png_rgb(img.pixels.data(), h.width, h.height);
}

}  // namespace

Heatmap render_heatmap(const Scene& scene, const HeatmapOptions& options,
                       const std::function<void(const std::string&)>& progress) {
    Heatmap h;
    const ClusterMethod methods[2] = {ClusterMethod::kmeans, ClusterMethod::vco};
    std::vector<uint32_t> counts[2];
    std::vector<double> hits;
    Camera cam;
    for (int panel = 0; panel < 2; ++panel) {
        if (progress) progress(std::string("heat map: ") + method_name(methods[panel]) + " panel");
        ClusterOptions c = options.clustering;
        c.method = methods[panel];
        BoundsOptions b;
        b.mask = bounds_auto;
        b.obb = options.obb;
        BakedScene baked = bake_in_memory(scene, c, b, nullptr, {}, options.threads);
        if (panel == 0) {  // the camera and the light from the world bounds; the same for both panels
            double lo[3], hi[3];
            if (!world_box(baked, lo, hi)) return h;
            cam = default_camera(lo, hi, options.size, options.size);
            hits = first_hits(baked, cam, options.threads);
            h.sun = options.sun && options.has_light;
            if (options.has_light)
                std::copy(options.light, options.light + 3, h.light);
            else {
                std::vector<double> l = report_lights(lo, hi, 1);
                std::copy(l.begin(), l.end(), h.light);
            }
        }
        LoadedAsset asset;
        open_asset_copy(encode_asset(baked.meshes, baked.instances), asset);
        counts[panel] = useless_tests(asset.view, h.light, hit_points(hits), options.one_sided, options.threads, h.sun);
    }
    h.pixels = counts[0].size();
    std::vector<uint32_t> all(counts[0]);
    all.insert(all.end(), counts[1].begin(), counts[1].end());
    std::sort(all.begin(), all.end());
    h.scale_max =
        std::max<uint32_t>(1, all.empty() ? 1 : all[std::min(all.size() - 1, size_t(0.99 * double(all.size())))]);
    for (int panel = 0; panel < 2; ++panel) {
        double sum = 0;
        for (uint32_t v : counts[panel]) sum += v;
        h.mean_useless[panel] = counts[panel].empty() ? 0 : sum / double(counts[panel].size());
    }

    compose(h, counts, hits, cam, int(options.size));
    return h;
}

}  // namespace cb
