// The body of query_scene, built once for each set of lanes the dispatch in scene_query.cpp may pick: as
// the baseline unit of cb_query, and again with -mavx2 -mfma and with -mavx512f (query/CMakeLists.txt).
// Everything the runtime defines here lands in cb::CB_LANES (cb_simd.h), so the builds share no symbol.
#include <algorithm>
#include <chrono>
#include <thread>

#include "parallel.h"
#include "scene_query.h"
#include "timing.h"

namespace cb {
inline namespace CB_LANES {

namespace {

// The scan's bounds, once per mesh however many instances it has; none for the reference or a tree traversal.
std::vector<ScanBounds> bounds_for(const AssetView& view, const SceneQueryOptions& o) {
    return o.traversal == Traversal::scan && !o.reference && view.instance_count ? make_scan_bounds(view)
                                                                                 : std::vector<ScanBounds>{};
}

// One light's answers with the bounds already made.
SceneQueryResult answer_light(const AssetView& view, const std::vector<ScanBounds>& bounds, const double* light,
                              const double* points, size_t n, const SceneQueryOptions& o) {
    SceneQueryResult r;
    const unsigned thread_count = threads_or_all(o.threads);

    // One structure per instance for this light (none for the reference).
    auto build_start = std::chrono::steady_clock::now();
    std::vector<InstanceShadow> trees(o.reference ? 0 : view.instance_count);
    ShadowBuildOptions build;
    build.traversal = o.traversal;
    build.one_sided = o.one_sided;
    build.threads = thread_count;
    build.bounds = bounds.empty() ? nullptr : bounds.data();
    build.capsule_ratio = o.capsule_ratio;
    build.metric_build = o.metric_build;
    for (uint32_t i = 0; i < trees.size(); ++i) {
        trees[i].build(view, i, light, build);
        r.skipped += trees[i].skipped_clusters();
        r.nodes += trees[i].node_count();
        r.tree_bytes += trees[i].memory_bytes();
        r.always_tested += trees[i].always_tested();
    }
    r.trees = trees.size();
    r.build_seconds = seconds_since(build_start);

    // The trees are const: threads take contiguous slices of the points' order by direction from the light
    // (the order a batch takes them in, so that each slice's tiles are as close as one batch's), each with
    // its own scratch and counts; the reference, and points asking alone, take slices of the points as given.
    auto start = std::chrono::steady_clock::now();
    r.shadowed.assign(n, 0);
    if (o.per_point) r.point_stats.assign(n, QueryStats{});
    std::vector<QueryStats> counts(thread_count);
    std::vector<uint32_t> order;
    const bool batch = !o.reference && !o.per_point;
    if (batch) {
        order.resize(n);
        std::vector<uint32_t> sort_scratch(batch_order_scratch_size(n));
        batch_order(light, points, n, order.data(), sort_scratch.data());
    }
    size_t stack_size = 0;
    for (const InstanceShadow& tree : trees) stack_size = std::max(stack_size, tree.stack_size());
    parallel_for(thread_count, thread_count, [&](size_t t) {
        size_t first = n * t / thread_count, last = n * (t + 1) / thread_count;
        if (batch) {
            std::vector<uint32_t> own(ordered_scratch_size(trees.data(), trees.size()));
            occluded_ordered(trees.data(), trees.size(), points, order.data() + first, last - first, r.shadowed.data(),
                             own.data(), &counts[t]);
            return;
        }
        std::vector<uint32_t> stack(stack_size);
        for (size_t i = first; i < last; ++i) {
            QueryStats* s = o.per_point ? &r.point_stats[i] : &counts[t];
            const double* p = &points[i * 3];
            if (o.reference) {
                r.shadowed[i] = occluded_reference(view, p, light, o.one_sided, s);
            } else {
                for (const InstanceShadow& tree : trees)
                    if (!r.shadowed[i]) r.shadowed[i] = tree.occluded(p, stack.data(), s);
            }
        }
    });
    auto add = [&](const QueryStats& c) {
        r.stats.nodes_visited += c.nodes_visited, r.stats.clusters_tested += c.clusters_tested;
        r.stats.triangles_tested += c.triangles_tested, r.stats.touching += c.touching;
    };
    for (const QueryStats& c : counts) add(c);
    for (const QueryStats& c : r.point_stats) add(c);
    r.query_seconds = seconds_since(start);
    return r;
}

}  // namespace

SceneQueryResult query_scene_lanes(const AssetView& view, const double* light, const double* points, size_t n,
                                   const SceneQueryOptions& o) {
    auto start = std::chrono::steady_clock::now();
    const std::vector<ScanBounds> bounds = bounds_for(view, o);
    const double bounds_seconds = seconds_since(start);
    SceneQueryResult r = answer_light(view, bounds, light, points, n, o);
    r.build_seconds += bounds_seconds;  // one light: its build includes them
    return r;
}

double query_lights_lanes(const AssetView& view, const double* lights, size_t light_count, const double* points,
                          size_t n, const SceneQueryOptions& o,
                          const std::function<void(size_t, const SceneQueryResult&)>& on_light) {
    auto start = std::chrono::steady_clock::now();
    const std::vector<ScanBounds> bounds = light_count ? bounds_for(view, o) : std::vector<ScanBounds>{};
    const double bounds_seconds = seconds_since(start);
    for (size_t l = 0; l < light_count; ++l) on_light(l, answer_light(view, bounds, &lights[l * 3], points, n, o));
    return bounds_seconds;
}

}  // namespace CB_LANES
}  // namespace cb
