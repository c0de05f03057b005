#include "cluster_stats.h"

#include <cb_shadow.h>
#include <detail/cb_math.h>
#include <detail/cb_tile.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <tuple>

#include "bounds.h"
#include "cluster.h"
#include "first_hits.h"
#include "parallel.h"
#include "random.h"
#include "timing.h"

namespace cb {
namespace {

using math::cross3;
using math::dot3;
double length(const double* a) { return std::sqrt(dot3(a, a)); }

double obb_area(const Obb& b) {
    double h0 = b.half[0], h1 = b.half[1], h2 = b.half[2];
    return 8 * (h0 * h1 + h1 * h2 + h0 * h2);
}

// Triangles [first, first + count) of the mesh's cluster order.
struct TriangleRange {
    uint32_t first, count;
};

TriangleRange coarse_triangles(const AssetMesh& m, uint32_t c) {
    const ClusterRange& r = m.coarse[c];
    const ClusterRange& a = m.fine[r.first];
    const ClusterRange& z = m.fine[r.first + r.count - 1];
    return {a.first, z.first + z.count - a.first};
}

// Per vertex, the smallest index of a vertex at exactly the same position: connectivity of unwelded
// meshes (an STL soup) is by position, not by index.
std::vector<uint32_t> welded_ids(const std::vector<float>& positions) {
    uint32_t n = uint32_t(positions.size() / 3);
    std::vector<uint32_t> order(n), id(n);
    std::iota(order.begin(), order.end(), 0u);
    auto key = [&](uint32_t v) { return std::tuple(positions[v * 3], positions[v * 3 + 1], positions[v * 3 + 2]); };
    std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return key(a) < key(b); });
    for (uint32_t i = 0; i < n; ++i)
        id[order[i]] = i > 0 && key(order[i]) == key(order[i - 1]) ? id[order[i - 1]] : order[i];
    return id;
}

uint32_t find_root(std::vector<uint32_t>& parent, uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
}

// What one cluster contributes; summed in cluster order afterwards.
struct ClusterFigures {
    uint32_t triangles = 0, vertices = 0, components = 0;
    double area = 0;
    uint64_t samples = 0, useless = 0, lights_skipping = 0, no_volume = 0;
    uint64_t sun_samples = 0, sun_useless = 0, suns_skipping = 0;
};

struct MeshContext {
    const AssetMesh* mesh;
    std::vector<uint32_t> weld;
    double lo[3], hi[3];
    std::vector<double> lights;  // xyz per light, mesh frame
    std::vector<double> suns;    // unit xyz toward each sun, mesh frame
};

bool has_double_sided(const AssetMesh& m, TriangleRange r) {
    if (m.double_sided.empty()) return false;
    for (uint32_t t = r.first; t < r.first + r.count; ++t)
        if (m.double_sided[t]) return true;
    return false;
}

