#include "stats_input.h"

#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>

#include "load.h"

namespace cb {

bool is_asset_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    char magic[8] = {};
    return in.read(magic, 8) && std::memcmp(magic, asset_magic, 8) == 0;
}

BakedScene bake_in_memory(const Scene& scene, const ClusterOptions& clustering, const BoundsOptions& bounds, BakeStats* stats) {
    BakeStats local;
    BakeStats& s = stats ? *stats : local;
    BakedScene out;
    out.meshes = cluster_scene(scene, clustering, s);
    fit_scene_bounds(out.meshes, bounds, clustering.threads, s);
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
                      std::string* fitted_note) {
    if (!is_asset_file(path)) {
        Scene scene = load_scene(path);  // LoadError is a runtime_error naming the file
        return bake_in_memory(scene, clustering, bounds);
    }
    std::ifstream in(path, std::ios::binary);
    std::vector<char> raw((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::vector<uint64_t> storage((raw.size() + 7) / 8);
    std::memcpy(storage.data(), raw.data(), raw.size());
    AssetView view;
    AssetError e = open_asset(storage.data(), raw.size(), &view);
    if (e != AssetError::ok) throw std::runtime_error(path + ": " + asset_error_text(e));
    BakedScene baked = baked_scene_from_asset(view);
    uint32_t missing = bounds.mask & ~kinds_present(baked.meshes);
    if (missing) {
        // Fit the missing kinds on a copy (fitting replaces every volume) and take only those.
        std::vector<AssetMesh> fitted = baked.meshes;
        BoundsOptions b = bounds;
        b.mask = missing;
        BakeStats ignored;
        fit_scene_bounds(fitted, b, clustering.threads, ignored);
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
