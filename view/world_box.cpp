#include "world_box.h"

#include <cb_segment.h>

#include <cmath>
#include <cstddef>

namespace cb {

namespace {

// The union of the world boxes box_of(i, lo, hi) gives for each of the instances; false when it is empty.
template <class Instances, class Box>
bool union_of(const Instances& instances, double* lo, double* hi, Box&& box_of) {
    for (int k = 0; k < 3; ++k) {
        lo[k] = INFINITY;
        hi[k] = -INFINITY;
    }
    for (size_t i = 0; i < instances.size(); ++i) {
        double box_lo[3], box_hi[3];
        box_of(i, box_lo, box_hi);
        grow_box(lo, hi, box_lo, box_hi);
    }
    return lo[0] <= hi[0];
}

// The world box of `instances` placing `meshes`, whose `positions` hold xyz floats (a scene's as loaded, or
// as baked).
template <class Meshes>
bool placed_world_box(const Meshes& meshes, const std::vector<Instance>& instances, double* lo, double* hi) {
    return union_of(instances, lo, hi, [&](size_t i, double* box_lo, double* box_hi) {
        const std::vector<float>& positions = meshes[instances[i].mesh].positions;
        double m[12];
        instance_matrix(instances[i].world, m);
        instance_world_box(positions.data(), positions.size() / 3, m, box_lo, box_hi);
    });
}

}  // namespace

void instance_world_box(const float* positions, size_t count, const double* m, double* lo, double* hi) {
    for (int k = 0; k < 3; ++k) {
        lo[k] = INFINITY;
        hi[k] = -INFINITY;
    }
    for (size_t v = 0; v < count; ++v) {
        const double local[3] = {positions[v * 3], positions[v * 3 + 1], positions[v * 3 + 2]};
        double w[3];
        apply_instance(m, local, w);
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], w[k]);
            hi[k] = std::max(hi[k], w[k]);
        }
    }
}

void instance_world_box(const LevelInput& level, size_t i, double* lo, double* hi) {
    const LevelInstance& placed = level.instances[i];
    const AssetView& view = *level.assets[placed.asset];
    const MeshRecord& mesh = view.meshes[placed.mesh];
    instance_world_box(view.position(mesh, 0), mesh.vertex_count, placed.transform, lo, hi);
}

bool level_world_box(const LevelInput& level, double* lo, double* hi) {
    return union_of(level.instances, lo, hi,
                    [&](size_t i, double* box_lo, double* box_hi) { instance_world_box(level, i, box_lo, box_hi); });
}

bool instance_world_boxes(const LevelInput& level, std::vector<std::array<double, 6>>& boxes, double* lo, double* hi) {
    boxes.resize(level.instances.size());
    return union_of(level.instances, lo, hi, [&](size_t i, double* box_lo, double* box_hi) {
        instance_world_box(level, i, box_lo, box_hi);
        std::copy(box_lo, box_lo + 3, boxes[i].data());
        std::copy(box_hi, box_hi + 3, boxes[i].data() + 3);
    });
}

bool world_box(const Scene& scene, double* lo, double* hi) {
    return placed_world_box(scene.meshes, scene.instances, lo, hi);
}

bool world_box(const BakedScene& baked, double* lo, double* hi) {
    return placed_world_box(baked.meshes, baked.instances, lo, hi);
}

}  // namespace cb
