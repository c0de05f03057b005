// libFuzzer target for the runtime's asset reader: open_asset must reject any corruption with an error
// code and, when it accepts, every range it vouched for must be readable (AddressSanitizer watches).
#include <cb_asset.h>
#include <cb_instance_shadow.h>
#include <cb_cull.h>
#include <cb_level.h>

#include <cstddef>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

namespace {

volatile float sink;

// Reads every value the view's records point at, as a consumer would.
void walk(const cb::AssetView& v) {
    float acc = 0;
    for (uint32_t m = 0; m < v.mesh_count; ++m) {
        const cb::MeshRecord& r = v.meshes[m];
        for (uint32_t f = 0; f < r.fine_count; ++f) {
            const cb::FineCluster& c = v.fine[r.first_fine + f];
            for (uint32_t t = c.first_triangle; t < c.first_triangle + c.triangle_count; ++t) {
                uint32_t id[3];
                v.triangle(r, f, t, id);
                for (int k = 0; k < 3; ++k) acc += v.position(r, id[k])[0];
            }
            if (v.fine_bounds.obbs) acc += v.fine_bounds.obb(r.first_fine + f).half[2];
            if (v.fine_bounds.cones) acc += v.fine_bounds.cone(r.first_fine + f).axis[2];
        }
        for (uint32_t c = 0; c < r.coarse_count; ++c) {
            const cb::ClusterRange& range = v.coarse[r.first_coarse + c];
            acc += float(v.fine[r.first_fine + range.first + range.count - 1].triangle_count);
            if (v.coarse_bounds.spheres) acc += v.coarse_bounds.spheres[r.first_coarse + c].radius;
        }
    }
    for (uint32_t i = 0; i < v.instance_count; ++i) acc += float(v.instances[i].transform[11]);
    sink = acc;
}

// What a consumer does next with an accepted asset: a shadow tree per instance (first few), in each tree
// structure and both sidedness modes, a few queries one by one and as a batch (tiles, including points at
// the light, not finite, or in opposite directions), the same through a level, for a sun too, and culling;
// none may read outside what open_asset vouched for.
void query(const cb::AssetView& v) {
    const double light[3] = {0.3, 2.5, -1.7},
                 points[4][3] = {{0, 0, 0}, {0.5, -0.25, 0.125}, {-3, 1, 2}, {0.3, 2.5, -1.7}};
    std::vector<double> batch;
    for (int k = 0; k < 70; ++k)
        batch.insert(batch.end(), {std::sin(k * 0.7) * (k % 5), std::cos(k * 0.3) * 2.0, 0.1 * k - 3.0});
    batch.insert(batch.end(), {light[0], light[1], light[2], NAN, 0.0, 1.0, INFINITY, 1.0, 0.0});
    const size_t n = batch.size() / 3;
    std::vector<uint8_t> shadow(n);
    for (int variant = 0; variant < 3; ++variant) {  // scan two-sided, fine trees one-sided, one tree
        cb::ShadowBuildOptions options;
        options.traversal = cb::Traversal(variant);
        options.one_sided = variant == 1;
        std::vector<cb::InstanceShadow> trees(std::min<uint32_t>(v.instance_count, 4));
        for (uint32_t i = 0; i < trees.size(); ++i) {
            trees[i].build(v, i, light, options);
            std::vector<uint32_t> stack(trees[i].stack_size());
            for (const double* p : points) sink = sink + float(trees[i].occluded(p, stack.data()));
        }
        std::vector<uint32_t> scratch(cb::batch_scratch_size(trees.data(), trees.size(), n));
        cb::occluded_batch(trees.data(), trees.size(), batch.data(), n, shadow.data(), scratch.data());
        for (uint8_t o : shadow) sink = sink + float(o);
    }
    // The same batch through a level of the asset's instances: its hierarchy and per-tile culling over the
    // asset's bounds, whatever they hold.
    cb::Level level;
    level.add_baked(level.add_asset(v));
    level.commit();
    cb::LevelShadow through_level;
    through_level.occluded_batch(level, light, batch.data(), n, shadow.data());
    for (uint8_t o : shadow) sink = sink + float(o);
    // And a sun (its own traversal, prisms along the direction), the light's position taken as a direction.
    through_level.occluded_sun_batch(level, light, batch.data(), n, shadow.data());
    for (uint8_t o : shadow) sink = sink + float(o);
    for (const double* p : points) sink = sink + float(cb::occluded_sun_reference(v, p, light, 0.0));
    for (const double* p : points) sink = sink + float(cb::occluded_reference(v, p, light, 0.0));
    cb::Frustum f{};
    f.count = 1;
    f.plane[0][0] = 1;
    f.plane[0][3] = 1;
    f.eye[0] = -2;
    cb::VisibleCluster out[16];
    sink = sink + float(cb::cull_clusters(v, f, true, out, 16));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    // The view wants 8-byte alignment (instance doubles); give it an exactly sized, aligned copy so
    // AddressSanitizer sees any read past the end.
    std::vector<uint64_t> storage((size + 7) / 8);
    if (size) std::memcpy(storage.data(), data, size);
    cb::AssetView view;
    if (cb::open_asset(storage.data(), size, &view) == cb::AssetError::ok) walk(view), query(view);
    // Again with the checksum made right, so mutations reach the structural checks behind it.
    if (size >= sizeof(cb::AssetHeader)) {
        uint8_t* bytes = reinterpret_cast<uint8_t*>(storage.data());
        uint64_t sum = cb::asset_checksum(bytes, size);
        std::memcpy(bytes + offsetof(cb::AssetHeader, checksum), &sum, 8);
        if (cb::open_asset(storage.data(), size, &view) == cb::AssetError::ok) walk(view), query(view);
    }
    return 0;
}
