// Oriented boxes: the PCA frames (of the vertices, and area-weighted over the triangles), the refined frame
// (minimum-area rectangles across PCA axes and triangle normals, then a descent over small rotations),
// CGAL's optimum (obb_cgal.cpp); the frame stored as a packed box.
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cstring>
#include <vector>

#include "fitting.h"
#include "vector_clones.h"

namespace cb {

// Defined in obb_cgal.cpp: CGAL's optimal box frame, rows are axes. False when CGAL cannot fit one.
bool cgal_optimal_frame(const double* points, size_t n, double frame[3][3]);

namespace fitting {
namespace {

void make_right_handed(Frame& f) {
    Vec a{f.axis[0][0], f.axis[0][1], f.axis[0][2]}, b{f.axis[1][0], f.axis[1][1], f.axis[1][2]};
    Vec c = cross(a, b);
    for (int k = 0; k < 3; ++k) f.axis[2][k] = c[k];
}

// Extents of the points along a frame: lo/hi per axis.
void extents(const double* pts, size_t n, const Frame& f, double lo[3], double hi[3]) {
    for (int i = 0; i < 3; ++i) {
        lo[i] = INFINITY;
        hi[i] = -INFINITY;
    }
    for (size_t v = 0; v < n; ++v)
        for (int i = 0; i < 3; ++i) {
            double d = dot3(pts + v * 3, f.axis[i]);
            lo[i] = std::min(lo[i], d);
            hi[i] = std::max(hi[i], d);
        }
}

Frame eigen_frame(const Eigen::Matrix3d& cov) {
    // The closed-form solver: the frame only starts the search and every extent is measured afterwards, so
    // the iterative solver's last digits buy nothing (the same PCA box volumes on the 13 scanned meshes).
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
    solver.computeDirect(cov);
    Frame f;
    // Largest variance first.
    for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k) f.axis[i][k] = solver.eigenvectors()(k, 2 - i);
    make_right_handed(f);
    return f;
}

// The covariance's six distinct entries, each summed over the points in order.
Frame pca_frame(const double* pts, size_t n) {
    double mean[3] = {0, 0, 0};
    for (size_t v = 0; v < n; ++v)
        for (int k = 0; k < 3; ++k) mean[k] += pts[v * 3 + k];
    for (int k = 0; k < 3; ++k) mean[k] /= double(n);
    double xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0;
    for (size_t v = 0; v < n; ++v) {
        const double x = pts[v * 3] - mean[0], y = pts[v * 3 + 1] - mean[1], z = pts[v * 3 + 2] - mean[2];
        xx += x * x;
        xy += x * y;
        xz += x * z;
        yy += y * y;
        yz += y * z;
        zz += z * z;
    }
    Eigen::Matrix3d cov;
    cov << xx, xy, xz, xy, yy, yz, xz, yz, zz;
    return eigen_frame(cov);
}

// Covariance of the triangles as continuous surfaces (Gottschalk, Lin and Manocha): each triangle weighs
// by its area, so dense tessellation in one corner does not tilt the frame. Every `stride`-th triangle from
// the first only. False when their area is zero.
bool area_frame(const float* positions, const uint32_t* indices, const uint32_t* tris, size_t count,
                const double* origin, Frame& out, size_t stride = 1) {
    // The second moment's six distinct entries (the solver reads the lower triangle), each summed as the
    // matrix expression area / 12 * (9 m m^T + sum of p p^T) sums it, term by term in that order.
    constexpr int row[6] = {0, 1, 2, 1, 2, 2}, col[6] = {0, 0, 0, 1, 1, 2};
    double second[6] = {0, 0, 0, 0, 0, 0};
    Eigen::Vector3d first = Eigen::Vector3d::Zero();
    double total = 0;
    for (size_t i = 0; i < count; i += stride) {
        Eigen::Vector3d p[3];
        for (int k = 0; k < 3; ++k) {
            const float* q = positions + size_t(indices[size_t(tris[i]) * 3 + k]) * 3;
            p[k] = Eigen::Vector3d(q[0] - origin[0], q[1] - origin[1], q[2] - origin[2]);
        }
        double area = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).norm();
        if (!(area > 0)) continue;
        Eigen::Vector3d m = (p[0] + p[1] + p[2]) / 3.0;
        const double weight = area / 12.0;
        for (int e = 0; e < 6; ++e) {
            const int r = row[e], c = col[e];
            second[e] += weight * ((9.0 * m[r]) * m[c] + p[0][r] * p[0][c] + p[1][r] * p[1][c] + p[2][r] * p[2][c]);
        }
        first += area * m;
        total += area;
    }
    if (!(total > 0)) return false;
    Eigen::Matrix3d moment;
    for (int e = 0; e < 6; ++e) moment(row[e], col[e]) = moment(col[e], row[e]) = second[e];
    Eigen::Vector3d mean = first / total;
    out = eigen_frame(moment / total - mean * mean.transpose());
    return true;
}

typedef std::array<double, 2> Point2;

// 2-D convex hull (monotone chain) of p[0, n) (sorted in place) into h, counter-clockwise, collinear points
// dropped; returns its size. `h` has room for 2n points.
size_t hull2d(Point2* p, size_t n, Point2* h) {
    // std::array's own order, spelled out: its generic lexicographic compare was most of this function. A
    // fine cluster's few points sort fastest by insertion; points that compare equal differ at most in the
    // sign of a zero, which moves no extent, so the sort's choice among them changes no rectangle.
    auto before = [](const Point2& a, const Point2& b) { return a[0] < b[0] || (a[0] == b[0] && a[1] < b[1]); };
    if (n <= 32) {
        for (size_t i = 1; i < n; ++i) {
            const Point2 x = p[i];
            size_t j = i;
            for (; j > 0 && before(x, p[j - 1]); --j) p[j] = p[j - 1];
            p[j] = x;
        }
    } else {
        std::sort(p, p + n, before);
    }
    n = size_t(std::unique(p, p + n, [](const Point2& a, const Point2& b) { return a[0] == b[0] && a[1] == b[1]; }) -
               p);
    if (n < 3) {
        std::copy_n(p, n, h);
        return n;
    }
    auto turn = [](const Point2& o, const Point2& a, const Point2& b) {
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
    };
    size_t k = 0;
    for (size_t i = 0; i < n; ++i) {
        while (k >= 2 && turn(h[k - 2], h[k - 1], p[i]) <= 0) --k;
        h[k++] = p[i];
    }
    for (size_t i = n - 1, t = k + 1; i-- > 0;) {
        while (k >= t && turn(h[k - 2], h[k - 1], p[i]) <= 0) --k;
        h[k++] = p[i];
    }
    return k - 1;
}

// Keeps axis `fixed` of the frame and turns the other two to the minimum-area rectangle of the points
// projected on their plane (one rectangle side lies on a hull edge: test every edge direction).
Frame min_area_rect_frame(const double* pts, size_t n, const Frame& f, int fixed) {
    const int u = (fixed + 1) % 3, w = (fixed + 2) % 3;
    // A fine cluster's points and hull on the stack; a larger set's in scratch kept by the thread.
    constexpr size_t few = 64;
    Point2 proj_few[few], hull_few[2 * few + 1];
    thread_local std::vector<Point2> proj_many, hull_many;
    Point2* proj = proj_few;
    Point2* h = hull_few;
    if (n > few) {
        proj_many.resize(n);
        hull_many.resize(2 * n + 1);
        proj = proj_many.data();
        h = hull_many.data();
    }
    for (size_t v = 0; v < n; ++v) proj[v] = {dot3(pts + v * 3, f.axis[u]), dot3(pts + v * 3, f.axis[w])};
    const size_t m = hull2d(proj, n, h);
    double best = INFINITY, best_c = 1, best_s = 0;
    // Rotating calipers: across the edges in counter-clockwise order, the vertex farthest along the edge
    // (i), farthest from it (j) and farthest back (k) only move forward, so each edge costs a few steps
    // instead of a pass over the hull. The near side is the edge itself.
    if (m >= 3)
        for (size_t v = 0; v <= m; ++v) h[m + v] = h[v];  // the hull twice round and once more: no wrapping
    auto along = [&](size_t v, double c, double s) { return c * h[v][0] + s * h[v][1]; };
    auto across = [&](size_t v, double c, double s) { return -s * h[v][0] + c * h[v][1]; };
    for (size_t e = 0, i = 1, j = 1, k = 1; e < m && m >= 3; ++e) {
        // Along the edge's own vector (dx, dy), not its unit direction: the area is then the product over
        // dx^2 + dy^2, one division where normalising took a root and two.
        const double dx = h[e + 1][0] - h[e][0], dy = h[e + 1][1] - h[e][1], len2 = dx * dx + dy * dy;
        if (!(len2 > 0)) continue;
        i = std::max(i, e + 1);
        while (i < e + m && along(i + 1, dx, dy) >= along(i, dx, dy)) ++i;
        j = std::max(j, i);
        while (j < e + m && across(j + 1, dx, dy) >= across(j, dx, dy)) ++j;
        k = std::max(k, j);
        while (k < e + m && along(k + 1, dx, dy) <= along(k, dx, dy)) ++k;
        double lo1 = std::min(across(e, dx, dy), across(e + 1, dx, dy));
        double area = (along(i, dx, dy) - along(k, dx, dy)) * (across(j, dx, dy) - lo1) / len2;
        if (area < best) {
            const double len = std::sqrt(len2);
            best = area;
            best_c = dx / len;
            best_s = dy / len;
        }
    }
    Frame out = f;
    for (int k = 0; k < 3; ++k) {
        out.axis[u][k] = best_c * f.axis[u][k] + best_s * f.axis[w][k];
        out.axis[w][k] = -best_s * f.axis[u][k] + best_c * f.axis[w][k];
    }
    // Keep the rows in the fixed/u/w roles, then restore handedness.
    Vec a{out.axis[0][0], out.axis[0][1], out.axis[0][2]}, b{out.axis[1][0], out.axis[1][1], out.axis[1][2]};
    Vec c = cross(a, b);
    if (dot3(c.data(), out.axis[2]) < 0)
        for (int k = 0; k < 3; ++k) out.axis[2][k] = -out.axis[2][k];
    return out;
}

// Turns a frame about its axis `k` by the angle of cosine `c` and sine `s` (the other two axes rotate in
// their plane).
Frame rotated(const Frame& f, int k, double c, double s) {
    int u = (k + 1) % 3, w = (k + 2) % 3;
    Frame out = f;
    for (int j = 0; j < 3; ++j) {
        out.axis[u][j] = c * f.axis[u][j] + s * f.axis[w][j];
        out.axis[w][j] = -s * f.axis[u][j] + c * f.axis[w][j];
    }
    return out;
}

// A frame whose axis 0 is `n` (unit), the others arbitrary; min_area_rect_frame then turns them.
Frame frame_around(const Vec& n) {
    Vec helper = std::fabs(n[0]) < 0.6 ? Vec{1, 0, 0} : Vec{0, 1, 0};
    Vec u = cross(n, helper);
    double ul = norm(u);
    Vec w = cross(n, {u[0] / ul, u[1] / ul, u[2] / ul});
    Frame f;
    for (int j = 0; j < 3; ++j) {
        f.axis[0][j] = n[j];
        f.axis[1][j] = u[j] / ul;
        f.axis[2][j] = w[j];
    }
    return f;
}

// Four doubles: GCC's vector extension, one register under AVX2 and AVX-512, two under SSE2. The descent's
// loops run over coordinate arrays padded to a multiple of four with copies of the last point, which change
// no minimum or maximum, so they take whole vectors only.
typedef double Lanes __attribute__((vector_size(32)));
constexpr size_t lane_count = 4;

// Helpers by reference: a vector passed or returned by value would take another calling convention in each
// clone.
void load_lanes(const double* p, Lanes& v) { std::memcpy(&v, p, sizeof v); }
void fill_lanes(double x, Lanes& v) { v = Lanes{x, x, x, x}; }
// Lane 0 of the result: the lowest (highest) of the four, halves folded in vector registers (through
// std::min's references the lanes would go to memory, and the compares to branches).
// (__builtin_shufflevector: GCC 12 and clang both have it; the fuzzing build uses clang.)
void fold_lowest(Lanes& v) {
    Lanes w = __builtin_shufflevector(v, v, 2, 3, 0, 1);
    v = w < v ? w : v;
    w = __builtin_shufflevector(v, v, 1, 0, 3, 2);
    v = w < v ? w : v;
}
void fold_highest(Lanes& v) {
    Lanes w = __builtin_shufflevector(v, v, 2, 3, 0, 1);
    v = w > v ? w : v;
    w = __builtin_shufflevector(v, v, 1, 0, 3, 2);
    v = w > v ? w : v;
}
double lowest(const Lanes& lanes) {
    Lanes v = lanes;
    fold_lowest(v);
    return v[0];
}
double highest(const Lanes& lanes) {
    Lanes v = lanes;
    fold_highest(v);
    return v[0];
}

// Box cost: volume, with every side padded by a tiny fraction of the diagonal so flat and needle sets still
// compare by area and length instead of all tying at zero. Coordinates come as three arrays (x, y, z) of a
// multiple of four points, the form the refinement's evaluations run fastest on (docs/PERFORMANCE.md): one
// pass for the three axes, in lanes. Each projection is the same double expression in every lane, and
// minima and maxima are exact, so the cost does not depend on the lanes or the processor.
CB_VECTOR_CLONES double soa_cost(const double* x, const double* y, const double* z, size_t n, const Frame& f,
                                 double pad) {
    Lanes lo[3], hi[3];
    for (int i = 0; i < 3; ++i) {
        fill_lanes(INFINITY, lo[i]);
        fill_lanes(-INFINITY, hi[i]);
    }
    for (size_t v = 0; v < n; v += lane_count) {
        Lanes px, py, pz;
        load_lanes(x + v, px);
        load_lanes(y + v, py);
        load_lanes(z + v, pz);
        for (int i = 0; i < 3; ++i) {
            const Lanes d = f.axis[i][0] * px + f.axis[i][1] * py + f.axis[i][2] * pz;
            lo[i] = d < lo[i] ? d : lo[i];
            hi[i] = d > hi[i] ? d : hi[i];
        }
    }
    double side[3];
    for (int i = 0; i < 3; ++i) side[i] = highest(hi[i]) - lowest(lo[i]) + pad;
    return side[0] * side[1] * side[2];
}

// The padded areas of the points' rectangle in a plane after turning its axes by the angle of cosine c and
// sine s (area[0]) and by its opposite (area[1]): (x, y) are the points' coordinates along the two axes
// before turning, a multiple of four. Both turns share the four products of a point, in lanes.
CB_VECTOR_CLONES void turned_areas(const double* x, const double* y, size_t n, double c, double s, double pad,
                                   double area[2]) {
    // lo/hi[t][j]: turn t (0 by +s, 1 by -s), coordinate j of the turned pair.
    Lanes lo[2][2], hi[2][2];
    for (int t = 0; t < 2; ++t)
        for (int j = 0; j < 2; ++j) {
            fill_lanes(INFINITY, lo[t][j]);
            fill_lanes(-INFINITY, hi[t][j]);
        }
    for (size_t v = 0; v < n; v += lane_count) {
        Lanes px, py;
        load_lanes(x + v, px);
        load_lanes(y + v, py);
        const Lanes cx = c * px, sy = s * py, cy = c * py, sx = s * px;
        const Lanes turned[2][2] = {{cx + sy, cy - sx}, {cx - sy, cy + sx}};
        for (int t = 0; t < 2; ++t)
            for (int j = 0; j < 2; ++j) {
                lo[t][j] = turned[t][j] < lo[t][j] ? turned[t][j] : lo[t][j];
                hi[t][j] = turned[t][j] > hi[t][j] ? turned[t][j] : hi[t][j];
            }
    }
    for (int t = 0; t < 2; ++t)
        area[t] = (highest(hi[t][0]) - lowest(lo[t][0]) + pad) * (highest(hi[t][1]) - lowest(lo[t][1]) + pad);
}

// Turns the points (x, y) in their plane as turned_areas's first turn turns them (the angle of cosine c and
// sine s, either sign), in place, and gives the turned extents along both axes.
CB_VECTOR_CLONES void turn_points(double* x, double* y, size_t n, double c, double s, double extent[2]) {
    Lanes lo[2], hi[2];
    for (int j = 0; j < 2; ++j) {
        fill_lanes(INFINITY, lo[j]);
        fill_lanes(-INFINITY, hi[j]);
    }
    for (size_t v = 0; v < n; v += lane_count) {
        Lanes px, py;
        load_lanes(x + v, px);
        load_lanes(y + v, py);
        const Lanes turned[2] = {c * px + s * py, c * py - s * px};
        std::memcpy(x + v, &turned[0], sizeof(Lanes));
        std::memcpy(y + v, &turned[1], sizeof(Lanes));
        for (int j = 0; j < 2; ++j) {
            lo[j] = turned[j] < lo[j] ? turned[j] : lo[j];
            hi[j] = turned[j] > hi[j] ? turned[j] : hi[j];
        }
    }
    for (int j = 0; j < 2; ++j) extent[j] = highest(hi[j]) - lowest(lo[j]);
}

// min_area_rect_frame's rectangle for a fine cluster, sampled: the best of 32 turns of the other two axes,
// evenly spaced over the quarter turn after which a rectangle repeats, all measured in one pass over the
// points (the turns in lanes, in float: the areas only choose where the descent starts). Samples 2.8
// degrees apart, the descent then closing in; no sort or hull, whose branches follow the data: the
// refined box in 0.79 to 0.85 of the time on 12 of the 13 scanned meshes' fine clusters, mean volume within
// 0.001 of the exact rectangle's (docs/PERFORMANCE.md).
typedef float FloatLanes __attribute__((vector_size(32)));
constexpr int sampled_turns = 32, float_lanes = 8;
CB_VECTOR_CLONES Frame sampled_rect_frame(const double* pts, size_t n, const Frame& f, int fixed, double pad) {
    constexpr int groups = sampled_turns / float_lanes;
    struct Turns {
        FloatLanes c[groups], s[groups];
        double cos[sampled_turns], sin[sampled_turns];  // the chosen turn, in double
    };
    static const Turns turns = [] {
        Turns t;
        for (int i = 0; i < sampled_turns; ++i) {
            const double a = i * (M_PI / 2) / sampled_turns;
            t.cos[i] = std::cos(a);
            t.sin[i] = std::sin(a);
            t.c[i / float_lanes][i % float_lanes] = float(t.cos[i]);
            t.s[i / float_lanes][i % float_lanes] = float(t.sin[i]);
        }
        return t;
    }();
    const int u = (fixed + 1) % 3, w = (fixed + 2) % 3;
    FloatLanes lo[2][groups], hi[2][groups];
    for (int j = 0; j < 2; ++j)
        for (int g = 0; g < groups; ++g) {
            lo[j][g] = FloatLanes{} + INFINITY;
            hi[j][g] = FloatLanes{} - INFINITY;
        }
    for (size_t v = 0; v < n; ++v) {
        const FloatLanes x = FloatLanes{} + float(dot3(pts + v * 3, f.axis[u])),
                         y = FloatLanes{} + float(dot3(pts + v * 3, f.axis[w]));
        for (int g = 0; g < groups; ++g) {
            const FloatLanes along = turns.c[g] * x + turns.s[g] * y, across = turns.c[g] * y - turns.s[g] * x;
            lo[0][g] = along < lo[0][g] ? along : lo[0][g];
            hi[0][g] = along > hi[0][g] ? along : hi[0][g];
            lo[1][g] = across < lo[1][g] ? across : lo[1][g];
            hi[1][g] = across > hi[1][g] ? across : hi[1][g];
        }
    }
    float best = INFINITY;
    int pick = 0;
    for (int g = 0; g < groups; ++g) {
        const FloatLanes area = (hi[0][g] - lo[0][g] + float(pad)) * (hi[1][g] - lo[1][g] + float(pad));
        for (int l = 0; l < float_lanes; ++l)
            if (area[l] < best) {
                best = area[l];
                pick = g * float_lanes + l;
            }
    }
    return rotated(f, fixed, turns.cos[pick], turns.sin[pick]);
}

// Axes spread evenly over a half sphere (a golden-angle spiral), for extreme_points: one array per
// coordinate, so that the lanes run across axes. 32 rather than 64: coarse boxes at most 0.8% larger in volume
// on the scanned meshes, no more work at run time, the fitting 4% fewer instructions (docs/PERFORMANCE.md).
constexpr int spread_axes = 32;
struct SpreadAxes {
    alignas(64) double x[spread_axes], y[spread_axes], z[spread_axes];
};
const SpreadAxes& spread_directions() {
    static const SpreadAxes axes = [] {
        SpreadAxes out;
        for (int i = 0; i < spread_axes; ++i) {
            double z = (i + 0.5) / spread_axes, r = std::sqrt(1 - z * z), a = i * 2.399963229728653;
            out.x[i] = r * std::cos(a);
            out.y[i] = r * std::sin(a);
            out.z[i] = z;
        }
        return out;
    }();
    return axes;
}

// The points that are lowest or highest along one of the spread axes (at most two per axis, in input order).
// They stand in for the hull's vertices when the frame search would otherwise sweep hundreds of points: a
// box around them is nearly the box around all, and the stored extents are measured on all points anyway.
// Each point is projected on every axis at once, in lanes (vector_clones.h); an axis keeps the first point
// of its lowest and of its highest projection, replacing only on a strictly lower or higher one, as a scan
// along the axis finds them.
CB_VECTOR_CLONES void extreme_points(const double* pts, size_t n, std::vector<double>& out) {
    const SpreadAxes& axis = spread_directions();
    alignas(64) double lo[spread_axes], hi[spread_axes];
    alignas(64) uint64_t lo_at[spread_axes], hi_at[spread_axes];
    for (int a = 0; a < spread_axes; ++a) {
        lo[a] = INFINITY;
        hi[a] = -INFINITY;
        lo_at[a] = hi_at[a] = 0;
    }
    for (size_t v = 0; v < n; ++v) {
        const double x = pts[v * 3], y = pts[v * 3 + 1], z = pts[v * 3 + 2];
        for (int a = 0; a < spread_axes; ++a) {
            const double d = axis.x[a] * x + axis.y[a] * y + axis.z[a] * z;
            // Branch-free, so that the compiler keeps the lanes: all-ones masks where lower or higher.
            const uint64_t below = 0 - uint64_t(d < lo[a]), above = 0 - uint64_t(d > hi[a]);
            lo_at[a] = (v & below) | (lo_at[a] & ~below);
            hi_at[a] = (v & above) | (hi_at[a] & ~above);
            lo[a] = d < lo[a] ? d : lo[a];
            hi[a] = d > hi[a] ? d : hi[a];
        }
    }
    thread_local std::vector<uint64_t> keep;
    keep.assign(lo_at, lo_at + spread_axes);
    keep.insert(keep.end(), hi_at, hi_at + spread_axes);
    std::sort(keep.begin(), keep.end());
    keep.erase(std::unique(keep.begin(), keep.end()), keep.end());
    out.resize(keep.size() * 3);
    for (size_t i = 0; i < keep.size(); ++i) std::copy_n(pts + keep[i] * 3, 3, &out[i * 3]);
}

// Clusters of more points than this search their frame over extreme_points, and also across triangle
// normals. On fine clusters the normals moved the mean box volume by under 0.2% (dragon, horse, fandisk,
// 3dfier) for a quarter of the fitting time; on coarse ones they gain 0.5 to 1.5%.
const size_t frame_search_limit = 64;

// The refined search's area-weighted frame only starts it: from about this many of a large cluster's
// triangles, coarse boxes are -0.03% to +0.2% in volume on the scanned meshes, for 4% of the fitting's
// instructions (docs/PERFORMANCE.md).
const size_t area_frame_samples = 512;

// The best box whose one axis is a PCA axis or (in a large cluster, with `positions`) a triangle normal and
// whose other two form the minimum-area rectangle across it; then a descent over small rotations about each
// axis. `fine`: the cluster has at most frame_search_limit points, given in full.
Frame refined_frame(const double* pts, size_t n, const Frame* pca, size_t pca_count, double pad, bool fine,
                    const float* positions, const uint32_t* indices, const uint32_t* tris, size_t count) {
    // The points as three coordinate arrays, padded to whole lanes with copies of the last point.
    const size_t padded = (n + lane_count - 1) / lane_count * lane_count;
    thread_local std::vector<double> soa;
    soa.resize(padded * 3);
    for (size_t v = 0; v < padded; ++v) {
        const double* p = pts + std::min(v, n - 1) * 3;
        soa[v] = p[0];
        soa[padded + v] = p[1];
        soa[2 * padded + v] = p[2];
    }
    auto cost = [&](const Frame& f) {
        return soa_cost(soa.data(), soa.data() + padded, soa.data() + 2 * padded, padded, f, pad);
    };
    Frame best = pca[0];
    double best_cost = cost(best);
    auto consider = [&](const Frame& f) {
        double c = cost(f);
        if (c < best_cost) {
            best_cost = c;
            best = f;
        }
    };
    // A large cluster tries rectangles across every axis of the vertex PCA frame, and across the thinnest (the
    // patch normal) of the area-weighted one, whose other fixings rarely win. A fine cluster tries only the
    // vertex frame's thinnest axis, with the sampled rectangle: the other three rectangles and the
    // area-weighted frame move the mean fine box by at most 0.2% on the 13 scanned meshes, for 40% of the box
    // fitting time (docs/PERFORMANCE.md).
    for (size_t p = 0; p < pca_count; ++p) {
        consider(pca[p]);
        if (fine)
            consider(sampled_rect_frame(pts, n, pca[p], 2, pad));
        else
            for (int fixed = p == 0 ? 0 : 2; fixed < 3; ++fixed) consider(min_area_rect_frame(pts, n, pca[p], fixed));
    }
    // Up to 4 triangle normals of a large cluster, evenly spaced through it: bounded work, and 8 gave no tighter
    // boxes on the dragon. A fine cluster's largest triangle makes boxes no tighter on the scanned meshes and
    // looser on fandisk (the descent ends in another local optimum), for a tenth of the fitting time.
    const size_t stride = std::max<size_t>(1, count / 4);
    for (size_t i = 0; !fine && positions && i < count; i += stride) {
        double p[3][3];
        for (int k = 0; k < 3; ++k)
            for (int j = 0; j < 3; ++j) p[k][j] = positions[size_t(indices[size_t(tris[i]) * 3 + k]) * 3 + j];
        Vec nrm = cross(sub(p[1], p[0]), sub(p[2], p[0]));
        double len = norm(nrm);
        if (!(len > 0)) continue;
        consider(min_area_rect_frame(pts, n, frame_around({nrm[0] / len, nrm[1] / len, nrm[2] / len}), 0));
    }
    // The descent turns the best frame about one of its axes at a time: the extent along that axis stays,
    // and the other two come from the points' projections on the frame, turned in the plane, so a try costs
    // four products per point instead of nine; a winning try's turned projections are kept.
    thread_local std::vector<double> proj;
    proj.resize(padded * 3);
    double extent[3];
    for (int i = 0; i < 3; ++i) {
        double* p = proj.data() + size_t(i) * padded;
        double lo = INFINITY, hi = -INFINITY;
        for (size_t v = 0; v < padded; ++v) {
            p[v] = best.axis[i][0] * soa[v] + best.axis[i][1] * soa[padded + v] + best.axis[i][2] * soa[2 * padded + v];
            lo = std::min(lo, p[v]);
            hi = std::max(hi, p[v]);
        }
        extent[i] = hi - lo;
    }
    // Steps from 0.16 down to 6.25e-4 radians, each a quarter of the one before. The last step sets the
    // tightness: the dragon's fine boxes come to 1.014 times CGAL's optimal volume on the mean (1.020 stopping
    // at 2.5e-3), and halving steps down to 3.1e-4 reached 1.013 for a fifth more fitting time.
    constexpr int levels = 5;
    static const std::array<std::array<double, 2>, levels> turns = [] {
        std::array<std::array<double, 2>, levels> t;
        for (int l = 0; l < levels; ++l) {
            const double step = 0.16 / double(1 << (2 * l));
            t[size_t(l)] = {std::cos(step), std::sin(step)};
        }
        return t;
    }();
    // A try on the same projections with the same step gives the same areas: each axis keeps its last areas
    // and the number of wins they were measured after, and takes them again while no try has won since (the
    // round that ends a step size then costs nothing, and the try after a win has its areas already).
    size_t wins = 0;
    for (const auto& [c, s] : turns) {
        double known[3][2];
        size_t known_after[3] = {SIZE_MAX, SIZE_MAX, SIZE_MAX};
        for (bool improved = true; improved;) {
            improved = false;
            for (int k = 0; k < 3; ++k) {
                const int u = (k + 1) % 3, w = (k + 2) % 3;
                double* x = proj.data() + size_t(u) * padded;
                double* y = proj.data() + size_t(w) * padded;
                double area[2];
                if (known_after[k] == wins)
                    std::copy_n(known[k], 2, area);
                else
                    turned_areas(x, y, padded, c, s, pad, area);
                bool current = true;  // `area` measured on the projections as they are
                for (int t = 0; t < 2; ++t) {
                    const double sign = t == 0 ? 1.0 : -1.0;
                    const double turned = (extent[k] + pad) * area[t];
                    if (!(turned < best_cost)) continue;
                    best_cost = turned;
                    best = rotated(best, k, c, sign * s);
                    improved = true;
                    ++wins;
                    current = false;
                    // The winning try's projections, turned as turned_areas turned them (the copies as their
                    // point), become the current ones: -s times y is minus s times y, so the same doubles.
                    double turned_extent[2];
                    turn_points(x, y, padded, c, sign * s, turned_extent);
                    extent[u] = turned_extent[0];
                    extent[w] = turned_extent[1];
                    // The turn back is then a try of its own, on the turned projections.
                    if (t == 0) {
                        turned_areas(x, y, padded, c, s, pad, area);
                        current = true;
                    }
                }
                if (current) {
                    std::copy_n(area, 2, known[k]);
                    known_after[k] = wins;
                }
            }
        }
    }
    make_right_handed(best);
    return best;
}

// The frame's rotation (rows are the axes, right-handed) as a packed unit quaternion.
void pack_rotation(const Frame& f, PackedObb& out) {
    // m(r, c): column c is axis c.
    auto m = [&](int r, int c) { return f.axis[c][r]; };
    double q[4], t = m(0, 0) + m(1, 1) + m(2, 2);  // x, y, z, w
    if (t > 0) {
        double s = 2 * std::sqrt(t + 1);
        q[3] = s / 4;
        q[0] = (m(2, 1) - m(1, 2)) / s;
        q[1] = (m(0, 2) - m(2, 0)) / s;
        q[2] = (m(1, 0) - m(0, 1)) / s;
    } else if (m(0, 0) >= m(1, 1) && m(0, 0) >= m(2, 2)) {
        double s = 2 * std::sqrt(std::max(0.0, 1 + m(0, 0) - m(1, 1) - m(2, 2)));
        q[3] = (m(2, 1) - m(1, 2)) / s;
        q[0] = s / 4;
        q[1] = (m(0, 1) + m(1, 0)) / s;
        q[2] = (m(0, 2) + m(2, 0)) / s;
    } else if (m(1, 1) >= m(2, 2)) {
        double s = 2 * std::sqrt(std::max(0.0, 1 + m(1, 1) - m(0, 0) - m(2, 2)));
        q[3] = (m(0, 2) - m(2, 0)) / s;
        q[0] = (m(0, 1) + m(1, 0)) / s;
        q[1] = s / 4;
        q[2] = (m(1, 2) + m(2, 1)) / s;
    } else {
        double s = 2 * std::sqrt(std::max(0.0, 1 + m(2, 2) - m(0, 0) - m(1, 1)));
        q[3] = (m(1, 0) - m(0, 1)) / s;
        q[0] = (m(0, 2) + m(2, 0)) / s;
        q[1] = (m(1, 2) + m(2, 1)) / s;
        q[2] = s / 4;
    }
    int largest = 0;
    for (int i = 1; i < 4; ++i)
        if (std::fabs(q[i]) > std::fabs(q[largest])) largest = i;
    double sign = q[largest] < 0 ? -1 : 1;
    out.largest = uint16_t(largest);
    for (int i = 0, k = 0; i < 4; ++i) {
        if (i == largest) continue;
        double v = std::round(sign * q[i] * (32767.0 * 1.4142135623730951));
        out.rotation[k++] = int16_t(std::clamp(v, -32767.0, 32767.0));
    }
}

// The same box under the rotation of its 24 that is nearest the identity: each world axis in turn takes the
// remaining axis most along it, pointing its way. Rotations near the identity pack with the least rounding,
// and a box along the world axes (a building, a CAD face) packs exactly, however its axes were found.
Frame nearest_identity(const Frame& f) {
    Frame out = f;
    bool used[3] = {false, false, false};
    for (int slot = 0; slot < 2; ++slot) {
        int pick = -1;
        for (int i = 0; i < 3; ++i)
            if (!used[i] && (pick < 0 || std::fabs(f.axis[i][slot]) > std::fabs(f.axis[pick][slot]))) pick = i;
        used[pick] = true;
        const double sign = f.axis[pick][slot] < 0 ? -1 : 1;
        for (int k = 0; k < 3; ++k) out.axis[slot][k] = sign * f.axis[pick][k];
    }
    make_right_handed(out);
    return out;
}

Frame search_frame(const double* pts, size_t n, ObbMethod method, const float* positions, const uint32_t* indices,
                   const uint32_t* tris, size_t count, const double* origin) {
    double lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < n * 3; ++i) {
        lo = std::min(lo, pts[i]);
        hi = std::max(hi, pts[i]);
    }
    double pad = std::max(hi - lo, 1e-300) * 1e-9;

