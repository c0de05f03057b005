#include "visibility.h"

#include <cb_cull.h>
#include <detail/cb_math.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "parallel.h"
#include "vec3.h"
#include "world_box.h"

namespace cb {

namespace {

using math::cross3;
using math::dot3;

// The culling frustum: the four planes through the eye and the picture's edges, and a near plane.
Frustum view_frustum(const Camera& c, double near) {
    Frustum f;
    const double aspect = aspect_of(c);
    double corner[4][3];  // directions to the picture's corners, counter-clockwise from bottom left
    const double sx[4] = {-1, 1, 1, -1}, sy[4] = {-1, -1, 1, 1};
    for (int i = 0; i < 4; ++i)
        for (int k = 0; k < 3; ++k)
            corner[i][k] = c.forward[k] + c.half_extent * (sx[i] * aspect * c.right[k] + sy[i] * c.up[k]);
    for (int i = 0; i < 4; ++i) {
        double n[3];
        cross3(corner[i], corner[(i + 1) % 4], n);
        if (dot3(n, c.forward) < 0)
            for (double& v : n) v = -v;
        std::copy(n, n + 3, f.plane[i]);
        f.plane[i][3] = -dot3(n, c.eye);
    }
    std::copy(c.forward, c.forward + 3, f.plane[4]);
    f.plane[4][3] = -dot3(c.forward, c.eye) - near;
    f.count = 5;
    std::copy(c.eye, c.eye + 3, f.eye);
    return f;
}

// The fine clusters to draw: those the frustum may see, or every one of an asset without fine boxes.
std::vector<VisibleCluster> clusters_to_draw(const LevelInput& level, const Frustum& f) {
    auto list = [&](VisibleCluster* out, size_t capacity) {
        size_t count = 0;
        for (uint32_t i = 0; i < level.instances.size(); ++i) {
            const LevelInstance& placed = level.instances[i];
            const AssetView& view = *level.assets[placed.asset];
            if (view.fine_bounds.obbs) {
                count = cull_instance(view, {placed.mesh, placed.transform}, i, f, /*backface=*/false, out, capacity,
                                      count);
                continue;
            }
            const MeshRecord& mesh = view.meshes[placed.mesh];
            for (uint32_t k = 0; k < mesh.fine_count; ++k, ++count)
                if (count < capacity) out[count] = {i, mesh.first_fine + k};
        }
        return count;
    };
    std::vector<VisibleCluster> out(list(nullptr, 0));
    list(out.data(), out.size());
    return out;
}

// Corners of triangle `t` (0-based within the cluster) of a listed cluster, in world space.
void cluster_triangle(const LevelInput& level, const VisibleCluster& vc, uint32_t t, double (*world)[3]) {
    const LevelInstance& placed = level.instances[vc.instance];
    const AssetView& view = *level.assets[placed.asset];
    const MeshRecord& mesh = view.meshes[placed.mesh];
    const uint32_t local_cluster = vc.fine - mesh.first_fine;
    uint32_t corner[3];
    view.triangle(mesh, local_cluster, view.fine[vc.fine].first_triangle + t, corner);
    for (int i = 0; i < 3; ++i) {
        const float* p = view.position(mesh, corner[i]);
        const double local[3] = {p[0], p[1], p[2]};
        apply_instance(placed.transform, local, world[i]);
    }
}

// The triangle clipped to the near plane and projected to pixel coordinates (pixel (x, y) covers [x, x + 1)
// x [y, y + 1)): up to 4 corners, counter-clockwise or clockwise as it faces.
int project_triangle(const Camera& c, double aspect, double near, const double (*world)[3], double (*out)[2]) {
    double cam[3][3];
    for (int i = 0; i < 3; ++i) {
        double e[3] = {world[i][0] - c.eye[0], world[i][1] - c.eye[1], world[i][2] - c.eye[2]};
        cam[i][0] = dot3(e, c.right);
        cam[i][1] = dot3(e, c.up);
        cam[i][2] = dot3(e, c.forward);
    }
    double poly[4][3];
    int n = 0;
    for (int i = 0; i < 3; ++i) {
        const double *a = cam[i], *b = cam[(i + 1) % 3];
        const bool a_in = a[2] >= near, b_in = b[2] >= near;
        if (a_in) std::copy(a, a + 3, poly[n++]);
        if (a_in != b_in) {
            const double s = (near - a[2]) / (b[2] - a[2]);
            for (int k = 0; k < 2; ++k) poly[n][k] = a[k] + s * (b[k] - a[k]);
            poly[n++][2] = near;
        }
    }
    for (int k = 0; k < n; ++k) {
        out[k][0] = (poly[k][0] / (poly[k][2] * c.half_extent * aspect) + 1) * 0.5 * c.width;
        out[k][1] = (1 - poly[k][1] / (poly[k][2] * c.half_extent)) * 0.5 * c.height;
        if (!std::isfinite(out[k][0]) || !std::isfinite(out[k][1])) return 0;
    }
    return n;
}

// The rows whose pixel centres lie within [lo, hi] (pixel coordinates), clamped to [0, size).
void centre_range(double lo, double hi, uint32_t size, int64_t& first, int64_t& last) {
    first = int64_t(std::max(0.0, std::ceil(std::max(-1.0, lo) - 0.5)));
    last = int64_t(std::min(double(size) - 1, std::floor(std::min(double(size) + 1, hi) - 0.5)));
}

double edge(const double* a, const double* b, double x, double y) {
    return (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]);
}

struct DepthBuffer {
    std::vector<double> depth;  // ray parameter along pixel_ray's direction
    std::vector<uint64_t> key;  // (listed cluster << 8) | triangle, or none
    static constexpr uint64_t none = std::numeric_limits<uint64_t>::max();
};

}  // namespace

