// What `stats`, `report` and `heatmap` start from: a scene file baked in memory, or an asset file read back
// (asset_input.h), with any bounding volume the statistics need and the asset lacks fitted here.
#pragma once

#include <string>

#include "asset_input.h"
#include "bake.h"

namespace cb {

// True when the file starts with the asset magic.
bool is_asset_file(const std::string& path);

// Clusters and fits the scene in memory (the same calls as `clusterbake bake`).
BakedScene bake_in_memory(const Scene& scene, const ClusterOptions& clustering, const BoundsOptions& bounds,
                          BakeStats* stats = nullptr);

// A scene file (clustered and fitted with the options) or an asset (its clusters and stored volumes as they
// are; the kinds in bounds.mask it does not hold are fitted with `bounds`). Throws std::runtime_error with a
// one-line message naming the file.
BakedScene load_baked(const std::string& path, const ClusterOptions& clustering, const BoundsOptions& bounds,
                      std::string* fitted_note = nullptr);

}  // namespace cb
