#include "first_hits.h"

#include <cb_segment.h>
#include <detail/cb_math.h>

#include <algorithm>
#include <cmath>

#include "parallel.h"
#include "world_box.h"

namespace cb {

namespace {

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
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
        if (t0 > t1) return INFINITY;
    }
    return t0;
}

namespace {

// Moller-Trumbore in double; INFINITY when missed.
double ray_triangle(const double* o, const double* v, const double* a, const double* b, const double* c) {
    double e1[3], e2[3], p[3], s[3], q[3];
    for (int k = 0; k < 3; ++k) {
        e1[k] = b[k] - a[k];
        e2[k] = c[k] - a[k];
        s[k] = o[k] - a[k];
    }
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

// The inverse of an instance's transform (column-major 3x4), when it has one.
struct InstanceFrame {
    double inverse[12];
    bool usable;
};

}  // namespace

std::vector<double> first_hits(const BakedScene& baked, const Camera& cam, unsigned threads) {
    std::vector<double> out(size_t(cam.width) * cam.height * 3, NAN);
    std::vector<InstanceFrame> frames(baked.instances.size());
    for (size_t i = 0; i < frames.size(); ++i) {
        double m[12];
        instance_matrix(baked.instances[i].world, m);
        frames[i].usable = invert_instance(m, frames[i].inverse);
    }
    const double aspect = aspect_of(cam);
    parallel_for(cam.height, threads, [&](size_t y) {
        for (uint32_t x = 0; x < cam.width; ++x) {
            double dir[3];
            pixel_ray(cam, aspect, x, uint32_t(y), dir);
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

}  // namespace cb
