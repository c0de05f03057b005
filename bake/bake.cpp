#include "bake.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <numeric>

#include "free_storage.h"
#include "parallel.h"
#include "timing.h"
#include "unset_vector.h"

namespace cb {

namespace {

// The closed-surface check, by ranges [lo, hi) of the edges' lower vertex: every edge whose lower vertex lies
// in the range, listed under that vertex by a counting sort (entries: the other end, shifted, and whether
// the edge leaves the lower vertex), then each vertex's short list checked on its own. Entry is uint32_t
// while vertex numbers fit in 31 bits, halving the largest array of the check.
class EdgeRange {
public:
    EdgeRange(const uint32_t* indices, size_t corners, uint32_t lo, uint32_t hi)
        : indices_(indices), corners_(corners), lo_(lo), hi_(hi) {}

    // Counts the range's edges per vertex; returns how many entries check() takes.
    size_t count() {
        start_.assign(size_t(hi_ - lo_) + 1, 0);
        each_edge([&](uint32_t, uint32_t, uint32_t v) { ++start_[v + 1]; });
        for (size_t v = 0; v + 1 < start_.size(); ++v) start_[v + 1] += start_[v];
        return start_.back();
    }

    // Lists the edges into entry[0, count()) and checks each vertex's list.
    template <class Entry>
    bool check(Entry* entry) {
        std::vector<uint32_t> fill(start_.begin(), start_.end() - 1);
        each_edge([&](uint32_t a, uint32_t b, uint32_t v) { entry[fill[v]++] = Entry(std::max(a, b)) << 1 | (a < b); });
        free_storage(fill);
        for (uint32_t v = 0; v < hi_ - lo_; ++v) {
            Entry* first = entry + start_[v];
            Entry* last = entry + start_[v + 1];
            std::sort(first, last);
            for (Entry* e = first; e < last;) {
                if (*e >> 1 == lo_ + v) {  // loop edge (a, a): its own reverse, so it must appear once
                    if (e + 1 < last && e[1] == e[0]) return false;
                    ++e;
                    continue;
                }
                if (last - e < 2 || (*e & 1) != 0 || e[1] != (*e | 1)) return false;  // both directions, once each
                e += 2;
                if (e < last && *e >> 1 == e[-1] >> 1) return false;  // a third use of the edge
            }
        }
        return true;
    }

private:
    template <class F>
    void each_edge(F&& f) const {
        for (size_t t = 0; t < corners_; t += 3)
            for (int k = 0; k < 3; ++k) {
                uint32_t a = indices_[t + k], b = indices_[t + (k + 1) % 3], low = std::min(a, b);
                if (low >= lo_ && low < hi_) f(a, b, low - lo_);
            }
    }