// Uniform points in the shadow volume of `box` from `light`, clipped to the mesh bounds; counts those the
// cluster's triangles do not shadow (exactly, two-sided).
void sample_shadow_volume(const MeshContext& ctx, const Obb& box, const double* light, TriangleRange r, uint32_t wanted,
                          SplitMix& rng, ClusterFigures& out) {
    ShadowVolume v = make_shadow_volume(box, light);
    if (!v.valid) {
        ++out.no_volume;
        return;
    }
    // The volume is {light + z (d + x u + y w)} over its rectangle (cb_shadow.h).
    const double *d = v.direction, *u = v.across[0], *w = v.across[1];
    double lo0 = v.rect[0], hi0 = v.rect[1], lo1 = v.rect[2], hi1 = v.rect[3];
    double widest = std::sqrt(1 + std::max(lo0 * lo0, hi0 * hi0) + std::max(lo1 * lo1, hi1 * hi1));
    double zmin = v.near / widest, zmax = 0;
    for (int c = 0; c < 8; ++c) {
        double corner[3] = {c & 1 ? ctx.hi[0] : ctx.lo[0], c & 2 ? ctx.hi[1] : ctx.lo[1],
                            c & 4 ? ctx.hi[2] : ctx.lo[2]};
        double e[3] = {corner[0] - light[0], corner[1] - light[1], corner[2] - light[2]};
        zmax = std::max(zmax, dot3(e, d));
    }
    if (!(zmax > zmin)) return;
    double z0 = zmin * zmin * zmin, z1 = zmax * zmax * zmax;
    const float* pos = ctx.mesh->positions.data();
    const uint32_t* tri = ctx.mesh->triangles.data();
    uint32_t accepted = 0;
    for (uint32_t attempt = 0; attempt < wanted * 16 && accepted < wanted; ++attempt) {
        double z = std::cbrt(z0 + rng.uniform() * (z1 - z0));  // density ~ z^2: uniform in volume
        double x = lo0 + rng.uniform() * (hi0 - lo0), y = lo1 + rng.uniform() * (hi1 - lo1), p[3];
        for (int k = 0; k < 3; ++k) p[k] = light[k] + z * (d[k] + x * u[k] + y * w[k]);
        bool inside_bounds = true;
        for (int k = 0; k < 3; ++k) inside_bounds &= p[k] >= ctx.lo[k] && p[k] <= ctx.hi[k];
        if (!inside_bounds || !inside_shadow_volume(v, light, p)) continue;
        double e[3] = {p[0] - light[0], p[1] - light[1], p[2] - light[2]};
        if (length(e) < v.near) continue;
        ++accepted;
        bool shadowed = false;
        for (uint32_t t = r.first; t < r.first + r.count && !shadowed; ++t) {
            double c[3][3];
            for (int k = 0; k < 3; ++k)
                for (int j = 0; j < 3; ++j) c[k][j] = pos[size_t(tri[size_t(t) * 3 + k]) * 3 + j];
            shadowed = segment_triangle(p, light, c[0], c[1], c[2], shadow_from(p, light, 0.0)).blocks;
        }
        out.useless += shadowed ? 0 : 1;
    }
    out.samples += accepted;
}

// Uniform points in the prism a sun casts from `box` (those whose ray toward the sun meets the box), clipped
// to the mesh bounds; counts those whose ray no triangle of the cluster blocks (exactly, two-sided).
void sample_sun_prism(const MeshContext& ctx, const Obb& box, const double* toward, TriangleRange r, uint32_t wanted,
                      SplitMix& rng, ClusterFigures& out) {
    double frame[3][3];  // along the direction, then across it
    if (!direction_frame(toward, frame)) return;
    // The box's rectangle across the direction and its top along it; the mesh bounds' bottom.
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY}, top = -INFINITY, bottom = INFINITY;
    for (int c = 0; c < 8; ++c) {
        double corner[3], bound[3];
        for (int k = 0; k < 3; ++k) {
            corner[k] = box.center[k];
            for (int a = 0; a < 3; ++a) corner[k] += (c >> a & 1 ? 1.0 : -1.0) * double(box.half[a]) * box.axis[a][k];
            bound[k] = c >> k & 1 ? ctx.hi[k] : ctx.lo[k];
        }
        for (int j = 0; j < 2; ++j) {
            lo[j] = std::min(lo[j], dot3(corner, frame[1 + j]));
            hi[j] = std::max(hi[j], dot3(corner, frame[1 + j]));
        }
        top = std::max(top, dot3(corner, frame[0]));
        bottom = std::min(bottom, dot3(bound, frame[0]));
    }
    if (!(top > bottom)) return;
    const float* pos = ctx.mesh->positions.data();
    const uint32_t* tri = ctx.mesh->triangles.data();
    uint32_t accepted = 0;
    for (uint32_t attempt = 0; attempt < wanted * 16 && accepted < wanted; ++attempt) {
        const double x = lo[0] + rng.uniform() * (hi[0] - lo[0]), y = lo[1] + rng.uniform() * (hi[1] - lo[1]),
                     z = bottom + rng.uniform() * (top - bottom);
        double p[3];
        bool inside_bounds = true;
        for (int k = 0; k < 3; ++k) {
            p[k] = z * frame[0][k] + x * frame[1][k] + y * frame[2][k];
            inside_bounds &= p[k] >= ctx.lo[k] && p[k] <= ctx.hi[k];
        }
        if (!inside_bounds || !(ray_box_entry(box, p, toward) < INFINITY)) continue;
        ++accepted;
        bool shadowed = false;
        for (uint32_t t = r.first; t < r.first + r.count && !shadowed; ++t) {
            double c[3][3];
            for (int k = 0; k < 3; ++k)
                for (int j = 0; j < 3; ++j) c[k][j] = pos[size_t(tri[size_t(t) * 3 + k]) * 3 + j];
            shadowed = ray_triangle(p, toward, c[0], c[1], c[2], 0.0).blocks;
        }
        out.sun_useless += shadowed ? 0 : 1;
    }
    out.sun_samples += accepted;
}

