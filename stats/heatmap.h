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
    bool one_sided = false;
};

struct Heatmap {
    std::vector<uint8_t> png;
    uint32_t width = 0, height = 0;
    uint32_t scale_max = 0;           // the colour ramp's top (brightest): this many useless tests or more
    double mean_useless[2] = {0, 0};  // per covered pixel: k-means, VCO
    uint64_t pixels = 0;              // pixels that see the scene
    double light[3] = {0, 0, 0};
    std::string caption() const;
};

// Left panel k-means, right panel VCO; a colour bar along the bottom (dark: 0, bright: scale_max).
// Pixels that miss the scene are grey. Each stage of the work is named to `progress` when set.
Heatmap render_heatmap(const Scene& scene, const HeatmapOptions& options,
                       const std::function<void(const std::string&)>& progress = {});

}  // namespace cb