    if (method == ObbMethod::cgal_optimal) {
        Frame f;
        if (n >= 4 && cgal_optimal_frame(pts, n, f.axis)) {
            make_right_handed(f);
            return f;
        }
        method = ObbMethod::refined;  // CGAL needs 4 points or more, not all in a plane
    }
    const bool fine = n <= frame_search_limit;
    Frame pca[2];
    size_t pca_count = 0;
    if (method == ObbMethod::pca || method == ObbMethod::refined) pca[pca_count++] = pca_frame(pts, n);
    if (method == ObbMethod::pca_area || (method == ObbMethod::refined && !fine)) {
        Frame f;
        const size_t stride = method == ObbMethod::refined ? std::max<size_t>(1, count / area_frame_samples) : 1;
        if (positions && area_frame(positions, indices, tris, count, origin, f, stride))
            pca[pca_count++] = f;
        else if (method == ObbMethod::pca_area)
            pca[pca_count++] = pca_frame(pts, n);
    }
    if (method != ObbMethod::refined) return pca[0];
    if (fine) return refined_frame(pts, n, pca, pca_count, pad, true, positions, indices, tris, count);
    thread_local std::vector<double> few;
    extreme_points(pts, n, few);
    return refined_frame(few.data(), few.size() / 3, pca, pca_count, pad, false, positions, indices, tris, count);
}

}  // namespace

