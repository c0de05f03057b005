// Test helper: a scene clustered, fitted and encoded in memory, then opened as the runtime opens a file.
#pragma once

#include <cb_asset.h>
#include <cb_segment.h>

#include <string>
#include <vector>

#include "asset_file.h"
#include "bake.h"
#include "load.h"

namespace cb::test {

// The bytes and their view (empty when the bytes did not open: tests check mesh_count), and the scene.
struct Baked : cb::LoadedAsset {
    cb::Scene scene;  // what was baked: oracles built from it do not depend on the encoding
};

// `fine_bounds` false drops the fine level's volumes before encoding, leaving the coarse ones: an asset the
// tools never write, but a hand-made file may be.
inline Baked bake_scene(const cb::Scene& scene, const cb::ClusterOptions& clustering = {},
                        uint32_t bounds = cb::bounds_auto, unsigned threads = 0, bool fine_bounds = true) {
    cb::BakeStats stats;
    std::vector<cb::AssetMesh> meshes = cb::cluster_scene(scene, clustering, stats);
    cb::BoundsOptions b;
    b.mask = bounds;
    cb::fit_scene_bounds(meshes, b, threads, stats);
    if (!fine_bounds)
        for (cb::AssetMesh& m : meshes) m.fine_volumes = {};
    std::vector<uint8_t> bytes = cb::encode_asset(meshes, scene.instances);
    Baked out;
    cb::open_asset_copy(bytes, out);
    out.scene = scene;
    return out;
}

inline Baked bake(const std::string& file) { return bake_scene(cb::load_scene(file)); }

// The self-shadowing bias an InstanceShadow of the asset takes by default (ShadowBuildOptions::bias zero),
// worked out once: tests give it to their builds and to the oracle.
inline double asset_bias(const cb::AssetView& v) { return cb::default_shadow_bias(cb::asset_world_size(v)); }

}  // namespace cb::test