ClusterFigures cluster_figures(const MeshContext& ctx, const LevelVolumes& volumes, uint32_t index, TriangleRange r,
                               const StatsOptions& options, uint64_t seed) {
    const AssetMesh& m = *ctx.mesh;
    ClusterFigures f;
    f.triangles = r.count;
    // Distinct vertices (stored indices) and components (triangles sharing a vertex position).
    std::vector<std::pair<uint32_t, uint32_t>> corners;  // (welded vertex, local triangle)
    std::vector<uint32_t> indices;
    for (uint32_t t = 0; t < r.count; ++t)
        for (int k = 0; k < 3; ++k) {
            uint32_t v = m.triangles[size_t(r.first + t) * 3 + k];
            indices.push_back(v);
            corners.push_back({ctx.weld[v], t});
        }
    std::sort(indices.begin(), indices.end());
    f.vertices = uint32_t(std::unique(indices.begin(), indices.end()) - indices.begin());
    std::sort(corners.begin(), corners.end());
    std::vector<uint32_t> parent(r.count);
    std::iota(parent.begin(), parent.end(), 0u);
    for (size_t i = 1; i < corners.size(); ++i)
        if (corners[i].first == corners[i - 1].first)
            parent[find_root(parent, corners[i].second)] = find_root(parent, corners[i - 1].second);
    for (uint32_t t = 0; t < r.count; ++t) f.components += find_root(parent, t) == t;
    for (uint32_t t = r.first; t < r.first + r.count; ++t) {
        double c[3][3], e1[3], e2[3], n[3];
        for (int k = 0; k < 3; ++k)
            for (int j = 0; j < 3; ++j) c[k][j] = m.positions[size_t(m.triangles[size_t(t) * 3 + k]) * 3 + j];
        for (int j = 0; j < 3; ++j) {
            e1[j] = c[1][j] - c[0][j];
            e2[j] = c[2][j] - c[0][j];
        }
        cross3(e1, e2, n);
        f.area += 0.5 * length(n);
    }
    bool sided = has_double_sided(m, r);
    SplitMix rng{seed};
    for (size_t l = 0; l < ctx.lights.size() / 3; ++l) {
        const double* light = &ctx.lights[l * 3];
        if (!volumes.cones.empty() && !sided &&
            light_in_front_cone(unpack_cone(volumes.cones[index], volumes.obbs[index]), light))
            ++f.lights_skipping;
        if (!volumes.obbs.empty())
            sample_shadow_volume(ctx, unpack_obb(volumes.obbs[index]), light, r, options.samples, rng, f);
    }
    for (size_t l = 0; l < ctx.suns.size() / 3; ++l) {
        const double* toward = &ctx.suns[l * 3];
        if (!volumes.cones.empty() && !sided &&
            sun_in_front_cone(unpack_cone(volumes.cones[index], volumes.obbs[index]), toward))
            ++f.suns_skipping;
        if (!volumes.obbs.empty())
            sample_sun_prism(ctx, unpack_obb(volumes.obbs[index]), toward, r, options.samples, rng, f);
    }
    return f;
}

double ratio(double a, double b) { return b > 0 ? a / b : NAN; }