VisibleSurface primary_visibility(const LevelInput& level, const Camera& c, unsigned threads) {
    VisibleSurface out;
    out.width = c.width;
    out.height = c.height;
    const size_t pixel_count = size_t(c.width) * c.height;
    double lo[3], hi[3];
    if (!level_world_box(level, lo, hi) || !pixel_count) return out;

    // The near plane: far enough that projected corners stay finite, near enough to cut nothing the
    // camera shows (a millionth of the distance across the scene and the eye).
    double reach = 0;
    for (int k = 0; k < 3; ++k)
        reach = std::max({reach, std::fabs(hi[k] - c.eye[k]), std::fabs(lo[k] - c.eye[k]), hi[k] - lo[k]});
    const double near = std::max(1e-6 * reach, 1e-300);
    const double aspect = aspect_of(c);
    const std::vector<VisibleCluster> clusters = clusters_to_draw(level, view_frustum(c, near));
    out.clusters_drawn = clusters.size();

    // Which rows each cluster reaches, so that a band of rows skips the others.
    std::vector<int64_t> first_row(clusters.size()), last_row(clusters.size());
    std::vector<uint32_t> triangles(clusters.size());
    parallel_for(clusters.size(), threads, [&](size_t i) {
        double top = INFINITY, bottom = -INFINITY;
        const uint32_t count =
            level.assets[level.instances[clusters[i].instance].asset]->fine[clusters[i].fine].triangle_count;
        for (uint32_t t = 0; t < count; ++t) {
            double world[3][3], screen[4][2];
            cluster_triangle(level, clusters[i], t, world);
            int n = project_triangle(c, aspect, near, world, screen);
            for (int k = 0; k < n; ++k) {
                top = std::min(top, screen[k][1]);
                bottom = std::max(bottom, screen[k][1]);
            }
        }
        triangles[i] = count;
        if (top <= bottom)
            centre_range(top, bottom, c.height, first_row[i], last_row[i]);
        else {
            first_row[i] = 1;
            last_row[i] = 0;
        }
    });
    for (uint32_t n : triangles) out.triangles_drawn += n;

    // Bands of rows on threads, each drawing every cluster that reaches it: a pixel keeps the nearest hit
    // of its ray on a triangle's plane, among the triangles whose projection holds its centre.
    DepthBuffer buffer;
    buffer.depth.assign(pixel_count, INFINITY);
    buffer.key.assign(pixel_count, DepthBuffer::none);
    const uint32_t band_rows = 8, bands = (c.height + band_rows - 1) / band_rows;
    parallel_for(bands, threads, [&](size_t band) {
        const int64_t band_first = int64_t(band * band_rows),
                      band_last = std::min<int64_t>(band_first + band_rows, c.height) - 1;
        for (size_t i = 0; i < clusters.size(); ++i) {
            if (last_row[i] < band_first || first_row[i] > band_last) continue;
            for (uint32_t t = 0; t < triangles[i]; ++t) {
                double world[3][3], screen[4][2];
                cluster_triangle(level, clusters[i], t, world);
                const int n = project_triangle(c, aspect, near, world, screen);
                if (n < 3) continue;
                double e1[3], e2[3], normal[3], to_a[3];
                for (int k = 0; k < 3; ++k) {
                    e1[k] = world[1][k] - world[0][k];
                    e2[k] = world[2][k] - world[0][k];
                    to_a[k] = world[0][k] - c.eye[k];
                }
                cross3(e1, e2, normal);
                const double plane = dot3(to_a, normal);
                for (int fan = 1; fan + 1 < n; ++fan) {
                    const double *a = screen[0], *b = screen[fan], *d = screen[fan + 1];
                    const double area = edge(a, b, d[0], d[1]);
                    if (!(area != 0)) continue;
                    int64_t y0, y1, x0, x1;
                    centre_range(std::min({a[1], b[1], d[1]}), std::max({a[1], b[1], d[1]}), c.height, y0, y1);
                    centre_range(std::min({a[0], b[0], d[0]}), std::max({a[0], b[0], d[0]}), c.width, x0, x1);
                    y0 = std::max(y0, band_first);
                    y1 = std::min(y1, band_last);
                    for (int64_t y = y0; y <= y1; ++y)
                        for (int64_t x = x0; x <= x1; ++x) {
                            const double px = x + 0.5, py = y + 0.5;
                            const double w0 = edge(b, d, px, py), w1 = edge(d, a, px, py), w2 = edge(a, b, px, py);
                            if (area > 0 ? (w0 < 0 || w1 < 0 || w2 < 0) : (w0 > 0 || w1 > 0 || w2 > 0)) continue;
                            double dir[3];
                            pixel_ray(c, aspect, uint32_t(x), uint32_t(y), dir);
                            const double along = dot3(dir, normal), depth = plane / along;
                            const size_t p = size_t(y) * c.width + size_t(x);
                            if (!(depth > 0) || !(depth < buffer.depth[p])) continue;  // edge-on or farther
                            buffer.depth[p] = depth;
                            buffer.key[p] = uint64_t(i) << 8 | t;
                        }
                }
            }
        }
    });

    // Each covered pixel's point and normal, from the triangle it kept.
    std::vector<uint32_t> first_mesh(level.assets.size(), 0);  // meshes numbered across the assets
    for (size_t a = 1; a < level.assets.size(); ++a)
        first_mesh[a] = first_mesh[a - 1] + level.assets[a - 1]->mesh_count;
    for (size_t p = 0; p < pixel_count; ++p)
        if (buffer.key[p] != DepthBuffer::none) out.pixel.push_back(uint32_t(p));
    const size_t covered = out.pixel.size();
    out.points.resize(covered * 3), out.normals.resize(covered * 3), out.meshes.resize(covered);
    parallel_for((covered + 4095) / 4096, threads, [&](size_t chunk) {
        for (size_t j = chunk * 4096; j < std::min(covered, chunk * 4096 + 4096); ++j) {
            const size_t p = out.pixel[j];
            const VisibleCluster& vc = clusters[buffer.key[p] >> 8];
            double world[3][3], e1[3], e2[3], dir[3];
            cluster_triangle(level, vc, uint32_t(buffer.key[p] & 255), world);
            for (int k = 0; k < 3; ++k) {
                e1[k] = world[1][k] - world[0][k];
                e2[k] = world[2][k] - world[0][k];
            }
            double* normal = &out.normals[j * 3];
            cross3(e1, e2, normal);
            normalise(normal);
            pixel_ray(c, aspect, uint32_t(p % c.width), uint32_t(p / c.width), dir);
            if (dot3(normal, dir) > 0)
                for (int k = 0; k < 3; ++k) normal[k] = -normal[k];
            for (int k = 0; k < 3; ++k) out.points[j * 3 + k] = c.eye[k] + buffer.depth[p] * dir[k];
            out.meshes[j] = first_mesh[level.instances[vc.instance].asset] + level.instances[vc.instance].mesh;
        }
    });
    return out;
}

}  // namespace cb
