// A fast exact shadow oracle over a loaded cb::Scene, independent of the runtime's asset encoding and of
// its trees. Per mesh, a CGAL AABB tree over its triangles with exact predicates (Epick: its segment-box
// and segment-triangle tests are exact) lists exactly the triangles the closed query segment meets; the
// exact per-triangle semantics (oracle() in shadow_oracle.h, CGAL's exact constructions) decide on those
// only. occluded_brute_force gives the same answers from every triangle, to check the trees' candidates.
#pragma once

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <cb_shadow.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "scene.h"
#include "shadow_oracle.h"

namespace cb::test {

using Epick = CGAL::Exact_predicates_inexact_constructions_kernel;

struct OracleAnswer {
    bool blocked = false;
    bool touching = false;       // some triangle the segment meets is touched (every one is looked at)
    bool only_touching = false;  // blocked, and only by touching contacts: the most delicate answers
};

// The runtime's 3x4 column-major instance transform (axes, then translation) from the scene's 4x4.
inline std::array<double, 12> instance_3x4(const cb::Transform& world) {
    std::array<double, 12> m{};
    for (int col = 0; col < 4; ++col)
        for (int row = 0; row < 3; ++row) m[size_t(col) * 3 + row] = world[size_t(col) * 4 + row];
    return m;
}

// The scene's vertices in world space, as the runtime places them (every `stride`-th kept: points on the
// surfaces), and the world bounds of all of them.
inline WorldSample sample_scene(const cb::Scene& scene, uint32_t stride) {
    WorldSample w;
    for (const cb::Instance& inst : scene.instances) {
        std::array<double, 12> m = instance_3x4(inst.world);
        const cb::Mesh& mesh = scene.meshes[inst.mesh];
        for (size_t k = 0; k < mesh.vertex_count(); ++k) {
            double local[3] = {mesh.positions[k * 3], mesh.positions[k * 3 + 1], mesh.positions[k * 3 + 2]}, p[3];
            cb::apply_instance(m.data(), local, p);
            for (int j = 0; j < 3; ++j) {
                w.lo[j] = std::min(w.lo[j], p[j]);
                w.hi[j] = std::max(w.hi[j], p[j]);
            }
            if (k % stride == 0) w.surface.push_back({p[0], p[1], p[2]});
        }
    }
    return w;
}

// The mesh-frame point the runtime makes of world point p for an instance (its inverse, in double).
inline bool world_to_mesh(const cb::Instance& inst, const double* p, double* out) {
    std::array<double, 12> m = instance_3x4(inst.world), inv;
    if (!cb::invert_instance(m.data(), inv.data())) return false;
    cb::apply_instance(inv.data(), p, out);
    return true;
}

// A light exactly on one triangle's plane, beside the triangle: b + c - a for its corners a, b, c (across
// the edge bc from a; in double, exact for most float triangles), placed in world space so that the
// runtime's mapping back into the mesh frame still lies exactly on that plane and off the triangle (checked
// with exact predicates; always so for an identity instance). Triangles are tried from a seeded start.
struct PlaneLight {
    bool found = false;
    uint32_t instance = 0;
    double light[3] = {0, 0, 0};
    double corner[3][3] = {};  // mesh frame
};

inline bool on_plane_beside(const double corner[3][3], const double* x) {
    Epick::Point_3 a(corner[0][0], corner[0][1], corner[0][2]), b(corner[1][0], corner[1][1], corner[1][2]),
        c(corner[2][0], corner[2][1], corner[2][2]), q(x[0], x[1], x[2]);
    return CGAL::orientation(a, b, c, q) == CGAL::COPLANAR && !Epick::Triangle_3(a, b, c).has_on(q);
}

inline PlaneLight plane_light(const cb::Scene& scene, uint64_t seed) {
    PlaneLight r;
    for (uint32_t i = 0; i < scene.instances.size(); ++i) {
        const cb::Mesh& mesh = scene.meshes[scene.instances[i].mesh];
        std::array<double, 12> m = instance_3x4(scene.instances[i].world);
        size_t n = mesh.triangle_count();
        for (size_t tries = 0; tries < std::min<size_t>(n, 256); ++tries) {
            size_t t = (seed + tries * 7919) % n;
            for (int k = 0; k < 3; ++k)
                for (int j = 0; j < 3; ++j) r.corner[k][j] = mesh.positions[size_t(mesh.indices[t * 3 + k]) * 3 + j];
            Epick::Point_3 a(r.corner[0][0], r.corner[0][1], r.corner[0][2]),
                b(r.corner[1][0], r.corner[1][1], r.corner[1][2]), c(r.corner[2][0], r.corner[2][1], r.corner[2][2]);
            if (CGAL::collinear(a, b, c)) continue;
            double local[3], back[3];
            for (int j = 0; j < 3; ++j) local[j] = r.corner[1][j] + r.corner[2][j] - r.corner[0][j];
            cb::apply_instance(m.data(), local, r.light);
            if (!world_to_mesh(scene.instances[i], r.light, back) || !on_plane_beside(r.corner, back)) continue;
            r.found = true;
            r.instance = i;
            return r;
        }
    }
    return r;
}

// A light exactly on a triangle's corner as the runtime sees it: a world point that maps back onto the
// vertex exactly.
inline bool vertex_light(const cb::Scene& scene, uint64_t seed, double* light) {
    for (const cb::Instance& inst : scene.instances) {
        const cb::Mesh& mesh = scene.meshes[inst.mesh];
        std::array<double, 12> m = instance_3x4(inst.world);
        for (size_t tries = 0; tries < std::min<size_t>(mesh.triangle_count(), 256); ++tries) {
            size_t t = (seed + tries * 7919) % mesh.triangle_count();
            const float* v = &mesh.positions[size_t(mesh.indices[t * 3 + tries % 3]) * 3];
            double local[3] = {v[0], v[1], v[2]}, back[3];
            cb::apply_instance(m.data(), local, light);
            if (world_to_mesh(inst, light, back) && back[0] == local[0] && back[1] == local[1] && back[2] == local[2])
                return true;
        }
    }
    return false;
}

// Points whose segment to the light runs through a triangle's centroid c (c + s (c - light) in world space,
// s = 1/64 or 1: just behind it or far), half of them through double-sided triangles when the scene has
// any: one-sided mode has to get sidedness right there.
inline std::vector<std::array<double, 3>> through_points(const cb::Scene& scene, const double* light, size_t n,
                                                         uint64_t seed) {
    std::vector<std::pair<uint32_t, uint32_t>> any, two_sided;  // (instance, triangle)
    for (uint32_t i = 0; i < scene.instances.size(); ++i) {
        const cb::Mesh& mesh = scene.meshes[scene.instances[i].mesh];
        for (const cb::Primitive& p : mesh.primitives)
            for (uint32_t t = p.first_triangle; t < p.first_triangle + p.triangle_count; ++t)
                (p.double_sided ? two_sided : any).push_back({i, t});
    }
    std::vector<std::array<double, 3>> out;
    for (size_t k = 0; k < n; ++k) {
        const auto& from = (k % 2 && !two_sided.empty()) || any.empty() ? two_sided : any;
        if (from.empty()) break;
        auto [i, t] = from[(seed + k * 104729) % from.size()];
        const cb::Mesh& mesh = scene.meshes[scene.instances[i].mesh];
        double c[3] = {0, 0, 0}, w[3];
        for (int v = 0; v < 3; ++v)
            for (int j = 0; j < 3; ++j) c[j] += mesh.positions[size_t(mesh.indices[size_t(t) * 3 + v]) * 3 + j] / 3.0;
        cb::apply_instance(instance_3x4(scene.instances[i].world).data(), c, w);
        double s = k % 4 < 2 ? 1.0 / 64 : 1.0;
        out.push_back({w[0] + s * (w[0] - light[0]), w[1] + s * (w[1] - light[1]), w[2] + s * (w[2] - light[2])});
    }
    return out;
}

class SceneOracle {
public:
    // `bias`: the self-shadowing bias the runtime's answers to compare with used (cb::Level::shadow_bias, or
    // cb::default_shadow_bias of cb::asset_world_size for an asset's InstanceShadows).
    SceneOracle(const cb::Scene& scene, double bias) : bias_(bias) {
        for (const cb::Mesh& m : scene.meshes) meshes_.push_back(build_mesh(m));
        for (const cb::Instance& i : scene.instances) {
            Frame f;
            f.mesh = i.mesh;
            f.to_world = instance_3x4(i.world);
            f.usable = cb::invert_instance(f.to_world.data(), f.to_mesh.data());
            frames_.push_back(f);
        }
    }

