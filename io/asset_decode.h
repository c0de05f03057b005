// The inverse of encode_asset: an opened asset turned back into the structs the writer takes, so that
// statistics read baked meshes, never the encoding. When the encoding changes, only asset_decode.cpp changes.
#pragma once

#include <cb_asset.h>

#include "asset_content.h"

namespace cb {

// Every mesh with its cluster ranges, the bounds the asset holds, sidedness and flags; every instance.
BakedScene baked_scene_from_asset(const AssetView& view);

}  // namespace cb
