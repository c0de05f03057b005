// The two-level hierarchy: coarse chunks first (Morton order, or the top of the k-means tree), then each
// chunk split into fine clusters independently, in parallel, with a seed that depends only on the chunk.
#include <algorithm>
#include <atomic>
#include <numeric>
#include <stdexcept>
#include <thread>

#include "cluster.h"
#include "parallel.h"
#include "populate_pages.h"
#include "random.h"
#include "unset_vector.h"

namespace cb {

void connected_patches(const uint32_t* indices, uint32_t* tris, size_t count, std::vector<uint32_t>& patch_sizes) {
    // Union-find over the slice; slices are small (fine_size triangles), so the pairwise test is cheap.
    std::vector<uint32_t> parent(count);
    std::iota(parent.begin(), parent.end(), 0u);
    auto root = [&](uint32_t i) {
        while (parent[i] != i) i = parent[i] = parent[parent[i]];
        return i;
    };
    for (size_t i = 0; i < count; ++i)
        for (size_t j = i + 1; j < count; ++j) {
            const uint32_t* a = indices + size_t(tris[i]) * 3;
            const uint32_t* b = indices + size_t(tris[j]) * 3;
            bool shared = false;
            for (int x = 0; x < 3 && !shared; ++x)
                for (int y = 0; y < 3 && !shared; ++y) shared = a[x] == b[y];
            if (shared) parent[root(uint32_t(j))] = root(uint32_t(i));
        }
    // Patches in order of their first triangle; triangles keep their order within a patch.
    std::vector<uint32_t> result;
    result.reserve(count);
    std::vector<uint8_t> taken(count, 0);
    for (size_t i = 0; i < count; ++i) {
        if (taken[i]) continue;
        uint32_t r = root(uint32_t(i));
        size_t before = result.size();
        for (size_t j = i; j < count; ++j)
            if (!taken[j] && root(uint32_t(j)) == r) {
                taken[j] = 1;
                result.push_back(tris[j]);
            }
        patch_sizes.push_back(uint32_t(result.size() - before));
    }
    std::copy(result.begin(), result.end(), tris);
}

namespace {

// k-means over the triangles tris[0..count): their boxes (6 floats each) gathered for this call only, so a
// bake never holds a box per triangle of the mesh at once; `tris` reordered as the tree orders them. The
// arrays stay with the thread for its next call (as k-means's own, kmeans.cpp).
void kmeans_tris(const float* positions, const uint32_t* indices, uint32_t* tris, size_t count, uint32_t max_size,
                 const ClusterOptions& o, uint64_t seed, std::vector<uint32_t>& leaves) {
    thread_local std::vector<float> boxes;
    thread_local std::vector<uint32_t> local;
    boxes.resize(count * 6);
    for (size_t i = 0; i < count; ++i) {
        const uint32_t* t = indices + size_t(tris[i]) * 3;
        const float* a = positions + size_t(t[0]) * 3;
        const float* b = positions + size_t(t[1]) * 3;
        const float* c = positions + size_t(t[2]) * 3;
        for (int k = 0; k < 3; ++k) {
            boxes[i * 6 + k] = std::min({a[k], b[k], c[k]});
            boxes[i * 6 + 3 + k] = std::max({a[k], b[k], c[k]});
        }
    }
    local.resize(count);
    std::iota(local.begin(), local.end(), 0u);
    kmeans_split(boxes.data(), local.data(), count, max_size, o.kmeans_branching, o.kmeans_max_iterations, seed,
                 leaves);
    for (uint32_t& l : local) l = tris[l];
    std::copy(local.begin(), local.end(), tris);
}

// Forsyth order inside one chunk (vertices renumbered locally so the cache state is the chunk's own), then
// slices of fine_size triangles, each cut into connected patches.
void vco_chunk(const uint32_t* indices, uint32_t* tris, size_t count, const ClusterOptions& o,
               std::vector<uint32_t>& sizes) {
    std::vector<uint32_t> local(count * 3), remap_keys;
    remap_keys.reserve(count * 3);
    for (size_t i = 0; i < count; ++i)
        for (int k = 0; k < 3; ++k) remap_keys.push_back(indices[size_t(tris[i]) * 3 + k]);
    std::vector<uint32_t> unique_vertices = remap_keys;
    std::sort(unique_vertices.begin(), unique_vertices.end());
    unique_vertices.erase(std::unique(unique_vertices.begin(), unique_vertices.end()), unique_vertices.end());
    for (size_t i = 0; i < remap_keys.size(); ++i)
        local[i] = uint32_t(std::lower_bound(unique_vertices.begin(), unique_vertices.end(), remap_keys[i]) -
                            unique_vertices.begin());
    std::vector<uint32_t> order = forsyth_order(local.data(), count, unique_vertices.size(), o.vco_cache_size);
    std::vector<uint32_t> reordered(count);
    for (size_t i = 0; i < count; ++i) reordered[i] = tris[order[i]];
    std::copy(reordered.begin(), reordered.end(), tris);
    for (size_t at = 0; at < count; at += o.fine_size)
        connected_patches(indices, tris + at, std::min<size_t>(o.fine_size, count - at), sizes);
}

void split_chunk(const float* positions, const uint32_t* indices, uint32_t* tris, size_t count, size_t chunk,
                 const ClusterOptions& o, std::vector<uint32_t>& sizes) {
    switch (o.method) {
        case ClusterMethod::kmeans:
            kmeans_tris(positions, indices, tris, count, o.fine_size, o, o.seed * 0x9e3779b97f4a7c15ULL + chunk, sizes);
            break;
        case ClusterMethod::vco: vco_chunk(indices, tris, count, o, sizes); break;
        case ClusterMethod::morton:
            for (size_t at = 0; at < count; at += o.fine_size)
                sizes.push_back(uint32_t(std::min<size_t>(o.fine_size, count - at)));
            break;
    }
}

}  // namespace

Hierarchy build_hierarchy(const float* positions, size_t vertex_count, const uint32_t* indices, size_t triangle_count,
                          const ClusterOptions& options, ClusterStats* stats,
                          const std::function<void(size_t, size_t)>& progress, unsigned threads) {
    const ClusterOptionsError error = check_options(options);
    if (error != ClusterOptionsError::none) throw std::invalid_argument(describe(error));
    const ClusterOptions& o = options;
    Hierarchy h;

    // Coarse level. With a Morton order, the triangles' corners are first copied into it (`h.corners`), and
    // both levels work on corners that lie together instead of scattered over the mesh: each k-means call
    // gathers its triangles' boxes from them, and its triangles' corners then move to their new places within
    // its own range of the array, while that range is in cache (`in_place`). `h.order` then holds the mesh's
    // triangles, in the order of the corners.
    std::vector<uint32_t> chunk_sizes;
    const bool in_morton_order =
        !(o.method == ClusterMethod::kmeans && o.kmeans_coarse_from_tree && o.kmeans_presplit == 0);
    if (in_morton_order) {
        // The corners' array is the sort's scatter room first (the same 12 bytes a triangle): its pages are
        // faulted in once, not once for each.
        parallel_resize(h.corners, triangle_count * 3, threads);
        h.order = morton_order(positions, indices, triangle_count, threads, h.corners.data());
        const Parts parts(triangle_count, size_t(1) << 16);
        parallel_for(parts.count(), threads, [&](size_t p) {
            for (size_t i = parts.first(p); i < parts.last(p); ++i)
                std::copy_n(indices + size_t(h.order[i]) * 3, 3, &h.corners[i * 3]);
        });
    }
    // Runs k-means (or the chunk's own method) on the corners [first, first + count) of the Morton order, then
    // moves them, and their triangles in `h.order`, into the order it found.
    auto in_place = [&](size_t first, size_t count, auto&& split) {
        thread_local UnsetVector<uint32_t> local, corners, triangles;
        local.resize(count);
        std::iota(local.begin(), local.end(), uint32_t(first));
        split(local.data());
        corners.assign(h.corners.begin() + std::ptrdiff_t(first * 3),
                       h.corners.begin() + std::ptrdiff_t((first + count) * 3));
        triangles.assign(h.order.begin() + std::ptrdiff_t(first), h.order.begin() + std::ptrdiff_t(first + count));
        for (size_t i = 0; i < count; ++i) {
            const size_t from = local[i] - first;
            std::copy_n(&corners[from * 3], 3, &h.corners[(first + i) * 3]);
            h.order[first + i] = triangles[from];
        }
    };
    if (!in_morton_order) {
        h.order.resize(triangle_count);
        std::iota(h.order.begin(), h.order.end(), 0u);
        kmeans_tris(positions, indices, h.order.data(), triangle_count, o.coarse_size, o, o.seed, chunk_sizes);
    } else if (o.method == ClusterMethod::kmeans && o.kmeans_coarse_from_tree) {
        const size_t part = std::max<size_t>(o.kmeans_presplit, o.coarse_size),
                     parts = (triangle_count + part - 1) / part;
        std::vector<std::vector<uint32_t>> sizes(parts);
        parallel_for(parts, threads, [&](size_t p) {
            const size_t first = p * part, count = std::min(part, triangle_count - first);
            in_place(first, count, [&](uint32_t* tris) {
                kmeans_tris(positions, h.corners.data(), tris, count, o.coarse_size, o, splitmix(o.seed ^ (p + 1)),
                            sizes[p]);
            });
        });
        for (const auto& s : sizes) chunk_sizes.insert(chunk_sizes.end(), s.begin(), s.end());
    } else {
        for (size_t at = 0; at < triangle_count; at += o.coarse_size)
            chunk_sizes.push_back(uint32_t(std::min<size_t>(o.coarse_size, triangle_count - at)));
    }
    std::vector<size_t> chunk_start(chunk_sizes.size() + 1, 0);
    for (size_t c = 0; c < chunk_sizes.size(); ++c) chunk_start[c + 1] = chunk_start[c] + chunk_sizes[c];

    // Fine level: chunks are independent; each writes only its own range and its own size list.
    std::vector<std::vector<uint32_t>> fine(chunk_sizes.size());
    std::atomic<size_t> done{0};
    const std::thread::id caller = std::this_thread::get_id();  // progress is reported from the caller only
    parallel_for(chunk_sizes.size(), threads, [&](size_t c) {
        if (in_morton_order)
            in_place(chunk_start[c], chunk_sizes[c], [&](uint32_t* tris) {
                split_chunk(positions, h.corners.data(), tris, chunk_sizes[c], c, o, fine[c]);
            });
        else
            split_chunk(positions, indices, h.order.data() + chunk_start[c], chunk_sizes[c], c, o, fine[c]);
        size_t finished = done.fetch_add(1) + 1;
        if (progress && std::this_thread::get_id() == caller) progress(finished, chunk_sizes.size());
    });
    if (!in_morton_order) {  // one tree over the mesh's own triangles: their corners gathered into its order
        h.corners.resize(triangle_count * 3);
        const Parts parts(triangle_count, size_t(1) << 16);
        parallel_for(parts.count(), threads, [&](size_t p) {
            for (size_t i = parts.first(p); i < parts.last(p); ++i)
                std::copy_n(indices + size_t(h.order[i]) * 3, 3, &h.corners[i * 3]);
        });
    }

    h.fine_offsets.push_back(0);
    h.coarse_offsets.push_back(0);
    uint64_t below_half = 0;
    for (const auto& sizes : fine) {
        for (uint32_t s : sizes) {
            h.fine_offsets.push_back(h.fine_offsets.back() + s);
            below_half += uint64_t(s) * 2 < o.fine_size;
        }
        h.coarse_offsets.push_back(uint32_t(h.fine_offsets.size() - 1));
    }
    if (stats) {
        stats->fine_below_half = below_half;
        if (o.method == ClusterMethod::vco) {
            std::vector<uint32_t> reordered(triangle_count * 3);
            for (size_t i = 0; i < triangle_count; ++i)
                for (int k = 0; k < 3; ++k) reordered[i * 3 + k] = indices[size_t(h.order[i]) * 3 + k];
            stats->acmr_before = fifo_acmr(indices, triangle_count, vertex_count, o.vco_cache_size);
            stats->acmr_after = fifo_acmr(reordered.data(), triangle_count, vertex_count, o.vco_cache_size);
        }
    }
    return h;
}

}  // namespace cb
