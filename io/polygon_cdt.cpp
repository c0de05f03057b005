#include "polygon_cdt.h"

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <algorithm>
#include <climits>
#include <numeric>

namespace cb {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;

// Per face: its winding number about the polygon, and for each edge how the polygon's edges along it
// change that number from the face to its neighbour (+1 for each edge the face lies to the left of).
struct FaceInfo {
    int winding = INT_MIN;  // INT_MIN until reached
    int step[3] = {0, 0, 0};
};

using Vb = CGAL::Triangulation_vertex_base_with_info_2<uint32_t, K>;  // the vertex's position group
using Fb = CGAL::Constrained_triangulation_face_base_2<K, CGAL::Triangulation_face_base_with_info_2<FaceInfo, K>>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
using Cdt = CGAL::Constrained_Delaunay_triangulation_2<K, Tds, CGAL::No_constraint_intersection_tag>;
using Point = K::Point_2;

int orient(const Point& a, const Point& b, const Point& c) {
    return CGAL::orientation(a, b, c) == CGAL::LEFT_TURN ? 1 : CGAL::orientation(a, b, c) == CGAL::RIGHT_TURN ? -1 : 0;
}

// 0 for directions in the half turn counterclockwise from `from` (itself included), 1 for the other half.
int half(const Point& p, const Point& from, const Point& x) {
    int o = orient(p, from, x);
    if (o != 0) return o > 0 ? 0 : 1;
    // On the line through p and `from`: the same half when on the same side of p.
    return (from < p) == (x < p) ? 0 : 1;
}

// Whether the direction p->x comes no later than p->y, sweeping counterclockwise from p->from.
bool no_later(const Point& p, const Point& from, const Point& x, const Point& y) {
    int hx = half(p, from, x), hy = half(p, from, y);
    if (hx != hy) return hx < hy;
    return orient(p, x, y) >= 0;
}

// Whether the triangle (p, q, r), counterclockwise, lies in the corner of the polygon at a visit of p
// whose interior sweeps counterclockwise from p->first to p->last.
bool in_corner(const Point& p, const Point& q, const Point& r, const Point& first, const Point& last) {
    return no_later(p, first, q, r) && no_later(p, first, r, last);
}

}  // namespace

bool triangulate_constrained(const double* uv, const uint32_t* ring, size_t m, int winding,
                             std::vector<uint32_t>& out) {
    auto point = [uv](size_t i) { return Point(uv[2 * i], uv[2 * i + 1]); };
    // Vertices at one projected point form a group (the polygon touching itself there): one CDT vertex.
    std::vector<uint32_t> order(m), group(m);
    std::iota(order.begin(), order.end(), 0u);
    std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
        return uv[2 * a] < uv[2 * b] || (uv[2 * a] == uv[2 * b] && uv[2 * a + 1] < uv[2 * b + 1]);
    });
    std::vector<std::pair<Point, uint32_t>> points;
    std::vector<uint32_t> first_visit;  // per group: where its visits start in `order`
    for (size_t k = 0; k < m; ++k) {
        const uint32_t i = order[k];
        if (k == 0 || point(order[k - 1]) != point(i)) {
            points.emplace_back(point(i), uint32_t(points.size()));
            first_visit.push_back(uint32_t(k));
        }
        group[i] = uint32_t(points.size() - 1);
    }
    first_visit.push_back(uint32_t(m));

    Cdt cdt;
    cdt.insert(points.begin(), points.end());
    std::vector<Cdt::Vertex_handle> handle(points.size());
    for (auto v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v) handle[v->info()] = v;

    // The edges as constraints; one walked twice (there and back) is constrained once. A constraint
    // through a vertex is split there by CGAL: then some polygon edge is no edge of the triangulation.
    auto next = [m](size_t i) { return i + 1 == m ? 0 : i + 1; };
    try {
        for (size_t i = 0; i < m; ++i) {
            Cdt::Vertex_handle a = handle[group[i]], b = handle[group[next(i)]];
            Cdt::Face_handle f;
            int e;
            if (cdt.is_edge(a, b, f, e) && f->is_constrained(e)) continue;
            cdt.insert_constraint(a, b);
        }
    } catch (const Cdt::Intersection_of_constraints_exception&) {
        return false;
    }
    for (size_t i = 0; i < m; ++i) {
        Cdt::Vertex_handle a = handle[group[i]], b = handle[group[next(i)]];
        Cdt::Face_handle f;
        int e;
        if (!cdt.is_edge(a, b, f, e)) return false;
        const int sign = f->vertex(Cdt::ccw(e)) == a ? 1 : -1;  // f lies left of a->b
        Cdt::Face_handle g = f->neighbor(e);
        f->info().step[e] += sign;
        g->info().step[g->index(f)] -= sign;
    }

    // Winding numbers, from the outside (0) across every edge.
    std::vector<Cdt::Face_handle> stack = {cdt.infinite_face()};
    cdt.infinite_face()->info().winding = 0;
    while (!stack.empty()) {
        Cdt::Face_handle f = stack.back();
        stack.pop_back();
        for (int e = 0; e < 3; ++e) {
            Cdt::Face_handle g = f->neighbor(e);
            const int w = f->info().winding - f->info().step[e];
            if (g->info().winding == INT_MIN) {
                g->info().winding = w;
                stack.push_back(g);
            } else if (g->info().winding != w) {
                return false;
            }
        }
    }

    // The inside, each corner named by the visit of its vertex whose corner holds the triangle.
    auto visit = [&](Cdt::Vertex_handle v, const Point& q, const Point& r) -> int64_t {
        const uint32_t g = v->info();
        if (first_visit[g + 1] - first_visit[g] == 1) return ring[order[first_visit[g]]];
        for (uint32_t k = first_visit[g]; k < first_visit[g + 1]; ++k) {
            const size_t i = order[k];
            const Point after = point(next(i)), before = point(i == 0 ? m - 1 : i - 1);
            if (winding > 0 ? in_corner(v->point(), q, r, after, before) : in_corner(v->point(), q, r, before, after))
                return ring[i];
        }
        return -1;
    };
    const size_t start = out.size();
    for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
        const int w = f->info().winding;
        if (w == 0) continue;
        if (w != winding) {
            out.resize(start);
            return false;
        }
        int64_t corner[3];
        for (int c = 0; c < 3; ++c)
            corner[c] = visit(f->vertex(c), f->vertex(Cdt::ccw(c))->point(), f->vertex(Cdt::cw(c))->point());
        if (corner[0] < 0 || corner[1] < 0 || corner[2] < 0) {
            out.resize(start);
            return false;
        }
        // CGAL's faces are counterclockwise; a clockwise polygon's triangles are turned to its winding.
        if (winding > 0)
            out.insert(out.end(), {uint32_t(corner[0]), uint32_t(corner[1]), uint32_t(corner[2])});
        else
            out.insert(out.end(), {uint32_t(corner[0]), uint32_t(corner[2]), uint32_t(corner[1])});
    }
    return out.size() > start;
}

}  // namespace cb
