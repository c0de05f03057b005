// The exact per-triangle shadow semantics shared by the shadow tests and the long check tool: CGAL's exact
// intersection construction with the runtime's semantics (cb_shadow.h). Whole queries over a scene are
// SceneOracle's (scene_oracle.h).
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

// Where contacts start to count, as docs/RUNTIME.md states the self-shadowing rule: the bias over the
// distance from p to the light, in double, the squares summed by fused multiply-adds z, then y onto x's.
inline double oracle_from(const double* p, const double* light, double bias) {
    const double d[3] = {light[0] - p[0], light[1] - p[1], light[2] - p[2]};
    const double squares = std::fma(d[2], d[2], std::fma(d[1], d[1], d[0] * d[0]));
    return bias / std::sqrt(squares);
}

// The same semantics as cb::segment_triangle, built from CGAL's exact intersection construction instead:
// contacts count from parameter `from` on (oracle_from). One-sided (two_sided false): only a triangle with
// the light (q) strictly on its negative side, CGAL's side opposite the counter-clockwise normal, can block.
inline cb::SegmentTest oracle(const double* p, const double* q, const double* a, const double* b, const double* c,
                              double from, bool two_sided = true) {
    cb::SegmentTest r;
    Epeck::Point_3 P(p[0], p[1], p[2]), Q(q[0], q[1], q[2]), A(a[0], a[1], a[2]), B(b[0], b[1], b[2]),
        C(c[0], c[1], c[2]);
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
    r.blocks = from <= 1 && tt >= Epeck::FT(from);
    return r;
}

// The sun's semantics (cb::ray_triangle): the ray p + t d, t >= from, against the closed triangle, from
// CGAL's exact ray-triangle intersection. The sun lies past every triangle along d: one-sided, a triangle
// blocks only with A + d strictly on its negative side.
inline cb::SegmentTest oracle_ray(const double* p, const double* d, const double* a, const double* b, const double* c,
                                  double from, bool two_sided = true) {
    cb::SegmentTest r;
    Epeck::Point_3 P(p[0], p[1], p[2]), A(a[0], a[1], a[2]), B(b[0], b[1], b[2]), C(c[0], c[1], c[2]);
    Epeck::Vector_3 D(d[0], d[1], d[2]);
    if (CGAL::collinear(A, B, C) || D == CGAL::NULL_VECTOR) return r;
    const CGAL::Orientation od = CGAL::orientation(A, B, C, A + D), op = CGAL::orientation(A, B, C, P);
    if (!two_sided && od != CGAL::NEGATIVE) return r;
    if (od == CGAL::COPLANAR) return r;  // parallel to the plane: edge-on, or never meeting it
    Epeck::Ray_3 ray(P, D);
    Epeck::Triangle_3 t(A, B, C);
    if (!CGAL::do_intersect(ray, t)) return r;
    auto hit = CGAL::intersection(ray, t);
    const Epeck::Point_3* x = boost::get<Epeck::Point_3>(&*hit);
    if (!x) return r;
    const bool on_edge = CGAL::collinear(A, B, *x) || CGAL::collinear(B, C, *x) || CGAL::collinear(C, A, *x);
    const Epeck::FT tt = ((*x - P) * D) / (D * D);
    r.blocks = std::isfinite(from) && tt >= Epeck::FT(from);
    r.touching = r.blocks && (on_edge || op == CGAL::COPLANAR);  // a boundary contact that counts
    return r;
}

// The sun's `from`: the bias over the direction's length, as oracle_from.
inline double oracle_sun_from(const double* d, double bias) {
    const double zero[3] = {0, 0, 0};
    return oracle_from(zero, d, bias);
}

// Instanced vertices in world space (every `stride`-th: points on the surfaces) and their bounds; made by
// sample_scene (scene_oracle.h).
struct WorldSample {
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    std::vector<std::array<double, 3>> surface;
    double size() const { return std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]}); }
};

}  // namespace cb::test
