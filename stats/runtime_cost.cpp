#include "runtime_cost.h"

#include <algorithm>

#include "scene_query.h"
#include "timing.h"

namespace cb {

RuntimeCost measure_runtime(const AssetView& view, const std::vector<double>& lights, const std::vector<double>& suns,
                            const std::vector<double>& points, int runs, bool one_sided, Traversal traversal) {
    RuntimeCost cost;
    size_t n = points.size() / 3;
    const uint32_t point_lights = uint32_t(lights.size() / 3);
    cost.lights = point_lights + uint32_t(suns.size() / 3);
    SceneQueryOptions options;
    options.one_sided = one_sided;
    options.traversal = traversal;
    options.threads = 1;  // the rates are per thread
    for (uint32_t l = 0; l < cost.lights; ++l) {
        options.sun = l >= point_lights;
        const double* light = options.sun ? &suns[size_t(l - point_lights) * 3] : &lights[size_t(l) * 3];
        std::vector<double> build_times, query_times;
        for (int r = 0; r < std::max(1, runs); ++r) {
            SceneQueryResult q = query_scene(view, light, points.data(), n, options);
            build_times.push_back(q.build_seconds), query_times.push_back(q.query_seconds);
            if (r == 0) {  // the counts are the same every run
                cost.stats.nodes_visited += q.stats.nodes_visited;
                cost.stats.clusters_tested += q.stats.clusters_tested;
                cost.stats.triangles_tested += q.stats.triangles_tested;
                cost.stats.touching += q.stats.touching;
                for (uint8_t s : q.shadowed) cost.shadowed += s;
            }
        }
        cost.build_seconds += median(build_times) / cost.lights;
        cost.query_seconds += median(query_times) / cost.lights;
        cost.queries += n;
    }
    return cost;
}

std::vector<uint32_t> useless_tests(const AssetView& view, const double* light, const std::vector<double>& points,
                                    bool one_sided, unsigned threads, bool sun) {
    SceneQueryOptions options;
    options.one_sided = one_sided;
    options.sun = sun;
    options.per_point = true;  // the counts are per point
    options.threads = threads;
    SceneQueryResult q = query_scene(view, light, points.data(), points.size() / 3, options);
    std::vector<uint32_t> out(q.shadowed.size());
    for (size_t p = 0; p < out.size(); ++p) out[p] = uint32_t(q.point_stats[p].clusters_tested - q.shadowed[p]);
    return out;
}

}  // namespace cb