LevelStats level_statistics(const std::vector<MeshContext>& contexts, const std::vector<Instance>& instances, bool fine,
                            double scene_volume, double scene_area, const StatsOptions& options) {
    struct Item {
        uint32_t mesh, cluster;
        TriangleRange range;
    };
    std::vector<Item> items;
    for (uint32_t m = 0; m < contexts.size(); ++m) {
        const AssetMesh& mesh = *contexts[m].mesh;
        size_t n = fine ? mesh.fine.size() : mesh.coarse.size();
        for (uint32_t c = 0; c < n; ++c)
            items.push_back(
                {m, c, fine ? TriangleRange{mesh.fine[c].first, mesh.fine[c].count} : coarse_triangles(mesh, c)});
    }
    std::vector<ClusterFigures> figures(items.size());
    parallel_for(items.size(), options.threads, [&](size_t i) {
        const Item& it = items[i];
        const AssetMesh& mesh = *contexts[it.mesh].mesh;
        uint64_t seed = splitmix(options.seed ^ splitmix(uint64_t(it.mesh) << 33 ^ uint64_t(fine) << 32 ^ it.cluster));
        figures[i] = cluster_figures(contexts[it.mesh], fine ? mesh.fine_volumes : mesh.coarse_volumes, it.cluster,
                                     it.range, options, seed);
    });

    LevelStats s;
    s.clusters = items.size();
    std::vector<double> tris, verts, comps, cone_degrees;
    uint64_t total_tris = 0, total_verts = 0, samples = 0, useless = 0, skips = 0, no_volume = 0, pairs = 0;
    uint64_t sun_samples = 0, sun_useless = 0, sun_skips = 0;
    for (const ClusterFigures& f : figures) {
        tris.push_back(f.triangles), verts.push_back(f.vertices), comps.push_back(f.components);
        total_tris += f.triangles;
        total_verts += f.vertices;
        s.split_clusters += f.components > 1;
        samples += f.samples;
        useless += f.useless;
        skips += f.lights_skipping;
        no_volume += f.no_volume;
        sun_samples += f.sun_samples;
        sun_useless += f.sun_useless;
        sun_skips += f.suns_skipping;
    }
    s.triangles = distribution(tris, true);
    s.vertices = distribution(verts, true);
    s.components = distribution(comps, true);
    s.vertices_per_triangle = ratio(double(total_verts), double(total_tris));

    // Volumes: present only when every mesh has them.
    auto all_have = [&](auto member) {
        for (const MeshContext& c : contexts) {
            const LevelVolumes& v = fine ? c.mesh->fine_volumes : c.mesh->coarse_volumes;
            if ((v.*member).size() != (fine ? c.mesh->fine.size() : c.mesh->coarse.size())) return false;
        }
        return !items.empty();
    };
    auto volumes_of = [&](const Item& it) -> const LevelVolumes& {
        return fine ? contexts[it.mesh].mesh->fine_volumes : contexts[it.mesh].mesh->coarse_volumes;
    };
    if (all_have(&LevelVolumes::obbs)) {
        double volume = 0, area = 0, triangle_area = 0, fill_sum = 0, sphere = 0, capsule = 0;
        bool spheres = all_have(&LevelVolumes::spheres), capsules = all_have(&LevelVolumes::capsules);
        std::vector<double> sphere_ratio, capsule_ratio;  // per cluster with a box of some volume
        for (size_t i = 0; i < items.size(); ++i) {
            const LevelVolumes& v = volumes_of(items[i]);
            const Obb b = unpack_obb(v.obbs[items[i].cluster]);
            double a = obb_area(b);
            volume += obb_volume(b);
            area += a;
            triangle_area += figures[i].area;
            fill_sum += a > 0 ? figures[i].area / a : 0;
            double box = obb_volume(b);
            // Flat boxes (a planar cluster) would make any ratio infinite: left out of the medians.
            bool solid =
                box > 1e-9 * std::pow(std::max({double(b.half[0]), double(b.half[1]), double(b.half[2])}) * 2, 3);
            if (spheres) {
                double v_sphere = 4.0 / 3.0 * M_PI * std::pow(double(v.spheres[items[i].cluster].radius), 3);
                sphere += v_sphere;
                if (solid) sphere_ratio.push_back(v_sphere / box);
            }
            if (capsules) {
                const Capsule& c = v.capsules[items[i].cluster];
                double e[3] = {double(c.b[0]) - c.a[0], double(c.b[1]) - c.a[1], double(c.b[2]) - c.a[2]}, r = c.radius;
                double v_capsule = M_PI * r * r * length(e) + 4.0 / 3.0 * M_PI * r * r * r;
                capsule += v_capsule;
                if (solid) capsule_ratio.push_back(v_capsule / box);
            }
        }
        s.obb_volume_sum = volume;
        s.obb_area_sum = area;
        s.obb_volume_mean = volume / double(items.size());
        s.obb_area_mean = area / double(items.size());
        s.fill = ratio(triangle_area, area);
        s.fill_mean = fill_sum / double(items.size());
        auto median_or_nan = [](const std::vector<double>& v) { return v.empty() ? double(NAN) : median(v); };
        if (spheres) {
            s.sphere_over_obb = ratio(sphere, volume);
            s.sphere_over_obb_median = median_or_nan(sphere_ratio);
        }
        if (capsules) {
            s.capsule_over_obb = ratio(capsule, volume);
            s.capsule_over_obb_median = median_or_nan(capsule_ratio);
        }
        // World space: each instance's linear part scales volumes by |det| and maps box faces to parallelograms.
        double world_volume = 0, world_area = 0;
        std::vector<std::vector<uint32_t>> items_of_mesh(contexts.size());
        for (uint32_t i = 0; i < items.size(); ++i) items_of_mesh[items[i].mesh].push_back(i);
        for (const Instance& inst : instances) {
            const double* t = inst.world.data();
            double col[3][3] = {{t[0], t[1], t[2]}, {t[4], t[5], t[6]}, {t[8], t[9], t[10]}}, x[3];
            cross3(col[1], col[2], x);
            double det = std::fabs(dot3(col[0], x));
            for (uint32_t i : items_of_mesh[inst.mesh]) {
                const Obb b = unpack_obb(volumes_of(items[i]).obbs[items[i].cluster]);
                double edge[3][3];
                for (int a = 0; a < 3; ++a)
                    for (int k = 0; k < 3; ++k)
                        edge[a][k] = 2 * double(b.half[a]) *
                            (col[0][k] * b.axis[a][0] + col[1][k] * b.axis[a][1] + col[2][k] * b.axis[a][2]);
                world_volume += det * obb_volume(b);
                double c01[3], c12[3], c02[3];
                cross3(edge[0], edge[1], c01), cross3(edge[1], edge[2], c12), cross3(edge[0], edge[2], c02);
                world_area += 2 * (length(c01) + length(c12) + length(c02));
            }
        }
        s.obb_volume_relative = ratio(world_volume, scene_volume);
        s.obb_area_relative = ratio(world_area, scene_area);
        s.useless_share = samples ? double(useless) / double(samples) : NAN;
        s.volume_samples = samples;
        s.sun_useless_share = sun_samples ? double(sun_useless) / double(sun_samples) : NAN;
        s.sun_prism_samples = sun_samples;
    }
    size_t lights = contexts.empty() ? 0 : contexts[0].lights.size() / 3;
    const uint64_t sun_pairs = uint64_t(items.size()) * (contexts.empty() ? 0 : contexts[0].suns.size() / 3);
    pairs = uint64_t(items.size()) * lights;
    if (all_have(&LevelVolumes::obbs) && pairs) s.no_volume_share = double(no_volume) / double(pairs);
    if (all_have(&LevelVolumes::cones)) {
        uint64_t invalid = 0;
        for (const Item& it : items) {
            const Cone c = unpack_cone(volumes_of(it).cones[it.cluster], volumes_of(it).obbs[it.cluster]);
            if (!c.valid) {
                ++invalid;
                continue;
            }
            double half = std::acos(std::clamp(double(c.cos_half_angle), -1.0, 1.0)) * 180 / M_PI;
            cone_degrees.push_back(std::max(0.0, 90 - half));
        }
        s.normal_cone_degrees = distribution(cone_degrees, false, 9);
        if (!cone_degrees.empty()) {  // ten-degree bins over [0, 90]
            s.normal_cone_degrees.first = 0;
            s.normal_cone_degrees.width = 10;
            s.normal_cone_degrees.counts.assign(9, 0);
            for (double a : cone_degrees) ++s.normal_cone_degrees.counts[std::min<size_t>(8, size_t(a / 10))];
        }
        s.no_cone_share = double(invalid) / double(items.size());
        if (pairs) s.light_skip_share = double(skips) / double(pairs);
        if (sun_pairs) s.sun_skip_share = double(sun_skips) / double(sun_pairs);
    }
    return s;
}

}  // namespace

