#include "heatmap.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "asset_file.h"
#include "baked_scene.h"
#include "png_writer.h"
#include "report.h"
#include "runtime_cost.h"

namespace cb {
namespace {

// A dark-to-bright ramp (black, purple, red, orange, pale yellow): readable in grey print too.
void ramp(double t, uint8_t* rgb) {
    static const double stops[5][3] = {{0, 0, 4}, {87, 16, 110}, {188, 55, 84}, {249, 142, 9}, {252, 255, 164}};
    t = std::clamp(t, 0.0, 1.0) * 4;
    int i = std::min(3, int(t));
    double f = t - i;
    for (int k = 0; k < 3; ++k) rgb[k] = uint8_t(std::lround(stops[i][k] + f * (stops[i + 1][k] - stops[i][k])));
}

}  // namespace

std::string Heatmap::caption() const {
    char buf[320];
    std::snprintf(
        buf, sizeof buf,
        "Useless cluster tests per pixel (light at %.4g, %.4g, %.4g): k-means (left) mean %.2f, VCO (right) mean %.2f "
        "over %llu pixels; colour bar from 0 (dark) to %u or more (bright); grey: no surface",
        light[0], light[1], light[2], mean_useless[0], mean_useless[1], (unsigned long long)pixels, scale_max);
    return buf;
}

Heatmap render_heatmap(const Scene& scene, const HeatmapOptions& options,
                       const std::function<void(const std::string&)>& progress) {
    Heatmap h;
    const ClusterMethod methods[2] = {ClusterMethod::kmeans, ClusterMethod::vco};
    std::vector<uint32_t> counts[2];
    std::vector<double> hits;
    for (int panel = 0; panel < 2; ++panel) {
        if (progress) progress(std::string("heat map: ") + method_name(methods[panel]) + " panel");
        ClusterOptions c = options.clustering;
        c.method = methods[panel];
        BoundsOptions b;
        b.mask = bounds_auto;
        b.obb = options.obb;
        BakedScene baked = bake_in_memory(scene, c, b);
        if (panel == 0) {  // the camera and the light from the world bounds; the same for both panels
            double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
            for (const Instance& inst : baked.instances) {
                const AssetMesh& m = baked.meshes[inst.mesh];
                for (size_t v = 0; v < m.positions.size() / 3; ++v) {
                    auto p =
                        transform_point(inst.world, m.positions[v * 3], m.positions[v * 3 + 1], m.positions[v * 3 + 2]);
                    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], p[k]), hi[k] = std::max(hi[k], p[k]);
                }
            }
            if (!(lo[0] <= hi[0])) return h;
            Camera cam = default_camera(lo, hi, options.size, options.size);
            hits = first_hits(baked, cam, c.threads);
            if (options.has_light)
                std::copy(options.light, options.light + 3, h.light);
            else {
                std::vector<double> l = report_lights(lo, hi, 1);
                std::copy(l.begin(), l.end(), h.light);
            }
        }
        LoadedAsset asset;
        open_asset_copy(encode_asset(baked.meshes, baked.instances), asset);
        counts[panel] = useless_tests(asset.view, h.light, hit_points(hits), options.one_sided, c.threads);
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

    const uint32_t n = options.size, gap = 8, bar = 12;
    h.width = 2 * n + gap, h.height = n + gap + bar;
    std::vector<uint8_t> rgb(size_t(h.width) * h.height * 3, 255);
    for (int panel = 0; panel < 2; ++panel) {
        size_t next = 0;
        for (uint32_t y = 0; y < n; ++y)
            for (uint32_t x = 0; x < n; ++x) {
                uint8_t* px = &rgb[(size_t(y) * h.width + panel * (n + gap) + x) * 3];
                if (std::isnan(hits[(size_t(y) * n + x) * 3])) {
                    px[0] = px[1] = px[2] = 128;
                    continue;
                }
                ramp(double(counts[panel][next++]) / h.scale_max, px);
            }
    }
    for (uint32_t y = n + gap; y < h.height; ++y)
        for (uint32_t x = 0; x < h.width; ++x) ramp(double(x) / (h.width - 1), &rgb[(size_t(y) * h.width + x) * 3]);
    h.png = encode_png_rgb(rgb.data(), h.width, h.height);
    return h;
}

}  // namespace cb
