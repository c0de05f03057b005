#include "bake.h"

#include <algorithm>
#include <chrono>

namespace cb {

AssetMesh clustered_mesh(const Mesh& mesh, const Hierarchy& h) {
    AssetMesh out;
    out.positions = mesh.positions;
    out.triangles.resize(h.order.size() * 3);
    for (size_t i = 0; i < h.order.size(); ++i)
        for (int k = 0; k < 3; ++k) out.triangles[i * 3 + k] = mesh.indices[size_t(h.order[i]) * 3 + k];
    for (size_t f = 0; f < h.fine_count(); ++f)
        out.fine.push_back({h.fine_offsets[f], h.fine_offsets[f + 1] - h.fine_offsets[f]});
    for (size_t c = 0; c < h.coarse_count(); ++c)
        out.coarse.push_back({h.coarse_offsets[c], h.coarse_offsets[c + 1] - h.coarse_offsets[c]});
    return out;
}

std::vector<AssetMesh> cluster_scene(const Scene& scene, const ClusterOptions& options, BakeStats& stats,
                                     const std::function<void(size_t, size_t, size_t, size_t)>& progress) {
    auto start = std::chrono::steady_clock::now();
    std::vector<AssetMesh> meshes;
    stats = BakeStats{};
    stats.fine_min = stats.coarse_min = UINT32_MAX;
    double acmr_before = 0, acmr_after = 0;
    for (size_t m = 0; m < scene.meshes.size(); ++m) {
        const Mesh& mesh = scene.meshes[m];
        ClusterStats cs;
        auto report = [&](size_t done, size_t total) {
            if (progress) progress(m, scene.meshes.size(), done, total);
        };
        Hierarchy h = build_hierarchy(mesh.positions.data(), mesh.vertex_count(), mesh.indices.data(),
                                      mesh.triangle_count(), options, &cs, report);
        AssetMesh am = clustered_mesh(mesh, h);
        stats.triangles += mesh.triangle_count();
        stats.fine_clusters += am.fine.size();
        stats.coarse_clusters += am.coarse.size();
        stats.fine_below_half += cs.fine_below_half;
        acmr_before += cs.acmr_before * double(mesh.triangle_count());
        acmr_after += cs.acmr_after * double(mesh.triangle_count());
        for (const ClusterRange& f : am.fine)
            stats.fine_min = std::min(stats.fine_min, f.count), stats.fine_max = std::max(stats.fine_max, f.count);
        for (const ClusterRange& c : am.coarse) {
            uint32_t tris = 0;
            for (uint32_t f = c.first; f < c.first + c.count; ++f) tris += am.fine[f].count;
            stats.coarse_min = std::min(stats.coarse_min, tris), stats.coarse_max = std::max(stats.coarse_max, tris);
        }
        meshes.push_back(std::move(am));
    }
    if (stats.fine_clusters == 0) stats.fine_min = 0;
    if (stats.coarse_clusters == 0) stats.coarse_min = 0;
    if (stats.triangles) {
        stats.acmr_before = acmr_before / double(stats.triangles);
        stats.acmr_after = acmr_after / double(stats.triangles);
    }
    stats.cluster_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return meshes;
}

}  // namespace cb
