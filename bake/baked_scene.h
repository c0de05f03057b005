// A bake held in memory rather than written: a scene file clustered and fitted here, or an asset file
// decoded back (io/asset_decode.h) with any bounding volume asked for and not stored fitted here. What the
// statistics, the report and the heat map start from.
#pragma once

#include <string>

#include "asset_content.h"
#include "bake.h"
#include "load.h"

namespace cb {

// Clusters and fits the scene in memory (the same calls as `clusterbake bake`) on `threads` threads (0 =
// all), reporting to `progress`.
BakedScene bake_in_memory(const Scene& scene, const ClusterOptions& clustering, const BoundsOptions& bounds,
                          BakeStats* stats = nullptr, const BakeProgress& progress = {}, unsigned threads = 0);

// A scene file (clustered and fitted with the options) or an asset (its clusters and stored volumes as they
// are; the kinds in bounds.mask it does not hold are fitted with `bounds`). A scene file is loaded as `load`
// allows. Throws std::runtime_error with a one-line message naming the file.
BakedScene load_baked(const std::string& path, const ClusterOptions& clustering, const BoundsOptions& bounds,
                      std::string* fitted_note = nullptr, const BakeProgress& progress = {},
                      const LoadOptions& load = {}, unsigned threads = 0);

// An opened asset decoded back (its clusters and stored volumes as they are), with the kinds in bounds.mask
// it does not hold fitted with `bounds`, as load_baked does for an asset file; `fitted_note` says which.
BakedScene baked_from_asset(const AssetView& view, const BoundsOptions& bounds, std::string* fitted_note = nullptr,
                            const BakeProgress& progress = {}, unsigned threads = 0);

}  // namespace cb