    // Is the segment from world point p to the light blocked? The same semantics as the runtime
    // (cb_shadow.h), two-sided or one-sided with each primitive's double_sided flag.
    OracleAnswer occluded(const double* p, const double* light, bool one_sided) const {
        return answer(p, light, one_sided, true);
    }

    // The same answer from every triangle of every instance, without the trees: to check the trees' candidates.
    OracleAnswer occluded_brute_force(const double* p, const double* light, bool one_sided) const {
        return answer(p, light, one_sided, false);
    }

    // Is p in the shadow of the sun in direction `toward` (cb::ray_triangle's semantics)? With the trees, or
    // from every triangle.
    OracleAnswer occluded_sun(const double* p, const double* toward, bool one_sided) const {
        return answer(p, toward, one_sided, true, true);
    }
    OracleAnswer occluded_sun_brute_force(const double* p, const double* toward, bool one_sided) const {
        return answer(p, toward, one_sided, false, true);
    }

    // The first surface point along a world ray (double constructions: near the surface, not on it).
    bool first_hit(const double* origin, const double* dir, double* hit) const {
        double best = INFINITY;
        for (const Frame& f : frames_) {
            const MeshTree& m = *meshes_[f.mesh];
            if (!f.usable || m.triangles.empty()) continue;
            double far[3] = {origin[0] + dir[0], origin[1] + dir[1], origin[2] + dir[2]}, lo[3], lf[3];
            cb::apply_instance(f.to_mesh.data(), origin, lo);
            cb::apply_instance(f.to_mesh.data(), far, lf);
            Epick::Ray_3 ray(Epick::Point_3(lo[0], lo[1], lo[2]), Epick::Point_3(lf[0], lf[1], lf[2]));
            auto h = m.tree.first_intersection(ray);
            if (!h) continue;
            const Epick::Point_3* x = boost::get<Epick::Point_3>(&h->first);
            const Epick::Segment_3* seg = boost::get<Epick::Segment_3>(&h->first);
            Epick::Point_3 local = x ? *x : seg->source();
            double lx[3] = {local.x(), local.y(), local.z()}, w[3];
            cb::apply_instance(f.to_world.data(), lx, w);
            double d = (w[0] - origin[0]) * (w[0] - origin[0]) + (w[1] - origin[1]) * (w[1] - origin[1]) +
                (w[2] - origin[2]) * (w[2] - origin[2]);
            if (d < best) {
                best = d;
                hit[0] = w[0];
                hit[1] = w[1];
                hit[2] = w[2];
            }
        }
        return best < INFINITY;
    }

