// The world box of a scene's instances: the box of every vertex as its instances place it, in double. One
// computation for the scene as loaded, as baked in memory, and as a level of opened assets.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <vector>

#include "asset_content.h"
#include "scene.h"
#include "scene_query.h"

namespace cb {

// An instance's column-major 4x4 transform as the runtime's column-major 3x4 (cb_segment.h's apply_instance).
inline void instance_matrix(const Transform& world, double* m) {
    const double linear_and_translation[12] = {world[0], world[1], world[2],  world[4],  world[5],  world[6],
                                               world[8], world[9], world[10], world[12], world[13], world[14]};
    for (int k = 0; k < 12; ++k) m[k] = linear_and_translation[k];
}

// Grows the box [lo, hi] to hold the box [box_lo, box_hi].
inline void grow_box(double* lo, double* hi, const double* box_lo, const double* box_hi) {
    for (int k = 0; k < 3; ++k) {
        lo[k] = std::min(lo[k], box_lo[k]);
        hi[k] = std::max(hi[k], box_hi[k]);
    }
}

// The world box [lo, hi] of `count` vertices (xyz floats, in their mesh's frame) placed by the instance
// transform `m` (column-major 3x4, as apply_instance takes it); lo is +infinity and hi -infinity when there
// are none.
void instance_world_box(const float* positions, size_t count, const double* m, double* lo, double* hi);

// The world box of the level's instance i.
void instance_world_box(const LevelInput& level, size_t i, double* lo, double* hi);

// The world box [lo, hi] of every instance's vertices; false when the level has none.
bool level_world_box(const LevelInput& level, double* lo, double* hi);

// The same, and the world box of each instance (lo xyz, then hi xyz) in `boxes`.
bool instance_world_boxes(const LevelInput& level, std::vector<std::array<double, 6>>& boxes, double* lo, double* hi);

// The same for a scene as loaded, and for one baked in memory.
bool world_box(const Scene& scene, double* lo, double* hi);
bool world_box(const BakedScene& baked, double* lo, double* hi);

}  // namespace cb
