#include "asset_decode.h"

#include <string>

namespace cb {
namespace {

template <class T>
void copy_records(const T* all, uint32_t first, uint32_t count, std::vector<T>& out) {
    if (all) out.assign(all + first, all + first + count);
}

void copy_level(const LevelBounds& level, uint32_t first, uint32_t count, LevelVolumes& out) {
    copy_records(level.obbs, first, count, out.obbs);
    copy_records(level.spheres, first, count, out.spheres);
    copy_records(level.capsules, first, count, out.capsules);
    copy_records(level.cones, first, count, out.cones);
    copy_records(level.slabs, first, count, out.slabs);
}

}  // namespace

BakedScene baked_scene_from_asset(const AssetView& view) {
    BakedScene out;
    for (uint32_t m = 0; m < view.mesh_count; ++m) {
        const MeshRecord& r = view.meshes[m];
        AssetMesh mesh;
        mesh.positions.assign(view.positions + size_t(r.first_vertex) * 3,
                              view.positions + size_t(r.first_vertex + r.vertex_count) * 3);
        // Local indices back to mesh-wide ones, cluster by cluster.
        for (uint32_t f = 0; f < r.fine_count; ++f) {
            const FineCluster& c = view.fine[r.first_fine + f];
            for (uint32_t t = c.first_triangle; t < c.first_triangle + c.triangle_count; ++t) {
                uint32_t id[3];
                view.triangle(r, f, t, id);
                mesh.triangles.insert(mesh.triangles.end(), id, id + 3);
            }
            mesh.fine.push_back({c.first_triangle, c.triangle_count});
        }
        mesh.coarse.assign(view.coarse + r.first_coarse, view.coarse + r.first_coarse + r.coarse_count);
        copy_level(view.fine_bounds, r.first_fine, r.fine_count, mesh.fine_volumes);
        copy_level(view.coarse_bounds, r.first_coarse, r.coarse_count, mesh.coarse_volumes);
        bool any_double = false;
        std::vector<uint8_t> sided(r.triangle_count);
        for (uint32_t t = 0; t < r.triangle_count; ++t)
            any_double |= (sided[t] = view.double_sided(size_t(r.first_triangle) + t)) != 0;
        if (any_double) mesh.double_sided = std::move(sided);
        mesh.flags = view.mesh_flags ? view.mesh_flags[m] : 0;
        out.meshes.push_back(std::move(mesh));
    }
    for (uint32_t i = 0; i < view.instance_count; ++i) {
        Instance inst;
        inst.mesh = view.instances[i].mesh;
        for (int col = 0; col < 4; ++col)
            for (int row = 0; row < 3; ++row)
                inst.world[size_t(col) * 4 + row] = view.instances[i].transform[col * 3 + row];
        inst.node_name = "instance " + std::to_string(i);
        out.instances.push_back(inst);
    }
    return out;
}

}  // namespace cb
