// The pipeline from a loaded Scene to asset bytes: cluster every mesh once (instances share it), then
// encode. Sits above io/ and cluster/ so neither needs the other; the CLI only calls this.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "asset_writer.h"
#include "bounds.h"
#include "cluster.h"
#include "scene.h"

namespace cb {

struct BakeStats {
    uint64_t triangles = 0, fine_clusters = 0, coarse_clusters = 0, fine_below_half = 0;
    uint32_t fine_min = 0, fine_max = 0;      // triangles per fine cluster
    uint32_t coarse_min = 0, coarse_max = 0;  // triangles per coarse cluster
    double acmr_before = 0, acmr_after = 0;   // triangle-weighted over meshes (vco only)
    double cluster_seconds = 0;
    double fit_seconds = 0;
    uint64_t valid_cones = 0, capsules = 0;  // fine and coarse clusters together
};

// Every edge used exactly twice, once in each direction (a closed, consistently wound surface): the
// triangles indices[0..corners) over `vertices` vertices, checked on `threads` threads (0 = all). `scratch`,
// when given, holds `corners` values that the check overwrites, in place of arrays of its own.
bool is_closed(const uint32_t* indices, size_t corners, size_t vertices, unsigned threads, uint32_t* scratch = nullptr);
bool is_closed(const Mesh& mesh);

// Clusters every mesh of the scene on `threads` threads (0 = all); the result does not depend on the count.
// `progress(mesh, mesh_count, chunk, chunk_count)` when set.
std::vector<AssetMesh> cluster_scene(const Scene& scene, const ClusterOptions& options, BakeStats& stats,
                                     const std::function<void(size_t, size_t, size_t, size_t)>& progress = {},
                                     unsigned threads = 0);

// The same, for a bake that needs the scene's geometry no longer: each mesh's positions move into its
// clustered mesh, and its indices, once it is clustered, serve the closed-surface check as scratch and are
// freed. The scene keeps its instances, names and report.
std::vector<AssetMesh> cluster_scene_releasing(Scene& scene, const ClusterOptions& options, BakeStats& stats,
                                               const std::function<void(size_t, size_t, size_t, size_t)>& progress = {},
                                               unsigned threads = 0);

// Fits the volumes in options.mask for every fine and coarse cluster of every mesh, in parallel over
// clusters (`threads`, 0 = all); the result does not depend on the thread count. `progress(done, total)`,
// when set, counts the triangles of the clusters fitted so far (a coarse cluster's count again), called
// from one thread at a time with rising counts, and last with done == total.
void fit_scene_bounds(std::vector<AssetMesh>& meshes, const BoundsOptions& options, unsigned threads, BakeStats& stats,
                      const std::function<void(size_t, size_t)>& progress = {});

// Sizes every mesh's volume arrays to its clusters for the kinds `options` fits and empties the others, as
// fit_scene_bounds does first: an asset can then be laid out before they are filled (AssetWriter). Sized
// again for the same clusters and options, the arrays stay where they are.
void size_scene_bounds(std::vector<AssetMesh>& meshes, const BoundsOptions& options);

// What a bake reports as it goes, each when set: cluster_scene's and fit_scene_bounds's progress.
struct BakeProgress {
    std::function<void(size_t, size_t, size_t, size_t)> clustering;
    std::function<void(size_t, size_t)> bounds;
};

}  // namespace cb
