// Statistics read baked meshes, never an asset's encoding: this is the one place that turns an opened asset
// back into the in-memory bake (the same structs cluster_scene and fit_scene_bounds produce). When the
// encoding changes, only asset_input.cpp changes.
#pragma once

#include <cb_asset.h>

#include <vector>

#include "asset_writer.h"
#include "scene.h"

namespace cb {

struct BakedScene {
    std::vector<AssetMesh> meshes;
    std::vector<Instance> instances;
};

// Every mesh with its cluster ranges, the bounds the asset holds, sidedness and flags; every instance.
BakedScene baked_scene_from_asset(const AssetView& view);

}  // namespace cb