    // Triangles with an area (the ones that can block), counted per instance.
    size_t triangles_in_scene() const {
        size_t n = 0;
        for (const Frame& f : frames_) n += meshes_[f.mesh]->triangles.size();
        return n;
    }

private:
    using Triangles = std::vector<Epick::Triangle_3>;
    using Primitive = CGAL::AABB_triangle_primitive<Epick, Triangles::const_iterator>;
    using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Epick, Primitive>>;

    // The tree's triangles in the nodes whose boxes the ray p + t d (t >= 0) may meet, by slabs in double
    // widened by 1e-9 of the sizes involved: CGAL's own Ray_3 from a point and a vector would hold p + d
    // rounded, a ray in another direction, and miss triangles that the exact ray meets near their box's side.
    struct RayCandidates {
        const double *p, *d;
        const Triangles* triangles;
        std::vector<size_t>* out;
        bool go_further() const { return true; }
        void intersection(int, const Primitive& primitive) {
            out->push_back(size_t(primitive.id() - triangles->begin()));
        }
        template <class Node>
        bool do_intersect(int, const Node& node) const {
            const CGAL::Bbox_3 b = node.bbox();
            double t0 = 0, t1 = INFINITY;
            for (int k = 0; k < 3; ++k) {
                const double margin = 1e-9 * (std::fabs(p[k]) + std::fabs(b.min(k)) + std::fabs(b.max(k))) + 1e-300;
                const double lo = b.min(k) - margin, hi = b.max(k) + margin;
                if (d[k] == 0) {
                    if (p[k] < lo || p[k] > hi) return false;
                    continue;
                }
                double ta = (lo - p[k]) / d[k], tb = (hi - p[k]) / d[k];
                if (ta > tb) std::swap(ta, tb);
                t0 = std::max(t0, ta);
                t1 = std::min(t1, tb);
            }
            return t0 <= t1 * (1 + 1e-9);
        }
    };

    struct MeshTree {
        Triangles triangles;                // the mesh's triangles with an area, in index order
        std::vector<uint8_t> double_sided;  // per kept triangle, from its primitive
        Tree tree;                          // holds iterators into `triangles`: a MeshTree never moves
    };

    struct Frame {
        uint32_t mesh = 0;
        std::array<double, 12> to_world{}, to_mesh{};
        bool usable = false;
    };

