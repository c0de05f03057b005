#include "runtime_cost.h"

#include <detail/cb_math.h>
#include <algorithm>
#include <cmath>

#include "parallel.h"
#include "scene_query.h"
#include "timing.h"

namespace cb {

namespace {

void normalise(double* v) {
    double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int k = 0; k < 3; ++k) v[k] /= l;
}
using math::cross3;
using math::dot3;

}  // namespace

double ray_box_entry(const Obb& b, const double* o, const double* v) {
    double t0 = 0, t1 = INFINITY;
    for (int i = 0; i < 3; ++i) {
        const double a[3] = {b.axis[i][0], b.axis[i][1], b.axis[i][2]};
        double oc = (o[0] - b.center[0]) * a[0] + (o[1] - b.center[1]) * a[1] + (o[2] - b.center[2]) * a[2];
        double dv = dot3(v, a), h = double(b.half[i]) * (1 + 1e-9) + 1e-12;
        if (std::fabs(dv) < 1e-300) {
            if (std::fabs(oc) > h) return INFINITY;
            continue;
        }
        double ta = (-h - oc) / dv, tb = (h - oc) / dv;
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta), t1 = std::min(t1, tb);
        if (t0 > t1) return INFINITY;
    }
    return t0;
}

namespace {

// Moller-Trumbore in double; INFINITY when missed.
double ray_triangle(const double* o, const double* v, const double* a, const double* b, const double* c) {
    double e1[3], e2[3], p[3], s[3], q[3];
    for (int k = 0; k < 3; ++k) e1[k] = b[k] - a[k], e2[k] = c[k] - a[k], s[k] = o[k] - a[k];
    cross3(v, e2, p);
    double det = dot3(e1, p);
    if (!(std::fabs(det) > 0)) return INFINITY;
    double inv = 1 / det, u = dot3(s, p) * inv;
    if (u < 0 || u > 1) return INFINITY;
    cross3(s, e1, q);
    double w = dot3(v, q) * inv;
    if (w < 0 || u + w > 1) return INFINITY;
    double t = dot3(e2, q) * inv;
    return t > 0 ? t : INFINITY;
}

// An instance's transform as the runtime's column-major 3x4, and its inverse.
struct InstanceFrame {
    double inverse[12];
    bool usable;
};

}  // namespace

Camera default_camera(const double* lo, const double* hi, uint32_t width, uint32_t height) {
    Camera c;
    c.width = width, c.height = height;
    double size = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-30});
    double centre[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
    const double from[3] = {1.2, 0.8, 1.5};
    double up[3] = {0, 1, 0};
    for (int k = 0; k < 3; ++k) c.eye[k] = centre[k] + from[k] * size, c.forward[k] = -from[k];
    normalise(c.forward);
    cross3(c.forward, up, c.right);
    normalise(c.right);
    cross3(c.right, c.forward, c.up);
    // Frame the box's corners tightly, so the scene fills the view whatever its proportions.
    double aspect = double(width) / double(std::max(1u, height)), extent = 1e-6;
    for (int i = 0; i < 8; ++i) {
        double e[3];
        for (int k = 0; k < 3; ++k) e[k] = ((i >> k & 1) ? hi[k] : lo[k]) - c.eye[k];
        double depth = dot3(e, c.forward);
        if (depth > 0)
            extent = std::max({extent, std::fabs(dot3(e, c.right)) / depth / aspect, std::fabs(dot3(e, c.up)) / depth});
    }
    c.half_extent = 1.04 * extent;
    return c;
}

