// What an engine does with a baked asset, through the installed runtime alone: open it in place, answer
// point-light shadow queries for a batch of points, and list the clusters a camera may see.
//
//   embed ASSET X,Y,Z POINTS
//
// POINTS holds one "x y z" a line. Prints one line per point, 1 in shadow and 0 lit (what `clusterbake
// query ASSET --light X,Y,Z --points POINTS` prints), then on stderr how many fine clusters a camera at the
// light looking at the scene's centre may see.
#include <clusterbake/cb_asset.h>
#include <clusterbake/cb_instance_shadow.h>
#include <clusterbake/cb_cull.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "files.h"

// The embedding example of docs/RUNTIME.md, word for word (tests/check_embed.sh compares the two).

// bytes: the asset in memory, 8-byte aligned; light: xyz; points: n xyz triples; all world space.
// in_shadow[i] becomes 1 when point i is in shadow, 0 when it is lit.
bool shadow_answers(const void* bytes, size_t size, const double* light, const double* points, size_t n,
                    uint8_t* in_shadow) {
    cb::AssetView view;
    if (cb::open_asset(bytes, size, &view) != cb::AssetError::ok) return false;
    // The light-independent bounds, once per asset
    const std::vector<cb::ScanBounds> bounds = cb::make_scan_bounds(view);
    // One structure per instance, built for each light
    std::vector<cb::InstanceShadow> shadows(view.instance_count);
    // The defaults: scan traversal, two-sided, one thread
    cb::ShadowBuildOptions options;
    options.bounds = bounds.data();
    // The self-shadowing bias (a world distance), worked out once rather than by each build
    options.bias = cb::default_shadow_bias(cb::asset_world_size(view));
    for (uint32_t i = 0; i < view.instance_count; ++i) shadows[i].build(view, i, light, options);
    std::vector<uint32_t> scratch(cb::batch_scratch_size(shadows.data(), shadows.size(), n));
    cb::occluded_batch(shadows.data(), shadows.size(), points, n, in_shadow, scratch.data());
    return true;
}

namespace {

// A frustum from `eye` towards `target`: a square 90-degree view, near 1e-3, no far plane.
cb::Frustum look_at(const double* eye, const double* target) {
    double z[3] = {target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]};
    const double zl = std::sqrt(z[0] * z[0] + z[1] * z[1] + z[2] * z[2]);
    for (double& c : z) c /= zl;
    const double up[3] = {std::fabs(z[1]) < 0.9 ? 0.0 : 1.0, std::fabs(z[1]) < 0.9 ? 1.0 : 0.0, 0.0};
    double x[3] = {up[1] * z[2] - up[2] * z[1], up[2] * z[0] - up[0] * z[2], up[0] * z[1] - up[1] * z[0]};
    const double xl = std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    for (double& c : x) c /= xl;
    const double y[3] = {z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]};
    cb::Frustum f;
    auto add = [&](double nx, double ny, double nz, double offset) {  // n . p + w >= 0 inside
        double* p = f.plane[f.count++];
        p[0] = nx;
        p[1] = ny;
        p[2] = nz;
        p[3] = -(nx * eye[0] + ny * eye[1] + nz * eye[2]) + offset;
    };
    add(z[0], z[1], z[2], -1e-3);       // near
    for (int s = -1; s <= 1; s += 2) {  // 45 degrees either side: z + s x and z + s y
        add(z[0] - s * x[0], z[1] - s * x[1], z[2] - s * x[2], 0);
        add(z[0] - s * y[0], z[1] - s * y[1], z[2] - s * y[2], 0);
    }
    for (int k = 0; k < 3; ++k) f.eye[k] = eye[k];
    return f;
}

}  // namespace

int main(int argc, char** argv) {
    double light[3];
    if (argc != 4 || std::sscanf(argv[2], "%lf,%lf,%lf", &light[0], &light[1], &light[2]) != 3) {
        std::fprintf(stderr, "usage: embed ASSET X,Y,Z POINTS\n");
        return 2;
    }
    void* bytes = nullptr;
    size_t size = 0;
    cb::AssetView view;
    if (!example::open_asset_file(argv[1], bytes, size, view)) return 2;
    const std::vector<double> points = example::read_points(argv[3]);
    const size_t n = points.size() / 3;

    // Shadows: the light-independent bounds, then per light one structure per instance, and one batch query
    // over all the points (the default traversal: a scan of the clusters' spheres).
    std::vector<uint8_t> shadowed(n);
    if (!shadow_answers(bytes, size, light, points.data(), n, shadowed.data())) return 2;
    for (uint8_t s : shadowed) std::printf("%d\n", int(s));

    // Culling: the fine clusters a camera at the light, looking at the first instance's first coarse
    // cluster, may see (into the caller's array; asked again with more room when it was too small).
    double target[3] = {0, 0, 0};
    if (view.instance_count && view.coarse_bounds.obbs) {
        const cb::InstanceRecord& first = view.instances[0];
        const float* c = view.coarse_bounds.obbs[view.meshes[first.mesh].first_coarse].center;
        const double local[3] = {c[0], c[1], c[2]};
        cb::apply_instance(first.transform, local, target);
    }
    const cb::Frustum frustum = look_at(light, target);
    std::vector<cb::VisibleCluster> visible(64);
    size_t count = cb::cull_clusters(view, frustum, true, visible.data(), visible.size());
    if (count > visible.size()) {
        visible.resize(count);
        count = cb::cull_clusters(view, frustum, true, visible.data(), visible.size());
    }
    std::fprintf(stderr, "%zu points, %zu in shadow; %zu of %u fine clusters in view\n", n,
                 size_t(std::count(shadowed.begin(), shadowed.end(), uint8_t(1))), count, view.fine_count);
    std::free(bytes);
    return 0;
}
