// Point-light shadow queries over every instance of an asset, as the tools ask them: the per-light
// structures of one light built for each instance, the points answered on threads, the traversal counts
// summed. `clusterbake query`, the report's runtime cost and the heat map all ask through here; no other
// code above the runtime calls its query API.
#pragma once

#include <cb_asset.h>
#include <cb_instance_shadow.h>
#include <cb_shadow.h>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace cb {

// The traversal (cb::Traversal, runtime/detail/cb_tile.h) named "scan", "top-two", "top-one", "mtsv-one" or
// "mtsv-two" (the older spellings "trees", "one-tree" and "mtsv" are read too); false on another name. Every
// traversal gives the same answers.
bool parse_traversal(const std::string& name, Traversal& out);
// The name parse_traversal reads for a traversal.
const char* traversal_name(Traversal t);
// The metric trees' build (cb::MetricBuild) named "heuristic" or "reference"; false on another name.
bool parse_metric_build(const std::string& name, MetricBuild& out);

// One instance of a level as the tools hold it: a mesh of one of the level's assets under a world transform
// (column-major 3x4 doubles: the x, y, z axes, then the translation).
struct LevelInstance {
    uint32_t asset, mesh;
    double transform[12];
};

// Opened assets and the instances placed from them: what query_level and the renderer answer over. The
// views must outlive it.
struct LevelInput {
    std::vector<const AssetView*> assets;
    std::vector<LevelInstance> instances;
};

// Every baked instance of `view` appended to `level`, under `matrix` (world = matrix x the baked transform,
// in double, as cb::Level::add_baked composes them; null: as baked). The view joins the level's assets
// unless it is there already.
void place_baked(LevelInput& level, const AssetView& view, const double* matrix = nullptr);

// The level of one asset's baked instances.
LevelInput baked_level(const AssetView& view);

struct SceneQueryOptions {
    Traversal traversal = Traversal::scan;
    bool one_sided = false;       // a triangle blocks only when the light is behind it (double-sided ones always)
    unsigned threads = 0;         // build and query threads, 0 = all; the answers do not depend on it
    bool reference = false;       // occluded_reference instead: every cluster box the segment may touch, no build
    bool per_point = false;       // each point asks alone and keeps its own counts (a batch's tiles share theirs)
    double capsule_aspect = 4.0;  // mtsv: capsule-cones for clusters at least this long for their width, else cones
    MetricBuild metric_build = MetricBuild::heuristic;  // mtsv: how the metric trees are built
    double bias = 0;   // self-shadowing bias, world distance (cb_segment.h); 0: the level's, cb::Level::shadow_bias
    bool sun = false;  // the light is a sun: its xyz is the direction toward it (cb_segment.h, "A sun"), answered
                       // by the sun's traversal (cb_sun.h) finding clusters as `traversal` names
};

struct SceneQueryResult {
    std::vector<uint8_t> shadowed;        // per point, 1 when its segment to the light (ray to the sun) is blocked
    QueryStats stats;                     // summed over the points
    std::vector<QueryStats> point_stats;  // per point, with per_point
    double build_seconds = 0;             // every instance's structure for the light, the scan's bounds included
    double query_seconds = 0;
    size_t structures = 0, nodes = 0;  // one structure per instance (none for the reference)
    size_t structure_bytes = 0;        // what those structures hold (ShadowBuildOptions' shared bounds not counted)
    size_t always_tested = 0;          // clusters tested for every point (light inside or level with their box)
    size_t skipped = 0;                // one-sided: clusters the light sees from their front
    double bias = 0;                   // the self-shadowing bias the answers used
};

// The `count` points (xyz, world) against the light (xyz, world), over every instance of the level. The
// work runs on the widest lanes this processor has among those the build made (query_lanes); every choice
// gives the same answers. structures counts the instances set up for the light.
SceneQueryResult query_level(const LevelInput& level, const double* light, const double* points, size_t count,
                             const SceneQueryOptions& options = {});

// query_level over the asset's baked instances.
SceneQueryResult query_scene(const AssetView& view, const double* light, const double* points, size_t count,
                             const SceneQueryOptions& options = {});

// The same `count` points against each of `light_count` lights (xyz triples, world), as query_level answers
// them one light at a time, but with the light-independent part made once: the level's hierarchy and the
// scan's per-asset bounds (make_scan_bounds). Each light's result goes to `on_light` as soon as it is done,
// in order, so a caller keeps only what it needs of it; its build_seconds leave the shared part out.
// Returns the seconds the shared part took.
double query_level_lights(const LevelInput& level, const double* lights, size_t light_count, const double* points,
                          size_t count, const SceneQueryOptions& options,
                          const std::function<void(size_t light, const SceneQueryResult&)>& on_light);

// The lanes query_level runs on ("avx512", "avx2", "sse2" or "portable", as cb::simd::name), picked on
// first use: the widest the processor runs, no wider than the environment's CLUSTERBAKE_LANES (sse2, avx2
// or avx512) when set. Throws std::runtime_error on an unknown CLUSTERBAKE_LANES.
const char* query_lanes();

}  // namespace cb
