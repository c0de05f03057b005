// Polygon triangulation by ear clipping in the polygon's plane, with exact orientation tests
// (polygon_triangulate.h).
#include "polygon_triangulate.h"

#include <algorithm>
#include <cmath>

#include "detail/cb_exact.h"
#include "polygon_cdt.h"

namespace cb {
namespace {

// Sign of the orientation of the 2-D points a, b, c: +1 when they turn counterclockwise, 0 when collinear,
// always exact. A double evaluation with Shewchuk's error bound settles almost every call; the rest are
// evaluated exactly with the runtime's floating-point expansions (cb_exact.h). Inputs are float
// coordinates, well inside the domain where that bound holds.
[[gnu::noinline]] int orient2d_exact(const double* a, const double* b, const double* c) {
    using namespace exact;
    double det[16];
    const int n =
        det2_exact(difference(a[0], c[0]), difference(a[1], c[1]), difference(b[0], c[0]), difference(b[1], c[1]), det);
    return sign(det, n);
}

inline int orient2d(const double* a, const double* b, const double* c) {
    double acx = a[0] - c[0], bcx = b[0] - c[0], acy = a[1] - c[1], bcy = b[1] - c[1];
    double left = acx * bcy, right = acy * bcx, det = left - right;
    // Shewchuk's bound for this evaluation is (3 + 16 eps) eps (|left| + |right|), eps = 2^-53; 1e-15 is
    // above it. Both products zero means a difference was exactly zero: the determinant is zero.
    double bound = 1e-15 * (std::fabs(left) + std::fabs(right));
    if (det > bound) return 1;
    if (-det > bound) return -1;
    if (bound == 0) return 0;
    return orient2d_exact(a, b, c);  // apart, so the common path needs no room for expansions
}

int compare(double a, double b) { return (a > b) - (a < b); }

// For collinear a, b, c: whether c lies on the closed segment ab.
bool within(const double* a, const double* b, const double* c) {
    return std::min(a[0], b[0]) <= c[0] && c[0] <= std::max(a[0], b[0]) && std::min(a[1], b[1]) <= c[1] &&
        c[1] <= std::max(a[1], b[1]);
}

bool equal(const double* a, const double* b) { return a[0] == b[0] && a[1] == b[1]; }

bool lexicographically_less(const double* a, const double* b) { return a[0] < b[0] || (a[0] == b[0] && a[1] < b[1]); }

// How two edges that are not neighbours in the polygon meet.
enum class Contact { none, at_vertices, crossing };

// `at_vertices` when the closed segments ab and cd share only points that are endpoints of both (two
// vertices at one position, or an edge walked there and back, as the bridge into a hole); `crossing` when
// they cross, overlap or one's endpoint lies inside the other.
Contact contact(const double* a, const double* b, const double* c, const double* d) {
    int d1 = orient2d(c, d, a), d2 = orient2d(c, d, b), d3 = orient2d(a, b, c), d4 = orient2d(a, b, d);
    if (d1 * d2 < 0 && d3 * d4 < 0) return Contact::crossing;
    if (d1 == 0 && d2 == 0) {  // on one line: compare the two intervals along it
        const double *lo1 = a, *hi1 = b, *lo2 = c, *hi2 = d;
        if (lexicographically_less(hi1, lo1)) std::swap(lo1, hi1);
        if (lexicographically_less(hi2, lo2)) std::swap(lo2, hi2);
        const double* lo = lexicographically_less(lo1, lo2) ? lo2 : lo1;
        const double* hi = lexicographically_less(hi1, hi2) ? hi1 : hi2;
        if (lexicographically_less(hi, lo)) return Contact::none;
        if (equal(lo, hi)) return Contact::at_vertices;
        return equal(a, d) && equal(b, c) ? Contact::at_vertices : Contact::crossing;
    }
    bool touch = false;
    auto check = [&](int side, const double* p, const double* s0, const double* s1) {
        if (side != 0 || !within(s0, s1, p)) return true;
        touch = true;
        return equal(p, s0) || equal(p, s1);
    };
    if (!check(d1, a, c, d) || !check(d2, b, c, d) || !check(d3, c, a, b) || !check(d4, d, a, b))
        return Contact::crossing;
    return touch ? Contact::at_vertices : Contact::none;
}

// Marks a clipped vertex in next_.
constexpr uint32_t clipped = UINT32_MAX;

void fan(const uint32_t* poly, size_t n, std::vector<uint32_t>& out) {
    for (size_t i = 1; i + 1 < n; ++i) out.insert(out.end(), {poly[0], poly[i], poly[i + 1]});
}

}  // namespace

// The winding is the turn at the lowest vertex (least u, then least v), which is strictly convex. A
// polygon touching itself may pass that position more than once: every pass must turn the same way, else 0.
int PolygonTriangulator::ring_winding() const {
    const size_t m = ring_.size();
    auto q = [this](size_t i) { return &uv_[2 * i]; };
    size_t low = 0;
    for (size_t i = 1; i < m; ++i)
        if (lexicographically_less(q(i), q(low))) low = i;
    int winding = 0;
    for (size_t i = 0; i < m; ++i)
        if (equal(q(i), q(low)) && turn_[i] != 0) {
            if (winding != 0 && turn_[i] != winding) return 0;
            winding = turn_[i];
        }
    return winding;
}

// A polygon of large_ vertices or more that is neither convex nor degenerate nor spiked: the constrained
// triangulation settles whether it is simple and tiles it in O(n log n).
PolygonShape PolygonTriangulator::add_large(const uint32_t* poly, size_t n, std::vector<uint32_t>& out) {
    const int winding = ring_winding();
    if (winding != 0 && triangulate_constrained(uv_.data(), ring_.data(), ring_.size(), winding, out))
        return PolygonShape::concave;
    fan(poly, n, out);
    return PolygonShape::not_simple;
}

// The polygon without repeated consecutive vertices (by index or by position) into ring_.
bool PolygonTriangulator::make_ring(const float* xyz, const uint32_t* poly, size_t n) {
    auto same = [xyz](uint32_t i, uint32_t j) {
        const float *p = xyz + size_t(i) * 3, *q = xyz + size_t(j) * 3;
        return i == j || (p[0] == q[0] && p[1] == q[1] && p[2] == q[2]);
    };
    ring_.clear();
    for (size_t i = 0; i < n; ++i)
        if (ring_.empty() || !same(ring_.back(), poly[i])) ring_.push_back(poly[i]);
    while (ring_.size() > 1 && same(ring_.back(), ring_.front())) ring_.pop_back();
    return ring_.size() >= 3;
}

// The ring projected onto the coordinate plane its Newell normal points at most along.
void PolygonTriangulator::project(const float* xyz) {
    auto at = [xyz](uint32_t i) { return xyz + size_t(i) * 3; };
    const size_t m = ring_.size();
    // The Newell normal (twice the area vector), about the first vertex to keep large coordinates from
    // cancelling; only the axis it points at most along is used.
    const float* o = at(ring_[0]);
    double normal[3] = {0, 0, 0};
    for (size_t i = 1; i + 1 < m; ++i) {
        const float *p = at(ring_[i]), *q = at(ring_[i + 1]);
        double a[3] = {double(p[0]) - o[0], double(p[1]) - o[1], double(p[2]) - o[2]};
        double b[3] = {double(q[0]) - o[0], double(q[1]) - o[1], double(q[2]) - o[2]};
        normal[0] += a[1] * b[2] - a[2] * b[1];
        normal[1] += a[2] * b[0] - a[0] * b[2];
        normal[2] += a[0] * b[1] - a[1] * b[0];
    }
    int axis = 2;
    if (std::fabs(normal[0]) > std::fabs(normal[1]) && std::fabs(normal[0]) > std::fabs(normal[2]))
        axis = 0;
    else if (std::fabs(normal[1]) > std::fabs(normal[2]))
        axis = 1;
    // The two other coordinates in cyclic order, so the projection keeps the winding seen from +axis.
    const int cu = (axis + 1) % 3, cv = (axis + 2) % 3;
    uv_.resize(2 * m);
    for (size_t i = 0; i < m; ++i) {
        const float* p = at(ring_[i]);
        uv_[2 * i] = p[cu];
        uv_[2 * i + 1] = p[cv];
    }
}

// The orientation at each vertex; `left` and `right` count the vertices turning each way.
void PolygonTriangulator::find_turns(size_t& left, size_t& right) {
    const size_t m = ring_.size();
    turn_.resize(m);
    left = 0;
    right = 0;
    for (size_t i = 0; i < m; ++i) {
        turn_[i] = orient2d(uv(before(i)), uv(i), uv(after(i)));
        left += turn_[i] > 0;
        right += turn_[i] < 0;
    }
}

// A straight vertex goes on in the direction it came from; a spike turns back, and a projected edge of
// zero length has no direction.
bool PolygonTriangulator::straight_on(size_t i) const {
    const double *a = uv(before(i)), *b = uv(i), *c = uv(after(i));
    int u0 = compare(b[0], a[0]), v0 = compare(b[1], a[1]), u1 = compare(c[0], b[0]), v1 = compare(c[1], b[1]);
    return (u0 != 0 || v0 != 0) && u0 == u1 && v0 == v1;
}

// Convex: no vertex dropped from the n of the polygon, no turn against the others, no spike, and the edge
// directions go round exactly once (the sign of their u component changes twice: a pentagram turns one way
// throughout but goes round twice); with straight vertices, also no zero-area triangle in the fan.
bool PolygonTriangulator::is_convex(size_t n, size_t left, size_t right) const {
    const size_t m = ring_.size();
    if (m != n || (left != 0 && right != 0)) return false;
    int first = 0, last = 0, changes = 0;
    for (size_t i = 0; i < m; ++i) {
        if (turn_[i] == 0 && !straight_on(i)) return false;
        int s = compare(uv(after(i))[0], uv(i)[0]);
        if (s == 0) continue;
        if (first == 0) first = s;
        if (last != 0 && s != last) ++changes;
        last = s;
    }
    changes += last != first;
    if (changes != 2) return false;
    // With straight vertices the fan from the first one may hold a triangle of zero area.
    if (left + right < m)
        for (size_t i = 1; i + 1 < m; ++i)
            if (orient2d(uv(0), uv(i), uv(i + 1)) == 0) return false;
    return true;
}

// A vertex where the boundary turns back on itself.
bool PolygonTriangulator::has_spike() const {
    for (size_t i = 0; i < ring_.size(); ++i)
        if (turn_[i] == 0 && !straight_on(i)) return true;
    return false;
}

// Whether two edges that are not neighbours cross or overlap. Edges sorted by their least u, swept: each is
// compared with the later ones that start before it ends. `touching`: whether two meet at vertices only
// (a ring cut open along a bridge edge), which a simple polygon may do.
bool PolygonTriangulator::crosses_itself(bool& touching) {
    const size_t m = ring_.size();
    auto umin = [&](size_t e) { return std::min(uv(e)[0], uv(after(e))[0]); };
    order_.resize(m);
    for (size_t i = 0; i < m; ++i) order_[i] = uint32_t(i);
    std::sort(order_.begin(), order_.end(), [&](uint32_t x, uint32_t y) { return umin(x) < umin(y); });
    touching = false;
    for (size_t k = 0; k < m; ++k) {
        const size_t i = order_[k];
        const double *a = uv(i), *b = uv(after(i));
        double umax = std::max(a[0], b[0]), vmin = std::min(a[1], b[1]), vmax = std::max(a[1], b[1]);
        for (size_t l = k + 1; l < m && umin(order_[l]) <= umax; ++l) {
            const size_t j = order_[l];
            if (j == after(i) || i == after(j)) continue;  // neighbours share a vertex
            const double *c = uv(j), *d = uv(after(j));
            if (std::max(c[1], d[1]) < vmin || std::min(c[1], d[1]) > vmax) continue;
            Contact contact_kind = contact(a, b, c, d);
            if (contact_kind == Contact::crossing) return true;
            touching = touching || contact_kind == Contact::at_vertices;
        }
    }
    return false;
}

// Whether b is an ear: its triangle (a, b, c) holds none of the vertices in order_ (those an ear test
// looks at), not even on its border; vertices no longer needed there are dropped from order_ on the way.
bool PolygonTriangulator::is_ear(uint32_t a, uint32_t b, uint32_t c, int winding, bool touching) {
    const double *pa = uv(a), *pb = uv(b), *pc = uv(c);
    double umin = std::min({pa[0], pb[0], pc[0]}), umax = std::max({pa[0], pb[0], pc[0]});
    double vmin = std::min({pa[1], pb[1], pc[1]}), vmax = std::max({pa[1], pb[1], pc[1]});
    for (size_t k = 0; k < order_.size(); ++k) {
        uint32_t j = order_[k];
        if (next_[j] == clipped || (turn_[j] == winding && !touching)) {  // no longer needed: drop it
            order_[k--] = order_.back();
            order_.pop_back();
            continue;
        }
        if (j == a || j == b || j == c) continue;
        const double* p = uv(j);
        if (p[0] < umin || p[0] > umax || p[1] < vmin || p[1] > vmax) continue;
        if (touching && (equal(p, pa) || equal(p, pb) || equal(p, pc))) continue;
        if (orient2d(pa, pb, p) * winding >= 0 && orient2d(pb, pc, p) * winding >= 0 &&
            orient2d(pc, pa, p) * winding >= 0)
            return false;
    }
    return true;
}

// Whether two of the triangles tris[from..] overlap: two triangles of one winding overlap unless the line
// through an edge of one has the other wholly on its outer side (the separating axis theorem).
bool PolygonTriangulator::any_overlap(size_t from, const std::vector<uint32_t>& tris, int winding) const {
    std::vector<size_t> corner;  // ring position of each index in tris[from..]
    for (size_t t = from; t < tris.size(); ++t)
        corner.push_back(size_t(std::find(ring_.begin(), ring_.end(), tris[t]) - ring_.begin()));
    auto apart = [&](const size_t* s, const size_t* t) {
        for (int e = 0; e < 3; ++e) {
            const double *p0 = uv(s[e]), *p1 = uv(s[(e + 1) % 3]);
            bool outside = true;
            for (int k = 0; k < 3 && outside; ++k) outside = orient2d(p0, p1, uv(t[k])) * winding <= 0;
            if (outside) return true;
        }
        return false;
    };
    for (size_t i = 0; i < corner.size(); i += 3)
        for (size_t j = i + 3; j < corner.size(); j += 3)
            if (!apart(&corner[i], &corner[j]) && !apart(&corner[j], &corner[i])) return true;
    return false;
}

// Ear clipping. An ear is a strictly convex vertex b whose triangle (a, b, c) holds no other vertex, not
// even on its border: then ac is a diagonal and the triangle lies in the polygon. Were any vertex in the
// triangle, the one farthest from ac would be reflex or straight, so in a simple polygon only those are
// tested. Every triangle clipped turns the polygon's way, and the polygon's winding number is, at every
// point, the sum of its triangles': so the triangles cover each point of the polygon once and nothing
// outside it, also where the polygon touches itself (there vertices at a, b or c's position are not counted
// as inside, and should that admit a wrong ear, clipping gets stuck and the fan is kept). Appends the
// triangles to `out` and returns true, or leaves `out` as it was and returns false.
bool PolygonTriangulator::clip_ears(int winding, bool touching, std::vector<uint32_t>& out) {
    const size_t m = ring_.size();
    prev_.resize(m);
    next_.resize(m);
    for (size_t i = 0; i < m; ++i) {
        prev_[i] = uint32_t(before(i));
        next_[i] = uint32_t(after(i));
    }
    // The vertices an ear test looks at: reflex and straight ones (clipping only ever turns those convex,
    // never back), or every vertex where the polygon touches itself. Clipped ones are marked in `next_`.
    order_.clear();
    for (size_t i = 0; i < m; ++i)
        if (touching || turn_[i] != winding) order_.push_back(uint32_t(i));
    const size_t start = out.size();
    size_t remaining = m, misses = 0;
    uint32_t b = 0;
    while (remaining > 3) {
        uint32_t a = prev_[b], c = next_[b];
        if (turn_[b] == winding && is_ear(a, b, c, winding, touching)) {
            out.insert(out.end(), {ring_[a], ring_[b], ring_[c]});
            next_[a] = c;
            prev_[c] = a;
            next_[b] = clipped;
            --remaining;
            turn_[a] = orient2d(uv(prev_[a]), uv(a), uv(c));
            turn_[c] = orient2d(uv(a), uv(c), uv(next_[c]));
            b = c;
            misses = 0;
            continue;
        }
        b = c;
        if (++misses > remaining) break;  // no ear: not simple after all (cannot happen if the tests hold)
    }
    if (remaining == 3 && turn_[b] == winding) {
        out.insert(out.end(), {ring_[prev_[b]], ring_[b], ring_[next_[b]]});
        // Where the polygon touches itself it may also wind round twice (a loop inside a loop, meeting at a
        // vertex): then two triangles overlap, and the polygon is not simple after all.
        if (!touching || !any_overlap(start, out, winding)) return true;
    }
    out.resize(start);
    return false;
}

PolygonShape PolygonTriangulator::add_polygon(const float* xyz, const uint32_t* poly, size_t n,
                                              std::vector<uint32_t>& out) {
    if (!make_ring(xyz, poly, n)) {
        fan(poly, n, out);
        return PolygonShape::degenerate;
    }
    project(xyz);
    size_t left = 0, right = 0;
    find_turns(left, right);
    if (left + right == 0) {  // every vertex on one line
        fan(poly, n, out);
        return PolygonShape::degenerate;
    }
    if (is_convex(n, left, right)) {
        fan(poly, n, out);
        return PolygonShape::convex;
    }
    // Simple: no spike, and no two edges that are not neighbours share a point. Touching itself only at
    // vertices (a ring cut open along a bridge edge) is allowed, but the ear test then needs every vertex.
    if (has_spike()) {
        fan(poly, n, out);
        return PolygonShape::not_simple;
    }
    if (ring_.size() >= large_) return add_large(poly, n, out);
    bool touching = false;
    const int winding = crosses_itself(touching) ? 0 : ring_winding();
    if (winding != 0 && clip_ears(winding, touching, out)) return PolygonShape::concave;
    fan(poly, n, out);
    return PolygonShape::not_simple;
}

PolygonShape triangulate_polygon(const float* xyz, const uint32_t* poly, size_t n, std::vector<uint32_t>& out,
                                 size_t large) {
    PolygonTriangulator triangulator(large);
    return triangulator.add(xyz, poly, n, out);
}

}  // namespace cb
