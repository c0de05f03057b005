// Cluster-quality statistics of a bake: per level (coarse, fine) sizes, connectivity, bounding-volume
// tightness, normal cones, how many clusters a light skips, and the conservativeness of the clusters'
// shadow volumes (the thesis's figure 2.15). Pure: a function of the baked meshes, the instances and the
// options; the same input gives the same figures whatever the thread count.
//
// Conventions (docs/STATS.md says more):
// - Per-cluster figures are over the stored clusters: a mesh used by several instances counts once.
// - "Relative to the scene bounds" sums each instance's clusters in world space (volumes and areas under
//   the instance transform) over the world box of the scene.
// - Lights are random (fixed seed) in each mesh's own frame, in the box three times its bounds and outside
//   the bounds themselves; shadow-volume samples are uniform in the volume, clipped to the mesh bounds.
//   Suns are random directions, uniform over the sphere; a box's sun prism (the points whose ray toward the
//   sun meets it) is sampled the same way.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

#include "asset_writer.h"
#include "scene.h"

namespace cb {

struct StatsOptions {
    uint32_t lights = 8;       // random light positions per mesh
    uint32_t samples = 32;     // points sampled in each cluster's shadow volume, per light and per sun
    uint32_t acmr_cache = 32;  // FIFO cache size for the ACMR of the cluster order
    uint64_t seed = 1;
    unsigned threads = 0;  // 0: all hardware threads (figures do not depend on it)
    uint32_t suns = 8;     // random sun directions per mesh
};

// min / mean / max of a per-cluster figure and a histogram of it: counts[i] holds values in
// [first + i * width, first + (i + 1) * width).
struct Distribution {
    uint64_t count = 0;
    double min = 0, mean = 0, max = 0;
    double first = 0, width = 1;
    std::vector<uint64_t> counts;
};

// NaN marks a figure that cannot be computed (no such volume in the input, a flat scene box, no samples);
// JSON writes it as null and text as "n/a".
struct LevelStats {
    uint64_t clusters = 0;
    Distribution triangles, vertices, components;  // per cluster; vertices: distinct indices
    uint64_t split_clusters = 0;                   // clusters of more than one connected component
    double vertices_per_triangle = 0;              // sum of distinct vertices / triangles (a per-cluster ACMR)

    double obb_volume_sum = NAN, obb_volume_mean = NAN, obb_area_sum = NAN, obb_area_mean = NAN;  // mesh frames
    double obb_volume_relative = NAN, obb_area_relative = NAN;           // world, over instances, / scene box
    double sphere_over_obb = NAN, capsule_over_obb = NAN;                // summed volumes over summed OBB volumes
    double sphere_over_obb_median = NAN, capsule_over_obb_median = NAN;  // per cluster (flat boxes left out)
    double fill = NAN, fill_mean = NAN;  // triangle area / OBB surface: summed, per cluster
    Distribution
        normal_cone_degrees;         // valid cones: the widest normal from the axis (90 degrees - the front half-angle)
    double no_cone_share = NAN;      // clusters without a valid cone
    double light_skip_share = NAN;   // clusters a light skips (one-sided, light in the front cone), mean over lights
    double useless_share = NAN;      // sampled points in a cluster's shadow volume its triangles do not shadow
    uint64_t volume_samples = 0;     // how many points that share is over
    double no_volume_share = NAN;    // (cluster, light) pairs with no shadow volume (light in or level with the box)
    double sun_skip_share = NAN;     // clusters a sun skips (one-sided, the sun in the front cone), mean over suns
    double sun_useless_share = NAN;  // sampled points in a cluster's sun prism its triangles do not shadow
    uint64_t sun_prism_samples = 0;
};

struct SceneStats {
    uint64_t meshes = 0, instances = 0, triangles = 0, scene_triangles = 0;
    double bounds_min[3] = {0, 0, 0}, bounds_max[3] = {0, 0, 0};  // world
    double acmr = 0;  // FIFO acmr_cache over the cluster order, triangle-weighted over meshes
    uint32_t acmr_cache = 32;
    StatsOptions options;
    LevelStats coarse, fine;
};

// Needs each mesh's fine and coarse OBBs for the volume figures and the shadow samples, cones for the cone
// figures, spheres and capsules for theirs; what is missing is reported as NaN.
SceneStats cluster_statistics(const std::vector<AssetMesh>& meshes, const std::vector<Instance>& instances,
                              const StatsOptions& options = {});

nlohmann::json to_json(const SceneStats& s);
std::string to_text(const SceneStats& s);

// Histogram and extremes of `values`; integer figures get unit-wide bins when max <= max_bins.
Distribution distribution(const std::vector<double>& values, bool integer, uint32_t max_bins = 16);

}  // namespace cb