Frame best_frame(const double* pts, size_t n, ObbMethod method, const float* positions, const uint32_t* indices,
                 const uint32_t* tris, size_t count, const double* origin) {
    return nearest_identity(search_frame(pts, n, method, positions, indices, tris, count, origin));
}

PackedObb store_obb(const Frame& f, const double* local, size_t n, const double* origin, const double* world) {
    double lo[3], hi[3];
    extents(local, n, f, lo, hi);
    double centre[3];
    for (int k = 0; k < 3; ++k) {
        centre[k] = origin[k];
        for (int i = 0; i < 3; ++i) centre[k] += 0.5 * (lo[i] + hi[i]) * f.axis[i][k];
    }
    PackedObb p{};
    pack_rotation(f, p);
    for (int k = 0; k < 3; ++k) p.center[k] = float(centre[k]);
    Obb b = unpack_obb(p);
    const double c[3] = {b.center[0], b.center[1], b.center[2]};
    double a[3][3], h[3] = {0, 0, 0}, scale[3] = {0, 0, 0};
    for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k) a[i][k] = b.axis[i][k];
    for (size_t v = 0; v < n; ++v) {  // a vertex's offset and its norm once, for the three axes
        const Vec d = sub(world + v * 3, c);
        const double l1 = std::fabs(d[0]) + std::fabs(d[1]) + std::fabs(d[2]);
        for (int i = 0; i < 3; ++i) {
            h[i] = std::max(h[i], std::fabs(dot3(d.data(), a[i])) + axis_step * l1);
            scale[i] =
                std::max(scale[i], std::fabs(d[0] * a[i][0]) + std::fabs(d[1] * a[i][1]) + std::fabs(d[2] * a[i][2]));
        }
    }
    for (int i = 0; i < 3; ++i) p.half[i] = round_up(h[i] + measure_margin * scale[i]);
    return p;
}

}  // namespace fitting

