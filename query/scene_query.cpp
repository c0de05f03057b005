#include "scene_query.h"

#include <cb_level.h>

#include <algorithm>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <utility>

namespace cb {

using LightCallback = std::function<void(size_t, const SceneQueryResult&)>;

// The builds of the query body (scene_query_lanes.cpp): this unit's own lanes, and where query/CMakeLists.txt
// built them, AVX2's and AVX-512's.
inline namespace CB_LANES {
SceneQueryResult query_level_lanes(const LevelInput&, const double*, const double*, size_t, const SceneQueryOptions&);
double query_lights_lanes(const LevelInput&, const double*, size_t, const double*, size_t, const SceneQueryOptions&,
                          const LightCallback&);
}  // namespace CB_LANES
#if defined(CB_QUERY_LANES_AVX)
namespace lanes_avx {
SceneQueryResult query_level_lanes(const LevelInput&, const double*, const double*, size_t, const SceneQueryOptions&);
double query_lights_lanes(const LevelInput&, const double*, size_t, const double*, size_t, const SceneQueryOptions&,
                          const LightCallback&);
}  // namespace lanes_avx
#endif
#if defined(CB_QUERY_LANES_AVX512)
namespace lanes_avx512 {
SceneQueryResult query_level_lanes(const LevelInput&, const double*, const double*, size_t, const SceneQueryOptions&);
double query_lights_lanes(const LevelInput&, const double*, size_t, const double*, size_t, const SceneQueryOptions&,
                          const LightCallback&);
}  // namespace lanes_avx512
#endif

namespace {

using QueryBody = SceneQueryResult (*)(const LevelInput&, const double*, const double*, size_t,
                                       const SceneQueryOptions&);
using LightsBody = double (*)(const LevelInput&, const double*, size_t, const double*, size_t, const SceneQueryOptions&,
                              const LightCallback&);
struct Lanes {
    const char* name;  // as simd::name
    int rank;          // wider lanes rank higher
    QueryBody body;
    LightsBody lights_body;
};

int lanes_rank(const std::string& name) {
    return name == "avx512" ? 4 : name == "avx2" ? 3 : name == "avx" ? 2 : name == "sse2" ? 1 : 0;
}

#if defined(CB_QUERY_LANES_AVX) || defined(CB_QUERY_LANES_AVX512)
bool cpu_has_avx2() { return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"); }
#endif

// The widest build this processor runs (__builtin_cpu_supports also checks that the operating system saves
// the wider registers), no wider than CLUSTERBAKE_LANES (sse2, avx2 or avx512) when that is set.
Lanes pick_lanes() {
    const Lanes builds[] = {
        {simd::name, lanes_rank(simd::name), &CB_LANES::query_level_lanes, &CB_LANES::query_lights_lanes},
#if defined(CB_QUERY_LANES_AVX)
        {"avx2", cpu_has_avx2() ? 3 : -1, &lanes_avx::query_level_lanes, &lanes_avx::query_lights_lanes},
#endif
#if defined(CB_QUERY_LANES_AVX512)
        {"avx512", cpu_has_avx2() && __builtin_cpu_supports("avx512f") ? 4 : -1, &lanes_avx512::query_level_lanes,
         &lanes_avx512::query_lights_lanes},
#endif
    };
    const char* cap_text = std::getenv("CLUSTERBAKE_LANES");
    int cap = 4;
    if (cap_text && *cap_text) {
        cap = lanes_rank(cap_text);
        if (cap < 1 || cap == 2)
            throw std::runtime_error(std::string("CLUSTERBAKE_LANES=") + cap_text + ": expected sse2, avx2 or avx512");
    }
    const Lanes* best = nullptr;
    for (const Lanes& b : builds)
        if (b.rank >= 0 && b.rank <= cap && (!best || b.rank > best->rank)) best = &b;
    if (!best)
        throw std::runtime_error(std::string("CLUSTERBAKE_LANES=") + cap_text + ": this build's narrowest lanes are " +
                                 simd::name);
    return *best;
}

const Lanes& lanes() {
    static const Lanes picked = pick_lanes();  // once, on first use
    return picked;
}

}  // namespace

bool parse_traversal(const std::string& name, Traversal& out) {
    // The names, then the older spellings of three of them, still read.
    const std::pair<const char*, Traversal> names[] = {
        {"scan", Traversal::scan},         {"top-two", Traversal::top_two},   {"top-one", Traversal::top_one},
        {"mtsv-one", Traversal::mtsv_one}, {"mtsv-two", Traversal::mtsv_two}, {"trees", Traversal::top_two},
        {"one-tree", Traversal::top_one},  {"mtsv", Traversal::mtsv_one}};
    for (const auto& [spelling, traversal] : names)
        if (name == spelling) {
            out = traversal;
            return true;
        }
    return false;
}

const char* traversal_name(Traversal t) {
    switch (t) {
        case Traversal::scan: return "scan";
        case Traversal::top_two: return "top-two";
        case Traversal::top_one: return "top-one";
        case Traversal::mtsv_one: return "mtsv-one";
        case Traversal::mtsv_two: return "mtsv-two";
    }
    return "scan";
}

bool parse_metric_build(const std::string& name, MetricBuild& out) {
    if (name == "heuristic") {
        out = MetricBuild::heuristic;
        return true;
    }
    if (name == "reference") {
        out = MetricBuild::reference;
        return true;
    }
    return false;
}

const char* query_lanes() { return lanes().name; }

void place_baked(LevelInput& level, const AssetView& view, const double* matrix) {
    uint32_t asset = 0;
    while (asset < level.assets.size() && level.assets[asset] != &view) ++asset;
    if (asset == level.assets.size()) level.assets.push_back(&view);
    for (uint32_t i = 0; i < view.instance_count; ++i) {
        LevelInstance placed{asset, view.instances[i].mesh, {}};
        if (matrix)
            compose_instance(matrix, view.instances[i].transform, placed.transform);
        else
            std::copy(view.instances[i].transform, view.instances[i].transform + 12, placed.transform);
        level.instances.push_back(placed);
    }
}

LevelInput baked_level(const AssetView& view) {
    LevelInput level;
    place_baked(level, view);
    return level;
}

SceneQueryResult query_level(const LevelInput& level, const double* light, const double* points, size_t count,
                             const SceneQueryOptions& options) {
    return lanes().body(level, light, points, count, options);
}

SceneQueryResult query_scene(const AssetView& view, const double* light, const double* points, size_t count,
                             const SceneQueryOptions& options) {
    return query_level(baked_level(view), light, points, count, options);
}

double query_level_lights(const LevelInput& level, const double* lights, size_t light_count, const double* points,
                          size_t count, const SceneQueryOptions& options,
                          const std::function<void(size_t light, const SceneQueryResult&)>& on_light) {
    return lanes().lights_body(level, lights, light_count, points, count, options, on_light);
}

}  // namespace cb