std::vector<double> first_hits(const BakedScene& baked, const Camera& cam, unsigned threads) {
    std::vector<double> out(size_t(cam.width) * cam.height * 3, NAN);
    std::vector<InstanceFrame> frames(baked.instances.size());
    for (size_t i = 0; i < frames.size(); ++i) {
        const auto& w = baked.instances[i].world;
        double m[12] = {w[0], w[1], w[2], w[4], w[5], w[6], w[8], w[9], w[10], w[12], w[13], w[14]};
        frames[i].usable = invert_instance(m, frames[i].inverse);
    }
    double aspect = double(cam.width) / double(std::max(1u, cam.height));
    parallel_for(cam.height, threads, [&](size_t y) {
        for (uint32_t x = 0; x < cam.width; ++x) {
            double sx = ((x + 0.5) / cam.width * 2 - 1) * aspect, sy = 1 - (y + 0.5) / cam.height * 2, dir[3];
            for (int k = 0; k < 3; ++k)
                dir[k] = cam.forward[k] + cam.half_extent * (sx * cam.right[k] + sy * cam.up[k]);
            double best = INFINITY;
            for (size_t i = 0; i < baked.instances.size(); ++i) {
                if (!frames[i].usable) continue;
                const AssetMesh& m = baked.meshes[baked.instances[i].mesh];
                if (m.coarse_volumes.obbs.size() != m.coarse.size() || m.fine_volumes.obbs.size() != m.fine.size())
                    continue;
                // The ray in the mesh frame: an affine map keeps the ray parameter t.
                const double* inv = frames[i].inverse;
                double o[3], v[3];
                apply_instance(inv, cam.eye, o);
                for (int k = 0; k < 3; ++k) v[k] = inv[k] * dir[0] + inv[3 + k] * dir[1] + inv[6 + k] * dir[2];
                for (size_t c = 0; c < m.coarse.size(); ++c) {
                    if (ray_box_entry(unpack_obb(m.coarse_volumes.obbs[c]), o, v) >= best) continue;
                    for (uint32_t f = m.coarse[c].first; f < m.coarse[c].first + m.coarse[c].count; ++f) {
                        if (ray_box_entry(unpack_obb(m.fine_volumes.obbs[f]), o, v) >= best) continue;
                        for (uint32_t t = m.fine[f].first; t < m.fine[f].first + m.fine[f].count; ++t) {
                            double p[3][3];
                            for (int k = 0; k < 3; ++k)
                                for (int j = 0; j < 3; ++j)
                                    p[k][j] = m.positions[size_t(m.triangles[size_t(t) * 3 + k]) * 3 + j];
                            best = std::min(best, ray_triangle(o, v, p[0], p[1], p[2]));
                        }
                    }
                }
            }
            if (best < INFINITY) {
                double* hit = &out[(size_t(y) * cam.width + x) * 3];
                for (int k = 0; k < 3; ++k) hit[k] = cam.eye[k] + best * dir[k];
            }
        }
    });
    return out;
}

std::vector<double> hit_points(const std::vector<double>& hits) {
    std::vector<double> out;
    for (size_t i = 0; i + 2 < hits.size(); i += 3)
        if (!std::isnan(hits[i])) out.insert(out.end(), {hits[i], hits[i + 1], hits[i + 2]});
    return out;
}

RuntimeCost measure_runtime(const AssetView& view, const std::vector<double>& lights, const std::vector<double>& suns,
                            const std::vector<double>& points, int runs, bool one_sided, Traversal traversal) {
    RuntimeCost cost;
    size_t n = points.size() / 3;
    const uint32_t point_lights = uint32_t(lights.size() / 3);
    cost.lights = point_lights + uint32_t(suns.size() / 3);
    SceneQueryOptions options;
    options.one_sided = one_sided;
    options.traversal = traversal;
    options.threads = 1;  // the rates are per thread
    for (uint32_t l = 0; l < cost.lights; ++l) {
        options.sun = l >= point_lights;
        const double* light = options.sun ? &suns[size_t(l - point_lights) * 3] : &lights[size_t(l) * 3];
        std::vector<double> build_times, query_times;
        for (int r = 0; r < std::max(1, runs); ++r) {
            SceneQueryResult q = query_scene(view, light, points.data(), n, options);
            build_times.push_back(q.build_seconds), query_times.push_back(q.query_seconds);
            if (r == 0) {  // the counts are the same every run
                cost.stats.nodes_visited += q.stats.nodes_visited,
                    cost.stats.clusters_tested += q.stats.clusters_tested;
                cost.stats.triangles_tested += q.stats.triangles_tested, cost.stats.touching += q.stats.touching;
                for (uint8_t s : q.shadowed) cost.shadowed += s;
            }
        }
        cost.build_seconds += median(build_times) / cost.lights;
        cost.query_seconds += median(query_times) / cost.lights;
        cost.queries += n;
    }
    return cost;
}

std::vector<uint32_t> useless_tests(const AssetView& view, const double* light, const std::vector<double>& points,
                                    bool one_sided, unsigned threads, bool sun) {
    SceneQueryOptions options;
    options.one_sided = one_sided;
    options.sun = sun;
    options.per_point = true;  // the counts are per point
    options.threads = threads;
    SceneQueryResult q = query_scene(view, light, points.data(), points.size() / 3, options);
    std::vector<uint32_t> out(q.shadowed.size());
    for (size_t p = 0; p < out.size(); ++p) out[p] = uint32_t(q.point_stats[p].clusters_tested - q.shadowed[p]);
    return out;
}

}  // namespace cb
