#include "baked_scene.h"

#include <stdexcept>

#include "asset_decode.h"
#include "asset_file.h"
#include "load.h"

namespace cb {

BakedScene bake_in_memory(const Scene& scene, const ClusterOptions& clustering, const BoundsOptions& bounds,
                          BakeStats* stats, const BakeProgress& progress, unsigned threads) {
    BakeStats local;
    BakeStats& s = stats ? *stats : local;
    BakedScene out;
    out.meshes = cluster_scene(scene, clustering, s, progress.clustering, threads);
    fit_scene_bounds(out.meshes, bounds, threads, s, progress.bounds);
    out.instances = scene.instances;
    return out;
}

namespace {

// The volume kinds every mesh of the level has.
uint32_t kinds_present(const std::vector<AssetMesh>& meshes) {
    uint32_t mask = bounds_all;
    for (const AssetMesh& m : meshes)
        for (const LevelVolumes* v : {&m.fine_volumes, &m.coarse_volumes}) {
            size_t n = v == &m.fine_volumes ? m.fine.size() : m.coarse.size();
            if (v->obbs.size() != n) mask &= ~uint32_t(bounds_obb);
            if (v->spheres.size() != n) mask &= ~uint32_t(bounds_sphere);
            if (v->capsules.size() != n) mask &= ~uint32_t(bounds_capsule);
            if (v->cones.size() != n) mask &= ~uint32_t(bounds_cone);
            if (v->slabs.size() != n) mask &= ~uint32_t(bounds_slab);
        }
    return mask;
}

std::string mask_text(uint32_t mask) {
    std::string out;
    const char* names[] = {"obb", "sphere", "capsule", "cone", "slab"};
    for (int b = 0; b < 5; ++b)
        if (mask & (1u << b)) out += (out.empty() ? "" : ",") + std::string(names[b]);
    return out;
}

}  // namespace

BakedScene load_baked(const std::string& path, const ClusterOptions& clustering, const BoundsOptions& bounds,
                      std::string* fitted_note, const BakeProgress& progress, const LoadOptions& load,
                      unsigned threads) {
    if (!is_asset_file(path)) {
        Scene scene = load_scene(path, load);  // LoadError is a runtime_error naming the file
        return bake_in_memory(scene, clustering, bounds, nullptr, progress, threads);
    }
    LoadedAsset asset;
    std::string error;
    if (!read_asset_file(path, asset, error)) throw std::runtime_error(error);
    return baked_from_asset(asset.view, bounds, fitted_note, progress, threads);
}

BakedScene baked_from_asset(const AssetView& view, const BoundsOptions& bounds, std::string* fitted_note,
                            const BakeProgress& progress, unsigned threads) {
    BakedScene baked = baked_scene_from_asset(view);
    uint32_t missing = bounds.mask & ~kinds_present(baked.meshes);
    if (missing) {
        // Fit the missing kinds on a copy (fitting replaces every volume) and take only those.
        std::vector<AssetMesh> fitted = baked.meshes;
        BoundsOptions b = bounds;
        b.mask = missing;
        BakeStats ignored;
        fit_scene_bounds(fitted, b, threads, ignored, progress.bounds);
        for (size_t m = 0; m < fitted.size(); ++m)
            for (int level = 0; level < 2; ++level) {
                LevelVolumes& to = level ? baked.meshes[m].coarse_volumes : baked.meshes[m].fine_volumes;
                LevelVolumes& from = level ? fitted[m].coarse_volumes : fitted[m].fine_volumes;
                if (missing & bounds_obb) to.obbs = std::move(from.obbs);
                if (missing & bounds_sphere) to.spheres = std::move(from.spheres);
                if (missing & bounds_capsule) to.capsules = std::move(from.capsules);
                if (missing & bounds_cone) to.cones = std::move(from.cones);
                if (missing & bounds_slab) to.slabs = std::move(from.slabs);
            }
        if (fitted_note) *fitted_note = "the asset has no " + mask_text(missing) + ": fitted here";
    }
    return baked;
}

}  // namespace cb
