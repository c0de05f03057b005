// Primary visibility, the renderer's first hits, from the level's assets themselves: the fine clusters a
// camera may see (cb_cull.h), then their triangles drawn into a depth buffer. Each covered pixel gets the
// point where its ray meets the nearest triangle, in double, and that triangle's normal. first_hits.h finds
// first hits by casting rays instead.
#pragma once

#include <cb_asset.h>

#include <cstdint>
#include <vector>

#include "camera.h"
#include "scene_query.h"

namespace cb {

struct VisibleSurface {
    uint32_t width = 0, height = 0;
    std::vector<uint32_t> pixel;   // per covered pixel, its index (y * width + x), in pixel order
    std::vector<double> points;    // per covered pixel: xyz, world, on the plane of the triangle it sees
    std::vector<double> normals;   // per covered pixel: unit normal of that triangle, turned to face the eye
    std::vector<uint32_t> meshes;  // per covered pixel: the mesh of that triangle, numbered across the assets
    size_t clusters_drawn = 0;     // fine clusters that passed culling (every cluster without fine boxes)
    size_t triangles_drawn = 0;
};

// Draws the fine clusters the camera may see (every one of an asset without fine boxes), both faces of
// every triangle, on `threads` threads (0: all). Deterministic: equal depths go to the cluster listed
// first (instance by instance, in the level's order).
VisibleSurface primary_visibility(const LevelInput& level, const Camera& camera, unsigned threads = 0);

}  // namespace cb
