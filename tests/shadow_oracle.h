// The exact shadow oracle shared by the shadow tests and the long check tool: CGAL's exact intersection
// construction, brute force over every triangle, with the runtime's semantics (cb_shadow.h); and helpers
// to bake a scene in memory and sample it.
#pragma once

#include <CGAL/Exact_predicates_exact_constructions_kernel.h>

#include <cb_asset.h>
#include <cb_shadow.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "baked.h"

namespace cb::test {

using Epeck = CGAL::Exact_predicates_exact_constructions_kernel;

// The same semantics as cb::segment_triangle, built from CGAL's exact intersection construction instead.
// One-sided (two_sided false): only a triangle with the light (q) strictly on its negative side, CGAL's
// side opposite the counter-clockwise normal, can block.
inline cb::SegmentTest oracle(const double* p, const double* q, const double* a, const double* b, const double* c,
                       bool two_sided = true) {
    cb::SegmentTest r;
    Epeck::Point_3 P(p[0], p[1], p[2]), Q(q[0], q[1], q[2]), A(a[0], a[1], a[2]), B(b[0], b[1], b[2]), C(c[0], c[1], c[2]);
    if (CGAL::collinear(A, B, C)) return r;
    if (!two_sided && CGAL::orientation(A, B, C, Q) != CGAL::NEGATIVE) return r;
    CGAL::Orientation op = CGAL::orientation(A, B, C, P), oq = CGAL::orientation(A, B, C, Q);
    if (op == CGAL::COPLANAR && oq == CGAL::COPLANAR) return r;
    Epeck::Segment_3 s(P, Q);
    Epeck::Triangle_3 t(A, B, C);
    if (!CGAL::do_intersect(s, t)) return r;
    auto hit = CGAL::intersection(s, t);
    const Epeck::Point_3* x = boost::get<Epeck::Point_3>(&*hit);
    if (!x) return r;  // a segment piece would mean coplanar, excluded above
    bool on_edge = CGAL::collinear(A, B, *x) || CGAL::collinear(B, C, *x) || CGAL::collinear(C, A, *x);
    r.touching = on_edge || op == CGAL::COPLANAR || oq == CGAL::COPLANAR;
    Epeck::FT tt = ((*x - P) * (Q - P)) / ((Q - P) * (Q - P));
    r.blocks = tt >= Epeck::FT(cb::self_shadow_fraction);
    return r;
}


// Brute force over every triangle of every instance, with CGAL's exact construction.
inline bool oracle_occluded(const cb::AssetView& v, const double* p, const double* light, bool& touching, bool one_sided) {
    touching = false;
    for (uint32_t i = 0; i < v.instance_count; ++i) {
        double inv[12], lp[3], ll[3];
        if (!cb::invert_instance(v.instances[i].transform, inv)) continue;
        cb::apply_instance(inv, p, lp);
        cb::apply_instance(inv, light, ll);
        const cb::MeshRecord& m = v.meshes[v.instances[i].mesh];
        for (uint32_t f = 0; f < m.fine_count; ++f) {
            const cb::FineCluster& fc = v.fine[m.first_fine + f];
            for (uint32_t t = fc.first_triangle; t < fc.first_triangle + fc.triangle_count; ++t) {
                uint32_t id[3];
                v.triangle(m, f, t, id);
                double c[3][3];
                for (int k = 0; k < 3; ++k)
                    for (int j = 0; j < 3; ++j) c[k][j] = v.position(m, id[k])[j];
                cb::SegmentTest s = oracle(lp, ll, c[0], c[1], c[2], !one_sided || v.double_sided(size_t(m.first_triangle) + t));
                touching |= s.touching;
                if (s.blocks) return true;
            }
        }
    }
    return false;
}

// The instanced vertices in world space (every `stride`-th: points on the surfaces) and their bounds.
struct WorldSample {
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    std::vector<std::array<double, 3>> surface;
    double size() const { return std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]}); }
};

inline WorldSample sample_world(const cb::AssetView& v, uint32_t stride) {
    WorldSample w;
    for (uint32_t i = 0; i < v.instance_count; ++i) {
        const cb::MeshRecord& m = v.meshes[v.instances[i].mesh];
        for (uint32_t k = 0; k < m.vertex_count; ++k) {
            const float* q = v.positions + (size_t(m.first_vertex) + k) * 3;
            double local[3] = {q[0], q[1], q[2]}, p[3];
            cb::apply_instance(v.instances[i].transform, local, p);
            for (int j = 0; j < 3; ++j) w.lo[j] = std::min(w.lo[j], p[j]), w.hi[j] = std::max(w.hi[j], p[j]);
            if (k % stride == 0) w.surface.push_back({p[0], p[1], p[2]});
        }
    }
    return w;
}


}  // namespace cb::test