Distribution distribution(const std::vector<double>& values, bool integer, uint32_t max_bins) {
    Distribution d;
    d.count = values.size();
    if (values.empty()) return d;
    d.min = *std::min_element(values.begin(), values.end());
    d.max = *std::max_element(values.begin(), values.end());
    double sum = 0;
    for (double v : values) sum += v;
    d.mean = sum / double(values.size());
    if (integer) {
        d.first = d.min;
        double span = d.max - d.min + 1;
        d.width = std::ceil(span / max_bins);
    } else {
        d.first = d.min;
        d.width = d.max > d.min ? (d.max - d.min) / max_bins : 1;
    }
    size_t bins = std::max<size_t>(1, size_t(std::ceil((d.max - d.first + (integer ? 1 : 0)) / d.width)));
    bins = std::min<size_t>(bins, max_bins);
    d.counts.assign(bins, 0);
    for (double v : values) ++d.counts[std::min(bins - 1, size_t((v - d.first) / d.width))];
    return d;
}

SceneStats cluster_statistics(const std::vector<AssetMesh>& meshes, const std::vector<Instance>& instances,
                              const StatsOptions& options) {
    SceneStats s;
    s.options = options;
    s.meshes = meshes.size();
    s.instances = instances.size();
    s.acmr_cache = options.acmr_cache;
    for (int k = 0; k < 3; ++k) {
        s.bounds_min[k] = INFINITY;
        s.bounds_max[k] = -INFINITY;
    }
    for (const Instance& inst : instances) {
        const AssetMesh& m = meshes[inst.mesh];
        s.scene_triangles += m.triangles.size() / 3;
        for (size_t v = 0; v < m.positions.size() / 3; ++v) {
            auto p = transform_point(inst.world, m.positions[v * 3], m.positions[v * 3 + 1], m.positions[v * 3 + 2]);
            for (int k = 0; k < 3; ++k) {
                s.bounds_min[k] = std::min(s.bounds_min[k], p[k]);
                s.bounds_max[k] = std::max(s.bounds_max[k], p[k]);
            }
        }
    }
    if (!(s.bounds_min[0] <= s.bounds_max[0]))
        for (int k = 0; k < 3; ++k) s.bounds_min[k] = s.bounds_max[k] = 0;
    double e[3] = {s.bounds_max[0] - s.bounds_min[0], s.bounds_max[1] - s.bounds_min[1],
                   s.bounds_max[2] - s.bounds_min[2]};
    double scene_volume = e[0] * e[1] * e[2], scene_area = 2 * (e[0] * e[1] + e[1] * e[2] + e[0] * e[2]);

    std::vector<MeshContext> contexts(meshes.size());
    double acmr_weighted = 0;
    for (size_t m = 0; m < meshes.size(); ++m) {
        MeshContext& c = contexts[m];
        const AssetMesh& mesh = meshes[m];
        c.mesh = &mesh;
        c.weld = welded_ids(mesh.positions);
        size_t tris = mesh.triangles.size() / 3;
        s.triangles += tris;
        acmr_weighted +=
            fifo_acmr(mesh.triangles.data(), tris, mesh.positions.size() / 3, options.acmr_cache) * double(tris);
        for (int k = 0; k < 3; ++k) {
            c.lo[k] = INFINITY;
            c.hi[k] = -INFINITY;
        }
        for (size_t v = 0; v < mesh.positions.size(); ++v)
            c.lo[v % 3] = std::min(c.lo[v % 3], double(mesh.positions[v])),
                     c.hi[v % 3] = std::max(c.hi[v % 3], double(mesh.positions[v]));
        if (mesh.positions.empty())
            for (int k = 0; k < 3; ++k) c.lo[k] = c.hi[k] = 0;
        // Lights in the box three times the mesh bounds (padded by the largest side on every axis, so flat
        // meshes get lights off their plane), outside the bounds.
        double pad = std::max({c.hi[0] - c.lo[0], c.hi[1] - c.lo[1], c.hi[2] - c.lo[2], 1e-30});
        SplitMix rng{splitmix(options.seed ^ 0x6c69676874ULL ^ splitmix(m))};
        while (c.lights.size() < size_t(options.lights) * 3) {
            double p[3];
            bool inside = true;
            for (int k = 0; k < 3; ++k) {
                p[k] = c.lo[k] - pad + rng.uniform() * (c.hi[k] - c.lo[k] + 2 * pad);
                inside &= p[k] >= c.lo[k] && p[k] <= c.hi[k];
            }
            if (!inside) c.lights.insert(c.lights.end(), p, p + 3);
        }
        // Suns from every direction alike: points of the unit ball, away from its centre, made unit.
        SplitMix sun_rng{splitmix(options.seed ^ 0x73756e ^ splitmix(m))};
        while (c.suns.size() < size_t(options.suns) * 3) {
            double d[3];
            for (double& x : d) x = 2 * sun_rng.uniform() - 1;
            const double l = length(d);
            if (l > 0.01 && l <= 1)
                for (double x : d) c.suns.push_back(x / l);
        }
    }
    s.acmr = s.triangles ? acmr_weighted / double(s.triangles) : 0;
    s.coarse = level_statistics(contexts, instances, false, scene_volume, scene_area, options);
    s.fine = level_statistics(contexts, instances, true, scene_volume, scene_area, options);
    return s;
}

