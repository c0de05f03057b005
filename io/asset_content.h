// What an asset holds, as flat per-mesh arrays: what the encoder writes (asset_writer.h) and what an opened
// asset decodes back to (asset_decode.h). A bake makes one (bake/baked_scene.h holds the bakes in memory).
#pragma once

#include <cb_asset.h>

#include <cstdint>
#include <vector>

#include "scene.h"

namespace cb {

// Bounding volumes of one level's clusters; each vector empty, or one record per cluster.
// Boxes and cones in their stored, packed form (decode with unpack_obb / unpack_cone); cones need boxes.
struct LevelVolumes {
    std::vector<PackedObb> obbs;
    std::vector<Sphere> spheres;
    std::vector<Capsule> capsules;
    std::vector<PackedCone> cones;
    std::vector<Slab> slabs;
};

// One mesh before encoding: triangles already in cluster order, ranges mesh-local. The encoder renumbers
// the vertices in order of first use (dropping unused ones) and turns the indices into per-cluster local ones.
struct AssetMesh {
    std::vector<float> positions;      // xyz per vertex
    std::vector<uint32_t> triangles;   // 3 per triangle, in cluster order
    std::vector<ClusterRange> fine;    // tiles the triangles
    std::vector<ClusterRange> coarse;  // tiles the fine clusters
    LevelVolumes fine_volumes, coarse_volumes;
    std::vector<uint8_t> double_sided;  // per triangle in cluster order (empty: all single-sided)
    uint32_t flags = 0;                 // MeshFlags
};

// A whole asset before encoding: what a bake makes (bake/), and what an opened asset decodes back to
// (asset_decode.h).
struct BakedScene {
    std::vector<AssetMesh> meshes;
    std::vector<Instance> instances;
};

}  // namespace cb
