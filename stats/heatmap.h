// The picture of the thesis's figure 2.15: for one camera and one light, how many cluster tests per pixel
// found nothing (the point's segment to the light was not blocked by that cluster), k-means beside VCO.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "bounds.h"
#include "cluster.h"
#include "scene.h"

namespace cb {

struct HeatmapOptions {
    ClusterOptions clustering;  // method is set per panel
    ObbMethod obb = ObbMethod::refined;
    uint32_t size = 256;  // each panel is size x size
    bool has_light = false;
    double light[3] = {0, 0, 0};  // world; default: the report's first light
    bool sun = false;             // `light` is a sun's direction toward it (cb_segment.h, "A sun"); needs has_light
    bool one_sided = false;
    unsigned threads = 0;  // 0: all hardware threads; the picture does not depend on it
};

// A rectangle of the picture, in pixels from its top-left corner.
struct PixelBox {
    int x = 0, y = 0, w = 0, h = 0;
};

// Where the picture's parts are, so that a reader (or a test) can find them.
struct HeatmapLayout {
    int text_scale = 1;  // pixels per font cell (bitmap_text.h)
    PixelBox panels[2];  // k-means, VCO
    PixelBox titles[2];  // above each panel: its method and mean
    std::vector<std::string> title_lines[2];
    PixelBox colour_bar;           // the ramp itself, 0 at its left edge, scale_max at its right
    std::vector<int> tick_values;  // numbered below the bar; the last is scale_max ("N+")
    PixelBox light_marks[2];       // the light's marker in each panel (an arrow at the edge when out of view)
    bool light_in_view = false;
};

struct Heatmap {
    std::vector<uint8_t> png;
    uint32_t width = 0, height = 0;
    uint32_t scale_max = 0;           // the colour ramp's top (brightest): this many useless tests or more
    double mean_useless[2] = {0, 0};  // per covered pixel: k-means, VCO
    uint64_t pixels = 0;              // pixels that see the scene
    double light[3] = {0, 0, 0};      // or, for a sun, the direction toward it
    bool sun = false;
    HeatmapLayout layout;
    std::string caption() const;
};

// Left panel k-means, right panel VCO, each titled with its method and mean; the light marked in both (an
// arrow at the panel's edge pointing to it when it is out of view; a sun where its direction vanishes); a numbered colour bar along the bottom
// (dark: 0, bright: scale_max or more). Pixels that miss the scene are grey, as the key beside the bar
// says. Each stage of the work is named to `progress` when set.
Heatmap render_heatmap(const Scene& scene, const HeatmapOptions& options,
                       const std::function<void(const std::string&)>& progress = {});

}  // namespace cb