namespace {

nlohmann::json number(double x) { return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr); }

nlohmann::json to_json(const Distribution& d) {
    return {{"min", d.min},
            {"mean", d.mean},
            {"max", d.max},
            {"histogram", {{"first", d.first}, {"width", d.width}, {"counts", d.counts}}}};
}

nlohmann::json to_json(const LevelStats& l) {
    return {
        {"clusters", l.clusters},
        {"triangles", to_json(l.triangles)},
        {"vertices", to_json(l.vertices)},
        {"vertices_per_triangle", number(l.vertices_per_triangle)},
        {"components", to_json(l.components)},
        {"clusters_with_several_components", l.split_clusters},
        {"obb",
         {{"volume_sum", number(l.obb_volume_sum)},
          {"volume_mean", number(l.obb_volume_mean)},
          {"area_sum", number(l.obb_area_sum)},
          {"area_mean", number(l.obb_area_mean)},
          {"volume_relative_to_scene", number(l.obb_volume_relative)},
          {"area_relative_to_scene", number(l.obb_area_relative)}}},
        {"sphere_volume_over_obb", number(l.sphere_over_obb)},
        {"capsule_volume_over_obb", number(l.capsule_over_obb)},
        {"sphere_volume_over_obb_median", number(l.sphere_over_obb_median)},
        {"capsule_volume_over_obb_median", number(l.capsule_over_obb_median)},
        {"fill", number(l.fill)},
        {"fill_mean", number(l.fill_mean)},
        {"normal_cone_degrees", l.normal_cone_degrees.count ? to_json(l.normal_cone_degrees) : nlohmann::json(nullptr)},
        {"no_cone_share", number(l.no_cone_share)},
        {"light_skip_share", number(l.light_skip_share)},
        {"shadow_volume",
         {{"useless_share", number(l.useless_share)},
          {"samples", l.volume_samples},
          {"no_volume_share", number(l.no_volume_share)}}},
        {"sun_skip_share", number(l.sun_skip_share)},
        {"sun_prism", {{"useless_share", number(l.sun_useless_share)}, {"samples", l.sun_prism_samples}}}};
}

