// Vertex-cache ordering after Tom Forsyth, "Linear-Speed Vertex Cache Optimisation" (2006), and the FIFO
// cache simulator that measures it.
//
// Each vertex scores by its position in a simulated LRU cache (the three most recent share a flat score, so
// the next triangle is not biased towards one of them; older positions decay with a power law) plus a
// bonus that grows as its remaining valence shrinks (finish off vertices before they leave the cache).
// A triangle scores the sum of its vertices. Greedily emit the best triangle touching the cache; when
// none does, continue from the most recently emitted vertex that still has triangles left (a dead-end
// stack, so the walk stays local), and only when that is empty from the next unemitted one in input order.
#include <algorithm>
#include <cmath>

#include "cluster.h"

namespace cb {
namespace {

// Forsyth's published constants are 1.5, 0.75, 2.0 and 0.5. These come from a grid search for the FIFO-32
// cache the benchmark measures, on some of the shared meshes, checked on others: a lower ACMR than the
// published constants and than meshopt_optimizeVertexCache on all of them (bench_cluster prints the
// comparison; the meshes and figures are in docs/PERFORMANCE.md).
constexpr float decay_power = 0.5f;
constexpr float last_triangle_score = 0.3f;
constexpr float valence_scale = 3.0f;
constexpr float valence_power = 0.5f;
constexpr uint32_t valence_table_size = 64;

}  // namespace

std::vector<uint32_t> forsyth_order(const uint32_t* indices, size_t triangle_count, size_t vertex_count,
                                    uint32_t cache_size) {
    cache_size = std::max(cache_size, 4u);
    std::vector<uint32_t> order;
    order.reserve(triangle_count);
    if (triangle_count == 0) return order;

    // Live triangles of each vertex (compact adjacency; emitted ones are swapped out).
    std::vector<uint32_t> valence(vertex_count, 0), first(vertex_count + 1, 0);
    for (size_t i = 0; i < triangle_count * 3; ++i) ++valence[indices[i]];
    for (size_t v = 0; v < vertex_count; ++v) first[v + 1] = first[v] + valence[v];
    std::vector<uint32_t> adjacency(triangle_count * 3), fill(first.begin(), first.end() - 1);
    for (size_t t = 0; t < triangle_count; ++t)
        for (int k = 0; k < 3; ++k) adjacency[fill[indices[t * 3 + k]]++] = uint32_t(t);

    // Score tables.
    std::vector<float> position_score(cache_size);
    for (uint32_t p = 0; p < cache_size; ++p)
        position_score[p] =
            p < 3 ? last_triangle_score : std::pow(1.0f - float(p - 3) / float(cache_size - 3), decay_power);
    float valence_score[valence_table_size];
    for (uint32_t n = 0; n < valence_table_size; ++n)
        valence_score[n] = n == 0 ? 0 : valence_scale * std::pow(float(n), -valence_power);
    auto vertex_score = [&](uint32_t v, int position) {
        uint32_t live = valence[v];
        if (live == 0) return -1.0f;  // no triangle left to emit: worthless
        float s = position >= 0 ? position_score[size_t(position)] : 0.0f;
        return s +
            (live < valence_table_size ? valence_score[live] : valence_scale * std::pow(float(live), -valence_power));
    };

    std::vector<float> score(vertex_count);
    for (size_t v = 0; v < vertex_count; ++v) score[v] = vertex_score(uint32_t(v), -1);
    std::vector<float> triangle_score(triangle_count);
    std::vector<uint8_t> emitted(triangle_count, 0);
    for (size_t t = 0; t < triangle_count; ++t)
        triangle_score[t] = score[indices[t * 3]] + score[indices[t * 3 + 1]] + score[indices[t * 3 + 2]];

    std::vector<uint32_t> cache, next_cache;
    cache.reserve(cache_size + 3);
    next_cache.reserve(cache_size + 3);
    size_t cursor = 0;               // every triangle before it is emitted
    std::vector<uint32_t> dead_end;  // vertices of emitted triangles, most recent last
    uint32_t best = uint32_t(std::max_element(triangle_score.begin(), triangle_score.end()) - triangle_score.begin());

    while (order.size() < triangle_count) {
        while (best == UINT32_MAX && !dead_end.empty()) {
            uint32_t v = dead_end.back();
            dead_end.pop_back();
            if (valence[v]) best = adjacency[first[v]];
        }
        if (best == UINT32_MAX) {  // nothing local left: the first unemitted triangle in input order
            while (emitted[cursor]) ++cursor;
            best = uint32_t(cursor);
        }
        order.push_back(best);
        emitted[best] = 1;
        const uint32_t* tri = indices + size_t(best) * 3;
        dead_end.insert(dead_end.end(), {tri[0], tri[1], tri[2]});

        // Retire the triangle from its vertices' live lists.
        for (int k = 0; k < 3; ++k) {
            uint32_t v = tri[k];
            uint32_t* live = &adjacency[first[v]];
            uint32_t* end = live + valence[v];
            uint32_t* it = std::find(live, end, best);
            if (it != end) {
                *it = end[-1];
                --valence[v];
            }
        }

        // LRU update: the triangle's vertices to the front, the rest shift back; past cache_size they leave.
        next_cache.clear();
        for (int k = 0; k < 3; ++k)
            if (std::find(next_cache.begin(), next_cache.end(), tri[k]) == next_cache.end())
                next_cache.push_back(tri[k]);
        for (uint32_t v : cache)
            if (v != tri[0] && v != tri[1] && v != tri[2]) next_cache.push_back(v);

        // Rescore every vertex whose position or valence changed, and push the change into its triangles.
        best = UINT32_MAX;
        float best_score = -INFINITY;
        for (size_t p = 0; p < next_cache.size(); ++p) {
            uint32_t v = next_cache[p];
            int position = p < cache_size ? int(p) : -1;
            float s = vertex_score(v, position);
            float delta = s - score[v];
            score[v] = s;
            for (uint32_t i = 0; i < valence[v]; ++i) {
                uint32_t t = adjacency[first[v] + i];
                triangle_score[t] += delta;
                if (triangle_score[t] > best_score) {
                    best_score = triangle_score[t];
                    best = t;
                }
            }
        }
        if (next_cache.size() > cache_size) next_cache.resize(cache_size);
        cache.swap(next_cache);
    }
    return order;
}

double fifo_acmr(const uint32_t* indices, size_t triangle_count, size_t vertex_count, uint32_t cache_size) {
    if (triangle_count == 0) return 0;
    // A vertex is in a FIFO cache when it entered within the last cache_size misses.
    std::vector<uint64_t> entered(vertex_count, 0);
    uint64_t misses = 0;
    for (size_t i = 0; i < triangle_count * 3; ++i) {
        uint32_t v = indices[i];
        if (entered[v] == 0 || misses - entered[v] + 1 > cache_size) {
            ++misses;
            entered[v] = misses;
        }
    }
    return double(misses) / double(triangle_count);
}

}  // namespace cb