using namespace fitting;

double obb_volume(const Obb& b) { return 8.0 * double(b.half[0]) * b.half[1] * b.half[2]; }

const char* obb_method_name(ObbMethod m) {
    switch (m) {
        case ObbMethod::pca: return "pca";
        case ObbMethod::pca_area: return "pca-area";
        case ObbMethod::refined: return "refined";
        case ObbMethod::cgal_optimal: return "cgal";
    }
    return "?";
}

bool parse_obb_method(const std::string& name, ObbMethod& out) {
    for (ObbMethod m : {ObbMethod::refined, ObbMethod::pca, ObbMethod::pca_area, ObbMethod::cgal_optimal})
        if (name == obb_method_name(m)) {
            out = m;
            return true;
        }
    return false;
}

Obb fit_obb(const double* local, size_t n, const double* origin, ObbMethod method, const float* positions,
            const uint32_t* indices, const uint32_t* triangle_ids, size_t triangle_count) {
    std::vector<double> world(n * 3);
    for (size_t i = 0; i < n * 3; ++i) world[i] = local[i] + origin[i % 3];
    Frame f = best_frame(local, n, method, positions, indices, triangle_ids, triangle_count, origin);
    return unpack_obb(store_obb(f, local, n, origin, world.data()));
}

}  // namespace cb