std::string fmt(const char* format, double x) {
    if (!std::isfinite(x)) return "n/a";
    char buf[64];
    std::snprintf(buf, sizeof buf, format, x);
    return buf;
}

std::string histogram_text(const Distribution& d, bool integer) {
    std::string out;
    for (size_t i = 0; i < d.counts.size(); ++i) {
        if (!d.counts[i]) continue;
        double a = d.first + double(i) * d.width, b = a + d.width - (integer ? 1 : 0);
        char buf[96];
        if (integer && a == b)
            std::snprintf(buf, sizeof buf, " %g:%llu", a, (unsigned long long)d.counts[i]);
        else
            std::snprintf(buf, sizeof buf, " %g-%g:%llu", a, b, (unsigned long long)d.counts[i]);
        out += buf;
    }
    return out;
}

}  // namespace

nlohmann::json to_json(const SceneStats& s) {
    return {{"meshes", s.meshes},
            {"instances", s.instances},
            {"triangles", s.triangles},
            {"scene_triangles", s.scene_triangles},
            {"world_bounds",
             {{"min", {s.bounds_min[0], s.bounds_min[1], s.bounds_min[2]}},
              {"max", {s.bounds_max[0], s.bounds_max[1], s.bounds_max[2]}}}},
            {"acmr", {{"cache", s.acmr_cache}, {"fifo", s.acmr}}},
            {"options",
             {{"lights", s.options.lights},
              {"suns", s.options.suns},
              {"samples", s.options.samples},
              {"seed", s.options.seed}}},
            {"coarse", to_json(s.coarse)},
            {"fine", to_json(s.fine)}};
}