    const uint32_t* indices_;
    size_t corners_;
    uint32_t lo_, hi_;
    std::vector<uint32_t> start_;  // per vertex of the range, its first entry; then the end
};

}  // namespace

// Every edge used exactly twice, once in each direction: a closed, consistently wound surface, on which
// one-sided and two-sided shadows agree for points outside the solid. Linear, and split over threads by
// ranges of the edges' lower vertex, each range read from the whole index array and checked on its own.
// The ranges' entries, one per corner in all, go to `scratch` when it is given and vertex numbers fit in 31
// bits, each range after the ones before it.
bool is_closed(const uint32_t* indices, size_t corners, size_t vertices, unsigned threads, uint32_t* scratch) {
    if (corners == 0) return false;
    const size_t parts = std::min<size_t>(threads_or_all(threads), std::max<size_t>(1, corners / 30000));
    std::vector<EdgeRange> ranges;
    for (size_t p = 0; p < parts; ++p)
        ranges.emplace_back(indices, corners, uint32_t(vertices * p / parts), uint32_t(vertices * (p + 1) / parts));
    std::vector<size_t> first(parts + 1, 0);
    parallel_for(parts, unsigned(parts), [&](size_t p) { first[p + 1] = ranges[p].count(); });
    for (size_t p = 0; p < parts; ++p) first[p + 1] += first[p];
    const bool narrow = vertices < (size_t(1) << 31);
    std::atomic<bool> closed{true};
    parallel_for(parts, unsigned(parts), [&](size_t p) {
        const size_t n = first[p + 1] - first[p];
        bool ok;
        if (narrow && scratch) {
            ok = ranges[p].check(scratch + first[p]);
        } else if (narrow) {
            UnsetVector<uint32_t> entry(n);
            ok = ranges[p].check(entry.data());
        } else {
            UnsetVector<uint64_t> entry(n);
            ok = ranges[p].check(entry.data());
        }
        if (!ok) closed = false;
    });
    return closed;
}

bool is_closed(const Mesh& mesh) { return is_closed(mesh.indices.data(), mesh.indices.size(), mesh.vertex_count(), 1); }

namespace {

// A clustered mesh's triangles (the hierarchy's corners, taken), sidedness following each triangle to its
// place (its positions and closed flag are set apart).
void order_triangles(const Mesh& mesh, Hierarchy& h, AssetMesh& out) {
    const size_t n = h.order.size();
    out.triangles = std::move(h.corners);
    bool any = std::any_of(mesh.primitives.begin(), mesh.primitives.end(),
                           [](const Primitive& p) { return p.double_sided && p.triangle_count; });
    if (any) {
        std::vector<uint8_t> sided(mesh.triangle_count(), 0);
        for (const Primitive& p : mesh.primitives)
            if (p.double_sided) std::fill_n(sided.begin() + p.first_triangle, p.triangle_count, 1);
        out.double_sided.resize(n);
        for (size_t i = 0; i < n; ++i) out.double_sided[i] = sided[h.order[i]];
    }
    out.flags = any ? uint32_t(mesh_has_double_sided) : 0u;
    for (size_t f = 0; f < h.fine_count(); ++f)
        out.fine.push_back({h.fine_offsets[f], h.fine_offsets[f + 1] - h.fine_offsets[f]});
    for (size_t c = 0; c < h.coarse_count(); ++c)
        out.coarse.push_back({h.coarse_offsets[c], h.coarse_offsets[c + 1] - h.coarse_offsets[c]});
}

// The closed flag, from the clustered triangles (the same set as the mesh's, so the same answer). `scratch`:
// one value per corner that the check may overwrite (the mesh's own indices, done with), or null.
void flag_closed(AssetMesh& out, unsigned threads, uint32_t* scratch) {
    if (is_closed(out.triangles.data(), out.triangles.size(), out.positions.size() / 3, threads, scratch))
        out.flags |= mesh_closed;
}

// cluster_scene's work; with `release` (the same scene), each mesh's positions move into its clustered mesh
// and its other arrays are freed once it is clustered.
std::vector<AssetMesh> cluster_meshes(const Scene& scene, Scene* release, const ClusterOptions& options,
                                      BakeStats& stats,
                                      const std::function<void(size_t, size_t, size_t, size_t)>& progress,
                                      unsigned threads) {
    auto start = std::chrono::steady_clock::now();
    std::vector<AssetMesh> meshes;
    stats = BakeStats{};
    stats.fine_min = stats.coarse_min = UINT32_MAX;
    double acmr_before = 0, acmr_after = 0;
    for (size_t m = 0; m < scene.meshes.size(); ++m) {
        const Mesh& mesh = scene.meshes[m];
        ClusterStats cs;
        auto report = [&](size_t done, size_t total) {
            if (progress) progress(m, scene.meshes.size(), done, total);
        };
        Hierarchy h = build_hierarchy(mesh.positions.data(), mesh.vertex_count(), mesh.indices.data(),
                                      mesh.triangle_count(), options, &cs, report, threads);
        const size_t triangles = mesh.triangle_count();
        AssetMesh am;
        order_triangles(mesh, h, am);
        h = Hierarchy{};
        if (release) {
            Mesh& owned = release->meshes[m];
            am.positions = std::move(owned.positions);
            flag_closed(am, threads, owned.indices.data());
            free_storage(owned.indices);
            free_storage(owned.primitives);
        } else {
            am.positions = mesh.positions;
            flag_closed(am, threads, nullptr);
        }
        stats.triangles += triangles;
        stats.fine_clusters += am.fine.size();
        stats.coarse_clusters += am.coarse.size();
        stats.fine_below_half += cs.fine_below_half;
        acmr_before += cs.acmr_before * double(triangles);
        acmr_after += cs.acmr_after * double(triangles);
        for (const ClusterRange& f : am.fine) {
            stats.fine_min = std::min(stats.fine_min, f.count);
            stats.fine_max = std::max(stats.fine_max, f.count);
        }
        for (const ClusterRange& c : am.coarse) {
            uint32_t tris = 0;
            for (uint32_t f = c.first; f < c.first + c.count; ++f) tris += am.fine[f].count;
            stats.coarse_min = std::min(stats.coarse_min, tris);
            stats.coarse_max = std::max(stats.coarse_max, tris);
        }
        meshes.push_back(std::move(am));
    }
    if (stats.fine_clusters == 0) stats.fine_min = 0;
    if (stats.coarse_clusters == 0) stats.coarse_min = 0;
    if (stats.triangles) {
        stats.acmr_before = acmr_before / double(stats.triangles);
        stats.acmr_after = acmr_after / double(stats.triangles);
    }
    stats.cluster_seconds = seconds_since(start);
    return meshes;
}

}  // namespace

std::vector<AssetMesh> cluster_scene(const Scene& scene, const ClusterOptions& options, BakeStats& stats,
                                     const std::function<void(size_t, size_t, size_t, size_t)>& progress,
                                     unsigned threads) {
    return cluster_meshes(scene, nullptr, options, stats, progress, threads);
}

std::vector<AssetMesh> cluster_scene_releasing(Scene& scene, const ClusterOptions& options, BakeStats& stats,
                                               const std::function<void(size_t, size_t, size_t, size_t)>& progress,
                                               unsigned threads) {
    return cluster_meshes(scene, &scene, options, stats, progress, threads);
}

void size_scene_bounds(std::vector<AssetMesh>& meshes, const BoundsOptions& options) {
    // Arrays already in shape are not touched: an AssetWriter may be reading where they are meanwhile.
    auto size = [](auto& array, bool fitted, size_t n) {
        if (fitted && array.size() != n)
            array.resize(n);
        else if (!fitted && array.capacity() > 0)
            std::vector<typename std::decay_t<decltype(array)>::value_type>().swap(array);
    };
    for (AssetMesh& am : meshes)
        for (bool fine : {true, false}) {
            LevelVolumes& v = fine ? am.fine_volumes : am.coarse_volumes;
            const size_t n = fine ? am.fine.size() : am.coarse.size();
            size(v.obbs, options.mask & (bounds_obb | bounds_cone), n);  // cones are stored relative to boxes
            size(v.spheres, options.mask & bounds_sphere, n);
            size(v.capsules, options.mask & bounds_capsule, n);
            size(v.cones, options.mask & bounds_cone, n);
            size(v.slabs, options.mask & bounds_slab, n);
        }
}

void fit_scene_bounds(std::vector<AssetMesh>& meshes, const BoundsOptions& options, unsigned threads, BakeStats& stats,
                      const std::function<void(size_t, size_t)>& progress) {
    auto start = std::chrono::steady_clock::now();
    // One work item per cluster: (mesh, level, index, first triangle, triangle count). Each writes its own
    // slots of its level's arrays, sized beforehand: nothing is gathered afterwards, and the result does not
    // depend on which thread fitted what.
    struct Item {
        uint32_t mesh, fine, index, first, count;
    };
    // Coarse clusters first: the largest items, so that none is left alone for one thread at the end.
    std::vector<Item> items;
    size_t item_count = 0;  // sized once: growing by copies would take fresh pages twice over (170 MB at 100 M)
    for (const AssetMesh& am : meshes) item_count += am.coarse.size() + am.fine.size();
    items.reserve(item_count);
    for (uint32_t m = 0; m < meshes.size(); ++m) {
        AssetMesh& am = meshes[m];
        for (uint32_t c = 0; c < am.coarse.size(); ++c) {
            const ClusterRange& r = am.coarse[c];
            uint32_t first = am.fine[r.first].first,
                     last = am.fine[r.first + r.count - 1].first + am.fine[r.first + r.count - 1].count;
            items.push_back({m, 0, c, first, last - first});
        }
    }
    for (uint32_t m = 0; m < meshes.size(); ++m) {
        AssetMesh& am = meshes[m];
        for (uint32_t f = 0; f < am.fine.size(); ++f) items.push_back({m, 1, f, am.fine[f].first, am.fine[f].count});
    }
    size_scene_bounds(meshes, options);
    uint32_t largest = 0;
    size_t total = 0;
    for (const Item& it : items) {
        largest = std::max(largest, it.count);
        total += it.count;
    }
    // Triangles are already in cluster order: a cluster's are [first, first + count) of its mesh, read
    // through these ids from its first triangle on.
    std::vector<uint32_t> ids(largest);
    std::iota(ids.begin(), ids.end(), 0u);
    // Items go to the threads in blocks, and the counters are summed per block: one shared atomic per
    // item, on a line both cores write, costs as much as fitting a fine cluster.
    constexpr size_t block = 64;
    std::atomic<size_t> done{0};
    std::atomic<uint64_t> valid_cones{0}, capsules{0};
    std::mutex reporting;  // one report at a time; a worker finding it taken goes on
    parallel_for((items.size() + block - 1) / block, threads, [&](size_t b) {
        size_t block_done = 0;
        uint64_t block_cones = 0, block_capsules = 0;
        for (size_t i = b * block; i < std::min(items.size(), (b + 1) * block); ++i) {
            const Item& it = items[i];
            AssetMesh& am = meshes[it.mesh];
            ClusterBounds fitted = fit_bounds(am.positions.data(), am.triangles.data() + size_t(it.first) * 3,
                                              ids.data(), it.count, options, am.positions.size() / 3);
            LevelVolumes& v = it.fine ? am.fine_volumes : am.coarse_volumes;
            if (!v.obbs.empty()) v.obbs[it.index] = fitted.packed_obb;
            if (!v.spheres.empty()) v.spheres[it.index] = fitted.sphere;
            if (!v.capsules.empty()) v.capsules[it.index] = fitted.capsule;
            if (!v.cones.empty()) v.cones[it.index] = fitted.packed_cone;
            if (!v.slabs.empty()) v.slabs[it.index] = fitted.slab;
            block_cones += fitted.cone.valid;
            block_capsules += fitted.has_capsule;
            block_done += it.count;
        }
        valid_cones += block_cones;
        capsules += block_capsules;
        done.fetch_add(block_done);
        if (progress && reporting.try_lock()) {
            progress(done.load(), total);  // read under the lock: the reports rise
            reporting.unlock();
        }
    });
    if (progress) progress(total, total);  // the last, whichever worker finished last
    stats.valid_cones += valid_cones.load();
    stats.capsules += capsules.load();
    stats.fit_seconds = seconds_since(start);
}

}  // namespace cb
