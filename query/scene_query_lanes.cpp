// The body of query_scene, built once for each set of lanes the dispatch in scene_query.cpp may pick: as
// the baseline unit of cb_query, and again with -mavx2 -mfma and with -mavx512f (query/CMakeLists.txt).
// Everything the runtime defines here lands in cb::CB_LANES (cb_simd.h), so the builds share no symbol.
#include <algorithm>
#include <chrono>
#include <thread>

#include <cb_level.h>

#include "parallel.h"
#include "scene_query.h"
#include "timing.h"

namespace cb {
inline namespace CB_LANES {

namespace {

// The tools' level as a runtime level (light-independent: made once for every light), with the scan's
// bounds when the scan reads them. Asset a of the input is asset a of the level, and instance i handle i.
struct RuntimeLevel {
    Level level;
    RuntimeLevel(const LevelInput& input, const SceneQueryOptions& o) {
        for (const AssetView* view : input.assets)
            level.add_asset(*view, (o.traversal == Traversal::scan || o.sun) && !o.reference);
        for (const LevelInstance& placed : input.instances)
            level.add_instance(placed.asset, placed.mesh, placed.transform);
        level.commit();
    }
};

void add_stats(QueryStats& to, const QueryStats& c) {
    to.nodes_visited += c.nodes_visited;
    to.clusters_tested += c.clusters_tested;
    to.triangles_tested += c.triangles_tested;
    to.touching += c.touching;
}

ShadowBuildOptions build_options(const SceneQueryOptions& o) {
    ShadowBuildOptions build;
    build.traversal = o.traversal;
    build.one_sided = o.one_sided;
    build.capsule_aspect = o.capsule_aspect;
    build.metric_build = o.metric_build;
    build.bias = o.bias;
    return build;
}

// A batch through the scene: tiles of points by direction (for a sun, by place across its direction) culled
// against the instances' hierarchy, the instances met set up for the light, then the tiles answered; each
// step in ranges over the threads.
void answer_batch(const Level& level, const double* light, const double* points, size_t n, const SceneQueryOptions& o,
                  unsigned thread_count, SceneQueryResult& r) {
    auto build_start = std::chrono::steady_clock::now();
    LevelShadow shadow;
    if (o.sun)
        shadow.begin_sun(level, light, points, n, build_options(o));
    else
        shadow.begin(level, light, points, n, build_options(o));
    const size_t tiles = shadow.tile_count();
    const size_t chunk = 64;  // tiles a culling job takes
    parallel_for((tiles + chunk - 1) / chunk, thread_count,
                 [&](size_t c) { shadow.cull(c * chunk, std::min(tiles, (c + 1) * chunk)); });
    const size_t built = shadow.gather();
    std::vector<BuildScratch> scratch(thread_count);
    parallel_for(thread_count, thread_count, [&](size_t t) {
        shadow.build(built * t / thread_count, built * (t + 1) / thread_count, &scratch[t]);
    });
    for (size_t i = 0; i < built; ++i) {
        const InstanceShadow& s = shadow.built(i);
        r.skipped += s.skipped_clusters();
        r.nodes += s.node_count();
        r.structure_bytes += s.memory_bytes();
        r.always_tested += s.always_tested();
    }
    r.structures = built;
    r.build_seconds = seconds_since(build_start);

    auto start = std::chrono::steady_clock::now();
    r.shadowed.assign(n, 0);
    std::vector<QueryStats> counts(thread_count);
    parallel_for(thread_count, thread_count, [&](size_t t) {
        std::vector<uint32_t> own(shadow.scratch_size());
        shadow.occluded(tiles * t / thread_count, tiles * (t + 1) / thread_count, r.shadowed.data(), own.data(),
                        &counts[t]);
    });
    for (const QueryStats& c : counts) add_stats(r.stats, c);
    r.query_seconds = seconds_since(start);
}

// Each point on its own, with its own counts (per_point), or the reference query.
void answer_points(const Level& level, const double* light, const double* points, size_t n, const SceneQueryOptions& o,
                   unsigned thread_count, SceneQueryResult& r) {
    auto build_start = std::chrono::steady_clock::now();
    std::vector<InstanceShadow> shadows(o.reference ? 0 : level.handle_limit());
    ShadowBuildOptions build = build_options(o);
    for (uint32_t h = 0; h < shadows.size(); ++h) {
        build.bounds = level.scan_bounds(level.asset_of(h));
        if (o.sun)
            shadows[h].build_sun(level.asset(level.asset_of(h)), level.placement(h), light, build);
        else
            shadows[h].build(level.asset(level.asset_of(h)), level.placement(h), light, build);
        r.skipped += shadows[h].skipped_clusters();
        r.nodes += shadows[h].node_count();
        r.structure_bytes += shadows[h].memory_bytes();
        r.always_tested += shadows[h].always_tested();
    }
    r.structures = shadows.size();
    r.build_seconds = seconds_since(build_start);

    auto start = std::chrono::steady_clock::now();
    r.shadowed.assign(n, 0);
    if (o.per_point) r.point_stats.assign(n, QueryStats{});
    std::vector<QueryStats> counts(thread_count);
    size_t stack_size = 0;
    for (const InstanceShadow& shadow : shadows) stack_size = std::max(stack_size, shadow.stack_size());
    parallel_for(thread_count, thread_count, [&](size_t t) {
        std::vector<uint32_t> stack(stack_size);
        for (size_t i = n * t / thread_count; i < n * (t + 1) / thread_count; ++i) {
            QueryStats* s = o.per_point ? &r.point_stats[i] : &counts[t];
            const double* p = &points[i * 3];
            if (o.reference) {
                r.shadowed[i] = o.sun ? occluded_sun_reference(level, p, light, o.bias, o.one_sided, s)
                                      : occluded_reference(level, p, light, o.bias, o.one_sided, s);
            } else {
                for (const InstanceShadow& shadow : shadows)
                    if (!r.shadowed[i]) r.shadowed[i] = shadow.occluded(p, stack.data(), s);
            }
        }
    });
    for (const QueryStats& c : counts) add_stats(r.stats, c);
    for (const QueryStats& c : r.point_stats) add_stats(r.stats, c);
    r.query_seconds = seconds_since(start);
}

// One light's answers over the level already made, with the level's bias unless the options give one.
SceneQueryResult answer_light(const Level& level, const double* light, const double* points, size_t n,
                              SceneQueryOptions o) {
    SceneQueryResult r;
    if (!(o.bias > 0)) o.bias = level.shadow_bias();
    r.bias = o.bias;
    const unsigned thread_count = threads_or_all(o.threads);
    if (!o.reference && !o.per_point)
        answer_batch(level, light, points, n, o, thread_count, r);
    else
        answer_points(level, light, points, n, o, thread_count, r);
    return r;
}

}  // namespace

SceneQueryResult query_level_lanes(const LevelInput& input, const double* light, const double* points, size_t n,
                                   const SceneQueryOptions& o) {
    auto start = std::chrono::steady_clock::now();
    const RuntimeLevel runtime(input, o);
    const double level_seconds = seconds_since(start);
    SceneQueryResult r = answer_light(runtime.level, light, points, n, o);
    r.build_seconds += level_seconds;  // one light: its build includes the level
    return r;
}

double query_lights_lanes(const LevelInput& input, const double* lights, size_t light_count, const double* points,
                          size_t n, const SceneQueryOptions& o,
                          const std::function<void(size_t, const SceneQueryResult&)>& on_light) {
    auto start = std::chrono::steady_clock::now();
    const RuntimeLevel runtime(input, o);
    const double level_seconds = seconds_since(start);
    for (size_t l = 0; l < light_count; ++l) on_light(l, answer_light(runtime.level, &lights[l * 3], points, n, o));
    return level_seconds;
}

}  // namespace CB_LANES
}  // namespace cb
