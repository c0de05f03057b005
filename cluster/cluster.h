// Two-level triangle clustering of one mesh: coarse clusters (at most `coarse_size` triangles) each split
// into fine clusters (at most `fine_size` triangles), by Morton order, hierarchical k-means++ over triangle
// boxes, or Forsyth vertex-cache order cut into connected patches. With k-means the coarse clusters are
// the top of the same trees (compact: a Morton chunk can be two distant pieces); otherwise Morton chunks.
//
// Pure functions over flat arrays: positions are xyz floats, indices 3 per triangle. The output is a
// permutation of the triangles plus two levels of ranges over it, identical for any thread count.
#pragma once

#include <cb_asset.h>  // max_cluster_vertices

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "unset_vector.h"

namespace cb {

// The most triangles a fine cluster may hold: even with no corner shared, its vertices fit the asset's 8-bit
// local indices (85 triangles, 255 corners).
constexpr uint32_t max_fine_size = max_cluster_vertices / 3;

enum class ClusterMethod { kmeans, vco, morton };

const char* method_name(ClusterMethod m);
bool parse_method(const std::string& name, ClusterMethod& out);

struct ClusterOptions {
    ClusterMethod method = ClusterMethod::kmeans;
    uint32_t coarse_size = 2048;    // maximum triangles per coarse cluster (Morton chunks hold exactly this many)
    uint32_t fine_size = 16;        // hard maximum triangles per fine cluster
    uint32_t kmeans_branching = 8;  // k0: children per k-means node
    uint32_t kmeans_max_iterations = 16;
    bool kmeans_coarse_from_tree = true;  // coarse level from the top of the k-means trees, not Morton chunks
    uint32_t kmeans_presplit = 65536;     // the trees grow in Morton chunks of this many triangles, in parallel
                                          // (0: one tree over the whole mesh, on one thread)
    uint32_t vco_cache_size = 32;
    uint64_t seed = 1;
};

// The rules ClusterOptions must keep, each an error of its own; checked in this order.
enum class ClusterOptionsError {
    none,
    fine_size_zero,               // fine_size must be at least 1
    fine_size_above_max,          // fine_size must be at most max_fine_size
    coarse_size_zero,             // coarse_size must be at least 1
    coarse_size_below_fine_size,  // coarse_size must be at least fine_size
    kmeans_branching_below_two,   // a k-means node needs two children
    vco_cache_size_below_three,   // the vertex cache must hold a triangle's corners
};

// The first rule `options` breaks, or none. build_hierarchy refuses options that break one; a caller checks
// them before any work.
ClusterOptionsError check_options(const ClusterOptions& options);

// The broken rule in one line ("coarse_size must be at least fine_size"), empty for none. Each field is
// named by `name` when set (a command line names it by its flag), by its own name otherwise.
std::string describe(ClusterOptionsError error, const std::function<std::string(const char* field)>& name = {});

// Ranges: fine cluster f holds triangles order[fine_offsets[f] .. fine_offsets[f+1]); coarse cluster c holds
// fine clusters [coarse_offsets[c] .. coarse_offsets[c+1]), whose triangles are contiguous in `order`.
struct Hierarchy {
    UnsetVector<uint32_t> order;           // triangle permutation: position -> original triangle index
    std::vector<uint32_t> fine_offsets;    // fine cluster count + 1 entries, into `order`
    std::vector<uint32_t> coarse_offsets;  // coarse cluster count + 1 entries, into fine clusters
    // The triangles' corners (3 per triangle) in `order`. A std::vector, zeroed when sized unlike `order`,
    // because it becomes the asset's triangles (AssetMesh::triangles) by a move, without a copy.
    std::vector<uint32_t> corners;

    size_t fine_count() const { return fine_offsets.empty() ? 0 : fine_offsets.size() - 1; }
    size_t coarse_count() const { return coarse_offsets.empty() ? 0 : coarse_offsets.size() - 1; }
};

struct ClusterStats {
    uint64_t fine_below_half = 0;  // fine clusters with fewer than fine_size / 2 triangles
    double acmr_before = 0;        // FIFO cache of vco_cache_size over the input order (vco only)
    double acmr_after = 0;         // ... and over the clustered order
};

// On `threads` worker threads (0: all hardware threads); the result is the same for any count. `progress`,
// when set, is called with (chunks done, chunk count) from the calling thread. Throws
// std::invalid_argument with describe()'s line, before any work, when check_options finds a broken rule.
Hierarchy build_hierarchy(const float* positions, size_t vertex_count, const uint32_t* indices, size_t triangle_count,
                          const ClusterOptions& options, ClusterStats* stats = nullptr,
                          const std::function<void(size_t, size_t)>& progress = {}, unsigned threads = 0);

// ---- the building blocks, exposed for tests and benchmarks

// Triangle indices sorted by the 63-bit Morton code of each triangle's box centre within the mesh bounds;
// ties keep input order. The same for any thread count (0: all hardware threads). `scratch`, when given, is
// sort_keys's.
UnsetVector<uint32_t> morton_order(const float* positions, const uint32_t* indices, size_t triangle_count,
                                   unsigned threads = 1, uint32_t* scratch = nullptr);

// Sorts the n keys stably in place; order[i] gets the input index of the key that ends at i. The same for
// any thread count (0: all hardware threads). `scratch`: room for 3 n values, 8-byte aligned, that the sort
// overwrites (a caller's array that is filled afterwards lends its pages); without it, the sort takes its own.
void sort_keys(uint64_t* keys, uint32_t* order, size_t n, unsigned threads = 1, uint32_t* scratch = nullptr);

// Hierarchical k-means++ over the triangles `tris` (reordered in place) with at most `max_size` per leaf;
// appends the leaf sizes to `leaf_sizes` in order. `boxes` holds 6 floats (min xyz, max xyz) per triangle.
void kmeans_split(const float* boxes, uint32_t* tris, size_t count, uint32_t max_size, uint32_t branching,
                  uint32_t max_iterations, uint64_t seed, std::vector<uint32_t>& leaf_sizes);

// Forsyth's linear-speed vertex cache optimisation: a new order of the triangles (indices into the input).
std::vector<uint32_t> forsyth_order(const uint32_t* indices, size_t triangle_count, size_t vertex_count,
                                    uint32_t cache_size);

// Average cache miss ratio (misses per triangle) of a FIFO cache of `cache_size` vertices.
double fifo_acmr(const uint32_t* indices, size_t triangle_count, size_t vertex_count, uint32_t cache_size);

// Splits consecutive triangles `tris[0..count)` into connected patches (sharing a vertex), stable within
// each patch; reorders `tris` so each patch is contiguous and appends the patch sizes.
void connected_patches(const uint32_t* indices, uint32_t* tris, size_t count, std::vector<uint32_t>& patch_sizes);

}  // namespace cb