std::string to_text(const SceneStats& s) {
    std::string out;
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "  meshes %llu, instances %llu, triangles %llu stored, %llu in scene; ACMR (FIFO %u) of the cluster "
                  "order %.3f\n",
                  (unsigned long long)s.meshes, (unsigned long long)s.instances, (unsigned long long)s.triangles,
                  (unsigned long long)s.scene_triangles, s.acmr_cache, s.acmr);
    out += buf;
    for (auto [name, l] : {std::pair{"coarse", &s.coarse}, std::pair{"fine", &s.fine}}) {
        std::snprintf(buf, sizeof buf, "  %s: %llu clusters\n", name, (unsigned long long)l->clusters);
        out += buf;
        std::snprintf(buf, sizeof buf, "    triangles per cluster %g / %.2f / %g (min / mean / max);%s\n",
                      l->triangles.min, l->triangles.mean, l->triangles.max,
                      histogram_text(l->triangles, true).c_str());
        out += buf;
        std::snprintf(buf, sizeof buf, "    vertices per cluster %g / %.2f / %g (%.3f per triangle);%s\n",
                      l->vertices.min, l->vertices.mean, l->vertices.max, l->vertices_per_triangle,
                      histogram_text(l->vertices, true).c_str());
        out += buf;
        std::snprintf(buf, sizeof buf, "    connected components %g / %.3f / %g; %llu clusters of several;%s\n",
                      l->components.min, l->components.mean, l->components.max, (unsigned long long)l->split_clusters,
                      histogram_text(l->components, true).c_str());
        out += buf;
        out += "    OBB volume sum " + fmt("%.6g", l->obb_volume_sum) + ", mean " + fmt("%.6g", l->obb_volume_mean) +
            ", relative to the scene box " + fmt("%.4f", l->obb_volume_relative) + "\n";
        out += "    OBB area sum " + fmt("%.6g", l->obb_area_sum) + ", mean " + fmt("%.6g", l->obb_area_mean) +
            ", relative to the scene box " + fmt("%.4f", l->obb_area_relative) + "\n";
        out += "    sphere / OBB volume " + fmt("%.3f", l->sphere_over_obb) + " (median per cluster " +
            fmt("%.3f", l->sphere_over_obb_median) + "), capsule / OBB volume " + fmt("%.3f", l->capsule_over_obb) +
            " (median " + fmt("%.3f", l->capsule_over_obb_median) + ")\n    fill (triangle area / OBB surface) " +
            fmt("%.3f", l->fill) + " (mean per cluster " + fmt("%.3f", l->fill_mean) + ")\n";
        if (l->normal_cone_degrees.count)
            std::snprintf(
                buf, sizeof buf, "    normal cones: widest normal %.1f / %.1f / %.1f degrees;%s; no valid cone %s\n",
                l->normal_cone_degrees.min, l->normal_cone_degrees.mean, l->normal_cone_degrees.max,
                histogram_text(l->normal_cone_degrees, false).c_str(), fmt("%.1f%%", 100 * l->no_cone_share).c_str());
        else
            std::snprintf(buf, sizeof buf, "    normal cones: none valid; no valid cone %s\n",
                          fmt("%.1f%%", 100 * l->no_cone_share).c_str());
        out += buf;
        out += "    a light skips " + fmt("%.1f%%", 100 * l->light_skip_share) + " of clusters (one-sided, mean over " +
            std::to_string(s.options.lights) + " lights)\n";
        std::snprintf(buf, sizeof buf,
                      "    shadow volumes: %s of %llu sampled points are not shadowed by their cluster; no volume for "
                      "%s of (cluster, light)\n",
                      fmt("%.1f%%", 100 * l->useless_share).c_str(), (unsigned long long)l->volume_samples,
                      fmt("%.1f%%", 100 * l->no_volume_share).c_str());
        out += buf;
        out += "    a sun skips " + fmt("%.1f%%", 100 * l->sun_skip_share) + " of clusters (one-sided, mean over " +
            std::to_string(s.options.suns) + " suns)\n    sun prisms: " + fmt("%.1f%%", 100 * l->sun_useless_share) +
            " of " + std::to_string(l->sun_prism_samples) + " sampled points are not shadowed by their cluster\n";
    }
    return out;
}

}  // namespace cb
