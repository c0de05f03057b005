// Primary visibility for the renderer, from the level's assets themselves: the fine clusters a camera may
// see (cb_cull.h), then their triangles drawn into a depth buffer. Each covered pixel gets the point where its
// ray meets the nearest triangle, in double, and that triangle's normal.
#pragma once

#include <cb_asset.h>

#include <cstdint>
#include <vector>

#include "runtime_cost.h"
#include "scene_query.h"

namespace cb {

// The world box [lo, hi] of every instance's vertices; false when the level has none.
bool level_world_box(const LevelInput& level, double* lo, double* hi);

// A camera at `eye` looking at `target`, `up` kept upright in the picture (when it is along the view,
// another axis is taken), a vertical field of view of `fov_degrees`.
Camera camera_looking_at(const double* eye, const double* target, const double* up, double fov_degrees, uint32_t width,
                         uint32_t height);

// The vertical field of view (degrees) from `eye` along `forward` that just holds the box [lo, hi], as
// default_camera frames it; 0 when some corner is not in front of the eye.
double framing_fov(const Camera& camera, const double* lo, const double* hi);

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