    // Exactly collinear triangles never block (the runtime's planes are all zero there): left out.
    static std::unique_ptr<MeshTree> build_mesh(const cb::Mesh& mesh) {
        auto m = std::make_unique<MeshTree>();
        std::vector<uint8_t> sided(mesh.triangle_count(), 0);
        for (const cb::Primitive& p : mesh.primitives)
            for (uint32_t t = p.first_triangle; t < p.first_triangle + p.triangle_count && t < sided.size(); ++t)
                sided[t] = p.double_sided;
        for (size_t t = 0; t < mesh.triangle_count(); ++t) {
            Epick::Point_3 v[3];
            for (int k = 0; k < 3; ++k) {
                const float* q = &mesh.positions[size_t(mesh.indices[t * 3 + k]) * 3];
                v[k] = Epick::Point_3(q[0], q[1], q[2]);
            }
            if (CGAL::collinear(v[0], v[1], v[2])) continue;
            m->triangles.emplace_back(v[0], v[1], v[2]);
            m->double_sided.push_back(sided[t]);
        }
        if (!m->triangles.empty()) {
            m->tree.insert(m->triangles.cbegin(), m->triangles.cend());
            m->tree.build();  // now, not lazily at the first query: queries may come from several threads
        }
        return m;
    }

    // Every instance: p and the light taken into the mesh frame exactly as the runtime maps them, then each
    // candidate triangle decided exactly. Candidates: those the AABB tree says the closed segment meets, or
    // (brute force) all of them.
    // A sun (`sun`): `light` is its direction, the ray taken into each mesh frame by the transform's linear part.
    OracleAnswer answer(const double* p, const double* light, bool one_sided, bool use_trees, bool sun = false) const {
        OracleAnswer a;
        // In world space: the same at every instance.
        const double from = sun ? oracle_sun_from(light, bias_) : oracle_from(p, light, bias_);
        if (!(sun ? std::isfinite(from) : from <= 1)) return a;  // within the bias of the light, or not finite
        bool blocked_by_a_crossing = false;
        std::vector<size_t> candidates;
        for (const Frame& f : frames_) {
            const MeshTree& m = *meshes_[f.mesh];
            if (!f.usable || m.triangles.empty()) continue;  // a singular transform flattens the mesh
            double lp[3], ll[3];
            cb::apply_instance(f.to_mesh.data(), p, lp);
            if (sun)
                cb::apply_linear(f.to_mesh.data(), light, ll);
            else
                cb::apply_instance(f.to_mesh.data(), light, ll);
            // p at the light, or a sun without a direction: nothing blocks (and CGAL wants a real segment).
            if (sun ? ll[0] == 0 && ll[1] == 0 && ll[2] == 0 : lp[0] == ll[0] && lp[1] == ll[1] && lp[2] == ll[2])
                continue;
            candidates.clear();
            if (use_trees) {
                std::vector<Triangles::const_iterator> met;
                const Epick::Point_3 start(lp[0], lp[1], lp[2]);
                if (sun) {
                    RayCandidates near{lp, ll, &m.triangles, &candidates};
                    m.tree.traversal(0, near);
                } else {
                    m.tree.all_intersected_primitives(Epick::Segment_3(start, Epick::Point_3(ll[0], ll[1], ll[2])),
                                                      std::back_inserter(met));
                }
                for (Triangles::const_iterator t : met) candidates.push_back(size_t(t - m.triangles.begin()));
            } else {
                for (size_t k = 0; k < m.triangles.size(); ++k) candidates.push_back(k);
            }
            for (size_t k : candidates) {
                double c[3][3];
                for (int v = 0; v < 3; ++v)
                    for (int j = 0; j < 3; ++j)
                        c[v][j] = CGAL::to_double(m.triangles[k].vertex(v)[j]);  // doubles from floats: exact
                const bool two_sided = !one_sided || m.double_sided[k];
                cb::SegmentTest r = sun ? oracle_ray(lp, ll, c[0], c[1], c[2], from, two_sided)
                                        : oracle(lp, ll, c[0], c[1], c[2], from, two_sided);
                a.touching |= r.touching;
                a.blocked |= r.blocks;
                blocked_by_a_crossing |= r.blocks && !r.touching;
            }
        }
        a.only_touching = a.blocked && !blocked_by_a_crossing;
        return a;
    }

    std::vector<std::unique_ptr<MeshTree>> meshes_;
    std::vector<Frame> frames_;
    double bias_;
};

}  // namespace cb::test
