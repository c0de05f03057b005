// Polygon triangulation (io/polygon_triangulate.h) against an exact oracle: in the projection the
// triangulator uses, the triangles must have the polygon's winding and non-zero area, their areas must sum
// to the polygon's exactly, and every sample point must lie in exactly one triangle when inside the polygon
// and in none when outside. Then the OBJ, OFF and PLY readers, and the shared scenes that hold polygons.
#include <gtest/gtest.h>

#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Polygon_2_algorithms.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "load.h"
#include "polygon_triangulate.h"
#include "scene_info.h"
#include "text_scan.h"

namespace fs = std::filesystem;

namespace {

using E = CGAL::Exact_predicates_exact_constructions_kernel;
using P2 = E::Point_2;

struct Polygon {
    std::vector<float> xyz;      // 3 per vertex
    std::vector<uint32_t> poly;  // the face, into xyz
};

// A polygon in a plane: 2-D points (a, b) placed at origin + a * u + b * v, rounded to float.
Polygon place(const std::vector<std::array<double, 2>>& pts, std::array<double, 3> u = {1, 0, 0},
              std::array<double, 3> v = {0, 1, 0}, std::array<double, 3> origin = {0, 0, 0}) {
    Polygon p;
    for (const auto& q : pts) {
        for (int k = 0; k < 3; ++k) p.xyz.push_back(float(origin[k] + q[0] * u[k] + q[1] * v[k]));
        p.poly.push_back(uint32_t(p.poly.size()));
    }
    return p;
}

std::vector<uint32_t> fan_of(const std::vector<uint32_t>& poly) {
    std::vector<uint32_t> out;
    for (size_t i = 1; i + 1 < poly.size(); ++i) out.insert(out.end(), {poly[0], poly[i], poly[i + 1]});
    return out;
}

std::vector<uint32_t> triangulate(const Polygon& p, cb::PolygonShape* shape = nullptr) {
    std::vector<uint32_t> out;
    cb::PolygonShape s = cb::triangulate_polygon(p.xyz.data(), p.poly.data(), p.poly.size(), out);
    if (shape) *shape = s;
    return out;
}

// The point dropping coordinate `axis`, the other two in cyclic order (the triangulator's projection).
P2 projected(const std::vector<float>& xyz, uint32_t i, int axis) {
    return P2(double(xyz[size_t(i) * 3 + (axis + 1) % 3]), double(xyz[size_t(i) * 3 + (axis + 2) % 3]));
}

// Whether `tris` tile the polygon seen along `axis` (see the file comment), with `samples` x `samples`
// points over its bounding box.
::testing::AssertionResult tiles(const Polygon& p, const std::vector<uint32_t>& tris, int axis = 2, int samples = 23) {
    std::vector<P2> outline;
    for (uint32_t i : p.poly) {
        P2 q = projected(p.xyz, i, axis);
        if (outline.empty() || outline.back() != q) outline.push_back(q);
    }
    while (outline.size() > 1 && outline.back() == outline.front()) outline.pop_back();
    E::FT area = CGAL::polygon_area_2(outline.begin(), outline.end(), E());
    if (CGAL::is_zero(area)) return ::testing::AssertionFailure() << "the polygon has no area";
    if (tris.size() % 3) return ::testing::AssertionFailure() << "not whole triangles";
    std::vector<E::Triangle_2> ts;
    E::FT sum = 0;
    for (size_t t = 0; t < tris.size(); t += 3) {
        E::Triangle_2 tri(projected(p.xyz, tris[t], axis), projected(p.xyz, tris[t + 1], axis),
                          projected(p.xyz, tris[t + 2], axis));
        if (CGAL::sign(tri.area()) != CGAL::sign(area))
            return ::testing::AssertionFailure() << "triangle " << t / 3 << " has zero area or the wrong winding";
        if (CGAL::bounded_side_2(outline.begin(), outline.end(), CGAL::centroid(tri), E()) != CGAL::ON_BOUNDED_SIDE)
            return ::testing::AssertionFailure() << "triangle " << t / 3 << " has its centroid outside the polygon";
        sum += tri.area();
        ts.push_back(tri);
    }
    if (sum != area)
        return ::testing::AssertionFailure()
            << "triangle areas sum to " << CGAL::to_double(sum) << ", the polygon has " << CGAL::to_double(area);
    CGAL::Bbox_2 box = CGAL::bbox_2(outline.begin(), outline.end());
    for (int i = 0; i < samples; ++i)
        for (int j = 0; j < samples; ++j) {
            // Irregular offsets keep most samples off the edges of axis-aligned test shapes.
            double s = (i + 0.5 + 0.31 * std::sin(7.0 * i + j)) / samples;
            double t = (j + 0.5 + 0.27 * std::cos(3.0 * j + i)) / samples;
            P2 x(box.xmin() + s * (box.xmax() - box.xmin()), box.ymin() + t * (box.ymax() - box.ymin()));
            CGAL::Bounded_side side = CGAL::bounded_side_2(outline.begin(), outline.end(), x, E());
            if (side == CGAL::ON_BOUNDARY) continue;
            int covered = 0;
            bool on_edge = false;
            for (const E::Triangle_2& tri : ts) {
                CGAL::Bounded_side in = tri.bounded_side(x);
                covered += in == CGAL::ON_BOUNDED_SIDE;
                on_edge = on_edge || in == CGAL::ON_BOUNDARY;
            }
            if (on_edge) continue;
            int want = side == CGAL::ON_BOUNDED_SIDE ? 1 : 0;
            if (covered != want)
                return ::testing::AssertionFailure()
                    << "point (" << CGAL::to_double(x.x()) << ", " << CGAL::to_double(x.y()) << ") is in " << covered
                    << " triangles, expected " << want;
        }
    return ::testing::AssertionSuccess();
}

// L, U and comb outlines, each starting at a vertex that does not see every other one, so the fan from
// the first vertex leaves the polygon.
const std::vector<std::array<double, 2>> l_shape = {{2, 0}, {2, 1}, {1, 1}, {1, 2}, {0, 2}, {0, 0}};
const std::vector<std::array<double, 2>> u_shape = {{0, 0}, {3, 0}, {3, 2}, {2, 2}, {2, 1}, {1, 1}, {1, 2}, {0, 2}};

std::vector<std::array<double, 2>> comb(int teeth) {
    double w = 2 * teeth - 1;
    std::vector<std::array<double, 2>> pts = {{0, 0}, {w, 0}};
    for (int k = teeth - 1; k >= 0; --k) {
        pts.push_back({2.0 * k + 1, 3});
        pts.push_back({2.0 * k, 3});
        if (k > 0) {
            pts.push_back({2.0 * k, 1});
            pts.push_back({2.0 * k - 1, 1});
        }
    }
    return pts;
}

std::vector<std::array<double, 2>> reversed(std::vector<std::array<double, 2>> pts) {
    std::reverse(pts.begin(), pts.end());
    return pts;
}

std::vector<std::array<double, 2>> rotated(std::vector<std::array<double, 2>> pts, size_t by) {
    std::rotate(pts.begin(), pts.begin() + std::ptrdiff_t(by % pts.size()), pts.end());
    return pts;
}

// Planes for placing test polygons: (u, v, the axis the triangulator projects along).
struct Plane {
    std::array<double, 3> u, v, origin;
    int axis;
};
const Plane planes[] = {
    {{1, 0, 0}, {0, 1, 0}, {0, 0, 0}, 2},
    {{0, 1, 0}, {1, 0, 0}, {0, 0, 5}, 2},                   // seen from -z
    {{0, 1, 0}, {0, 0, 1}, {3, 0, 0}, 0},                   // the x = 3 plane
    {{0, 0, 1}, {1, 0, 0}, {0, -2, 0}, 1},                  // the y = -2 plane
    {{1, 0, 0.25}, {0, 1, -0.125}, {85012, 447455, 1}, 2},  // tilted, far from the origin
};

}  // namespace

TEST(Polygons, OracleRejectsTheFanOnConcaveShapes) {
    // The oracle can fail: the fan from the first vertex covers area outside each of these.
    EXPECT_FALSE(tiles(place(l_shape), fan_of(place(l_shape).poly)));
    EXPECT_FALSE(tiles(place(u_shape), fan_of(place(u_shape).poly)));
    EXPECT_FALSE(tiles(place(comb(5)), fan_of(place(comb(5)).poly)));
}

TEST(Polygons, ConcaveShapesAreTiledExactly) {
    for (const auto& shape : {l_shape, u_shape, comb(2), comb(7), comb(60)})
        for (const Plane& plane : planes)
            for (bool reverse : {false, true})
                for (size_t start : {size_t(0), size_t(3)}) {
                    SCOPED_TRACE(std::to_string(shape.size()) + " vertices, axis " + std::to_string(plane.axis) +
                                 (reverse ? ", reversed" : "") + ", starting at " + std::to_string(start));
                    Polygon p =
                        place(rotated(reverse ? reversed(shape) : shape, start), plane.u, plane.v, plane.origin);
                    cb::PolygonShape kind;
                    std::vector<uint32_t> tris = triangulate(p, &kind);
                    EXPECT_EQ(kind, cb::PolygonShape::concave);
                    EXPECT_EQ(tris.size(), 3 * (shape.size() - 2));
                    EXPECT_TRUE(tiles(p, tris, plane.axis, shape.size() > 100 ? 61 : 23));
                }
}

TEST(Polygons, ConvexPolygonsGiveExactlyTheFan) {
    for (int n = 4; n <= 12; ++n)
        for (const Plane& plane : planes) {
            SCOPED_TRACE(std::to_string(n) + " vertices, axis " + std::to_string(plane.axis));
            std::vector<std::array<double, 2>> pts;
            for (int i = 0; i < n; ++i) pts.push_back({2 * std::cos(2 * M_PI * i / n), 2 * std::sin(2 * M_PI * i / n)});
            for (bool reverse : {false, true}) {
                Polygon p = place(reverse ? reversed(pts) : pts, plane.u, plane.v, plane.origin);
                cb::PolygonShape kind;
                EXPECT_EQ(triangulate(p, &kind), fan_of(p.poly));
                EXPECT_EQ(kind, cb::PolygonShape::convex);
            }
        }
    // A rectangle with a vertex on one side, whose fan has no zero-area triangle, stays the fan too.
    Polygon p = place({{2, 2}, {0, 2}, {0, 0}, {1, 0}, {2, 0}});
    cb::PolygonShape kind;
    EXPECT_EQ(triangulate(p, &kind), fan_of(p.poly));
    EXPECT_EQ(kind, cb::PolygonShape::convex);
    // Triangles are passed through whatever they hold.
    Polygon t = place({{0, 0}, {1, 0}, {2, 0}});
    EXPECT_EQ(triangulate(t, &kind), t.poly);
    EXPECT_EQ(kind, cb::PolygonShape::triangle);
}

TEST(Polygons, CollinearVerticesGiveNoZeroAreaTriangle) {
    // The fan from the first vertex would hold (0,0) (1,0) (2,0).
    std::vector<std::vector<std::array<double, 2>>> shapes = {
        {{0, 0}, {1, 0}, {2, 0}, {2, 2}, {0, 2}},
        {{0, 0}, {1, 0}, {2, 0}, {3, 0}, {3, 1}, {3, 2}, {2, 2}, {2, 1}, {1, 1}, {1, 2}, {0, 2}, {0, 1}},
        {{0, 0}, {0.5, 0}, {1, 0}, {1, 1}},  // a triangle with a vertex on one side
    };
    // A triangle with ten vertices on each side.
    std::vector<std::array<double, 2>> many;
    for (int i = 0; i < 10; ++i) many.push_back({i * 0.5, 0});
    for (int i = 0; i < 10; ++i) many.push_back({5 - i * 0.25, i * 0.5});
    for (int i = 0; i < 10; ++i) many.push_back({2.5 - i * 0.25, 5 - i * 0.5});
    shapes.push_back(many);
    for (const auto& shape : shapes)
        for (const Plane& plane : planes)
            for (size_t start = 0; start < shape.size(); start += 3) {
                SCOPED_TRACE(std::to_string(shape.size()) + " vertices, axis " + std::to_string(plane.axis) +
                             ", starting at " + std::to_string(start));
                Polygon p = place(rotated(shape, start), plane.u, plane.v, plane.origin);
                std::vector<uint32_t> tris = triangulate(p);
                EXPECT_EQ(tris.size(), 3 * (shape.size() - 2));
                EXPECT_TRUE(tiles(p, tris, plane.axis));
            }
}

TEST(Polygons, RepeatedVerticesAreDropped) {
    // By index (1 1), by position (vertex 6 is vertex 3 again), and the first vertex closing the polygon.
    Polygon p = place(l_shape);
    p.xyz.insert(p.xyz.end(), {p.xyz[3 * 3], p.xyz[3 * 3 + 1], p.xyz[3 * 3 + 2]});
    p.poly = {0, 1, 1, 2, 3, 6, 4, 5, 0};
    cb::PolygonShape kind;
    std::vector<uint32_t> tris = triangulate(p, &kind);
    EXPECT_EQ(kind, cb::PolygonShape::concave);
    EXPECT_EQ(tris.size(), 3u * 4);
    EXPECT_TRUE(tiles(p, tris));
    // A square with a repeated corner is not convex as written, but is tiled.
    Polygon q = place({{0, 0}, {1, 0}, {1, 1}, {0, 1}});
    q.poly = {0, 1, 2, 2, 3};
    tris = triangulate(q, &kind);
    EXPECT_EQ(kind, cb::PolygonShape::concave);
    EXPECT_EQ(tris.size(), 3u * 2);
    EXPECT_TRUE(tiles(q, tris));
}

TEST(Polygons, NonPlanarPolygonsUseTheirBestFitPlane) {
    // A slightly warped convex quad is still the fan.
    Polygon quad = place({{0, 0}, {1, 0}, {1, 1}, {0, 1}});
    quad.xyz[2 * 3 + 2] = 0.01f;
    cb::PolygonShape kind;
    EXPECT_EQ(triangulate(quad, &kind), fan_of(quad.poly));
    EXPECT_EQ(kind, cb::PolygonShape::convex);
    // A warped comb and L, in two planes: tiled in the projection.
    for (const auto& shape : {l_shape, u_shape, comb(6)})
        for (int plane : {0, 2}) {
            Polygon p = place(shape, planes[plane].u, planes[plane].v, planes[plane].origin);
            int axis = planes[plane].axis;
            for (size_t i = 0; i < p.poly.size(); ++i) {
                float a = p.xyz[i * 3 + (axis + 1) % 3], b = p.xyz[i * 3 + (axis + 2) % 3];
                p.xyz[i * 3 + axis] += 0.05f * a * b - 0.03f * a;
            }
            std::vector<uint32_t> tris = triangulate(p, &kind);
            EXPECT_EQ(kind, cb::PolygonShape::concave);
            EXPECT_TRUE(tiles(p, tris, axis));
        }
}

TEST(Polygons, RingCutOpenAlongABridgeIsTiled) {
    // A square with a square hole, the two outlines joined by an edge walked there and back: the polygon
    // touches itself at (0,0) and (1,1) only.
    std::vector<std::array<double, 2>> ring = {{0, 0}, {4, 0}, {4, 4}, {0, 4}, {0, 0},
                                               {1, 1}, {1, 3}, {3, 3}, {3, 1}, {1, 1}};
    for (const Plane& plane : planes)
        for (size_t start : {size_t(0), size_t(2), size_t(5), size_t(7)}) {
            SCOPED_TRACE("axis " + std::to_string(plane.axis) + ", starting at " + std::to_string(start));
            Polygon p = place(rotated(ring, start), plane.u, plane.v, plane.origin);
            cb::PolygonShape kind;
            std::vector<uint32_t> tris = triangulate(p, &kind);
            EXPECT_EQ(kind, cb::PolygonShape::concave);
            EXPECT_EQ(tris.size(), 3u * 8);
            EXPECT_TRUE(tiles(p, tris, plane.axis, 31));
        }
}

TEST(Polygons, SelfIntersectingPolygonsAreCountedAndKeepTheFan) {
    std::vector<std::vector<std::array<double, 2>>> shapes = {
        {{0, 0}, {1, 1}, {1, 0}, {0, 1}},                          // bow-tie
        {{0, 0}, {4, 0}, {4, 4}, {2, 0}, {0, 4}},                  // a vertex on another edge
        {{2, 0}, {4, 2}, {2, 4}, {0, 2}, {2, 0}, {3, 2}, {2, 3}},  // a loop inside, winding twice
        {{0, 0}, {2, 0}, {1, 0}, {1, 1}},                          // a spike
    };
    // A pentagram turns the same way at every vertex but goes round twice.
    std::vector<std::array<double, 2>> star;
    for (int i = 0; i < 5; ++i) star.push_back({std::cos(4 * M_PI * i / 5), std::sin(4 * M_PI * i / 5)});
    shapes.push_back(star);
    cb::PolygonTriangulator triangulator;
    for (const auto& shape : shapes) {
        SCOPED_TRACE(std::to_string(shape.size()) + " vertices");
        Polygon p = place(shape);
        std::vector<uint32_t> tris;
        EXPECT_EQ(triangulator.add(p.xyz.data(), p.poly.data(), p.poly.size(), tris), cb::PolygonShape::not_simple);
        EXPECT_EQ(tris, fan_of(p.poly));
    }
    EXPECT_EQ(triangulator.counts().total, shapes.size());
    EXPECT_EQ(triangulator.counts().not_simple, shapes.size());
    EXPECT_EQ(triangulator.counts().concave, 0u);
}

TEST(Polygons, DegeneratePolygonsKeepTheFan) {
    cb::PolygonShape kind;
    Polygon line = place({{0, 0}, {1, 1}, {3, 3}, {2, 2}});
    EXPECT_EQ(triangulate(line, &kind), fan_of(line.poly));
    EXPECT_EQ(kind, cb::PolygonShape::degenerate);
    Polygon point = place({{1, 1}, {1, 1}, {1, 1}, {1, 1}});
    EXPECT_EQ(triangulate(point, &kind), fan_of(point.poly));
    EXPECT_EQ(kind, cb::PolygonShape::degenerate);
}

TEST(Polygons, RandomStarShapedPolygonsOnAGrid) {
    // Integer vertices sorted by angle about the origin: simple, often concave, full of collinear runs.
    std::mt19937 rng(7);
    int checked = 0;
    for (int round = 0; round < 300; ++round) {
        int range = 2 + int(rng() % 12);
        std::uniform_int_distribution<int> coord(-range, range);
        size_t want = 4 + rng() % 40;
        std::vector<std::array<long long, 2>> pts;
        for (size_t tries = 0; pts.size() < want && tries < 400; ++tries) {
            std::array<long long, 2> p = {coord(rng), coord(rng)};
            if (p[0] == 0 && p[1] == 0) continue;
            bool same_angle = false;
            for (const auto& q : pts)
                same_angle = same_angle || (p[0] * q[1] == p[1] * q[0] && p[0] * q[0] + p[1] * q[1] > 0);
            if (!same_angle) pts.push_back(p);
        }
        std::sort(pts.begin(), pts.end(), [](const auto& a, const auto& b) {
            return std::atan2(double(a[1]), double(a[0])) < std::atan2(double(b[1]), double(b[0]));
        });
        // The origin must be strictly inside: every angular gap below a half turn.
        bool ok = pts.size() >= 4;
        for (size_t i = 0; i < pts.size() && ok; ++i) {
            const auto &a = pts[i], &b = pts[(i + 1) % pts.size()];
            ok = a[0] * b[1] - a[1] * b[0] > 0;
        }
        if (!ok) continue;
        std::vector<std::array<double, 2>> shape;
        for (const auto& p : pts) shape.push_back({double(p[0]), double(p[1])});
        const Plane& plane = planes[round % 5];
        SCOPED_TRACE("round " + std::to_string(round));
        Polygon p = place(rotated(shape, size_t(round)), plane.u, plane.v, plane.origin);
        std::vector<uint32_t> tris = triangulate(p);
        EXPECT_EQ(tris.size(), 3 * (shape.size() - 2));
        EXPECT_TRUE(tiles(p, tris, plane.axis, 17));
        ++checked;
    }
    EXPECT_GT(checked, 100);
}

TEST(Polygons, TheLargePolygonPathTilesEveryShape) {
    // The O(n log n) path (polygon_cdt.h) on the small shapes the ear clipper is tested on, by lowering the
    // size it starts at: the same shapes, triangle counts and tilings, the same refusals.
    auto large = [](const Polygon& p, cb::PolygonShape* kind) {
        std::vector<uint32_t> out;
        *kind = cb::triangulate_polygon(p.xyz.data(), p.poly.data(), p.poly.size(), out, 4);
        return out;
    };
    std::vector<std::array<double, 2>> bridge = {{0, 0}, {4, 0}, {4, 4}, {0, 4}, {0, 0},
                                                 {1, 1}, {1, 3}, {3, 3}, {3, 1}, {1, 1}};
    std::vector<std::array<double, 2>> collinear = {{0, 0}, {1, 0}, {2, 0}, {3, 0}, {3, 1}, {3, 2},
                                                    {2, 2}, {2, 1}, {1, 1}, {1, 2}, {0, 2}, {0, 1}};
    for (const auto& shape : {l_shape, u_shape, comb(7), bridge, collinear})
        for (const Plane& plane : planes)
            for (bool reverse : {false, true})
                for (size_t start : {size_t(0), size_t(2), size_t(5)}) {
                    SCOPED_TRACE(std::to_string(shape.size()) + " vertices, axis " + std::to_string(plane.axis) +
                                 (reverse ? ", reversed" : "") + ", starting at " + std::to_string(start));
                    Polygon p =
                        place(rotated(reverse ? reversed(shape) : shape, start), plane.u, plane.v, plane.origin);
                    cb::PolygonShape kind;
                    std::vector<uint32_t> tris = large(p, &kind);
                    EXPECT_EQ(kind, cb::PolygonShape::concave);
                    EXPECT_EQ(tris.size(), 3 * (shape.size() - 2));
                    EXPECT_TRUE(tiles(p, tris, plane.axis, 31));
                }
    std::vector<std::array<double, 2>> pentagram;
    for (int i = 0; i < 5; ++i) pentagram.push_back({std::cos(4 * M_PI * i / 5), std::sin(4 * M_PI * i / 5)});
    for (const auto& shape : std::vector<std::vector<std::array<double, 2>>>{
             {{0, 0}, {1, 1}, {1, 0}, {0, 1}},
             {{0, 0}, {4, 0}, {4, 4}, {2, 0}, {0, 4}},
             {{2, 0}, {4, 2}, {2, 4}, {0, 2}, {2, 0}, {3, 2}, {2, 3}},
             {{0, 0}, {4, 0}, {4, 4}, {2, 4}, {2, 0}, {1, 4}, {0, 4}},  // an edge along another
             pentagram}) {
        SCOPED_TRACE(std::to_string(shape.size()) + " vertices, not simple");
        Polygon p = place(shape);
        cb::PolygonShape kind;
        EXPECT_EQ(large(p, &kind), fan_of(p.poly));
        EXPECT_EQ(kind, cb::PolygonShape::not_simple);
    }
}

TEST(Polygons, AMillionVerticesAreTriangulated) {
    // A star of a million vertices (half of them reflex) and a circle whose float vertices turn both ways:
    // ear clipping's O(n^2) took minutes on either. The time is printed, not asserted (a figure of this
    // machine's load): 1.2-1.7 s of CPU on a 2-core VM.
    for (bool star : {true, false}) {
        const size_t n = 1'000'000;
        Polygon p;
        for (size_t i = 0; i < n; ++i) {
            double a = 2 * M_PI * double(i) / double(n), r = star && i % 2 ? 50 : 100;
            p.xyz.insert(p.xyz.end(), {float(r * std::cos(a)), float(r * std::sin(a)), 0.f});
            p.poly.push_back(uint32_t(i));
        }
        std::vector<uint32_t> tris;
        // The thread's own CPU time: ctest runs other tests beside this one on the same cores.
        auto cpu_seconds = [] {
            timespec t;
            clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
            return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
        };
        const double t0 = cpu_seconds();
        cb::PolygonShape kind = cb::triangulate_polygon(p.xyz.data(), p.poly.data(), n, tris);
        const double seconds = cpu_seconds() - t0;
        EXPECT_NE(kind, cb::PolygonShape::not_simple);
        EXPECT_EQ(tris.size(), 3 * (n - 2)) << "a simple polygon of n vertices makes n - 2 triangles";
        std::printf("%s of %zu vertices: %s, %zu triangles in %.3f s of CPU\n", star ? "star" : "circle", n,
                    kind == cb::PolygonShape::convex ? "convex" : "concave", tris.size() / 3, seconds);
    }
}

namespace {

cb::Scene load(const std::string& text, cb::FileFormat format) {
    return cb::load_mesh_memory(reinterpret_cast<const uint8_t*>(text.data()), text.size(), format, "t");
}

// The L shape (6 vertices), a convex quad (vertices 6..9) and a bow-tie (vertices 10..13), in three faces.
const char* const vertices =
    "2 0 0\n2 1 0\n1 1 0\n1 2 0\n0 2 0\n0 0 0\n"
    "5 0 0\n6 0 0\n6 1 0\n5 1 0\n"
    "8 0 0\n9 1 0\n9 0 0\n8 1 0\n";
const std::vector<std::vector<uint32_t>> faces = {{0, 1, 2, 3, 4, 5}, {6, 7, 8, 9}, {10, 11, 12, 13}};

void expect_three_faces(const cb::Scene& s) {
    const cb::Mesh& m = s.meshes[0];
    ASSERT_EQ(m.vertex_count(), 14u);
    ASSERT_EQ(m.triangle_count(), 4u + 2 + 2);
    Polygon l{m.positions, faces[0]};
    EXPECT_TRUE(tiles(l, std::vector<uint32_t>(m.indices.begin(), m.indices.begin() + 12)));
    EXPECT_EQ(std::vector<uint32_t>(m.indices.begin() + 12, m.indices.end()),
              (std::vector<uint32_t>{6, 7, 8, 6, 8, 9, 10, 11, 12, 10, 12, 13}));
    cb::SceneInfo info = cb::describe(s);
    EXPECT_EQ(info.polygons.total, 3u);
    EXPECT_EQ(info.polygons.concave, 1u);
    EXPECT_EQ(info.polygons.not_simple, 1u);
    EXPECT_EQ(info.polygons.degenerate, 0u);
    nlohmann::json j = cb::to_json(info);
    EXPECT_EQ(j["polygons"], 3);
    EXPECT_EQ(j["concave_polygons"], 1);
    EXPECT_EQ(j["not_simple_polygons"], 1);
}

std::string face_lines(const char* prefix, int base, bool with_count) {
    std::string out;
    for (const auto& f : faces) {
        out += prefix;
        if (with_count) out += std::to_string(f.size()) + " ";
        for (uint32_t i : f) out += std::to_string(int(i) + base) + " ";
        out += "\n";
    }
    return out;
}

}  // namespace

TEST(Polygons, ObjReader) {
    std::string obj;
    std::istringstream in(vertices);
    for (std::string line; std::getline(in, line);) obj += "v " + line + "\n";
    expect_three_faces(load(obj + face_lines("f ", 1, false), cb::FileFormat::obj));
}

TEST(Polygons, OffReader) {
    expect_three_faces(load(std::string("OFF\n14 3 0\n") + vertices + face_lines("", 0, true), cb::FileFormat::off));
}

TEST(Polygons, PlyReader) {
    std::string vertex_element = "element vertex 14\nproperty float x\nproperty float y\nproperty float z\n";
    std::string face_element = "element face 3\nproperty list uchar int vertex_indices\n";
    expect_three_faces(load(
        "ply\nformat ascii 1.0\n" + vertex_element + face_element + "end_header\n" + vertices + face_lines("", 0, true),
        cb::FileFormat::ply));
    // Faces before vertices: triangulated once the positions are read.
    expect_three_faces(load(
        "ply\nformat ascii 1.0\n" + face_element + vertex_element + "end_header\n" + face_lines("", 0, true) + vertices,
        cb::FileFormat::ply));
}

namespace {

// The faces of an OBJ or OFF file as written (v and f lines; OFF vertex and face lists), read here
// independently of the loaders.
struct Faces {
    std::vector<double> xyz;
    std::vector<std::vector<uint32_t>> faces;
};

Faces read_faces(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    cb::LineReader reader{text};
    Faces f;
    std::string line;
    std::vector<std::string_view> tok;
    bool off = path.extension() == ".off";
    long long nv = -1, nf = -1;
    while (reader.next(line, !off)) {
        cb::split(line, tok);
        if (tok.empty()) continue;
        if (off) {
            if (tok[0].find("OFF") != std::string_view::npos) continue;
            if (nv < 0) {
                cb::parse_int(tok[0], nv);
                cb::parse_int(tok[1], nf);
            } else if (f.xyz.size() < size_t(nv) * 3) {
                for (int k = 0; k < 3; ++k) cb::parse_double(tok[size_t(k)], f.xyz.emplace_back());
            } else {
                long long n;
                cb::parse_int(tok[0], n);
                std::vector<uint32_t> face;
                for (long long k = 1; k <= n; ++k) {
                    long long i;
                    cb::parse_int(tok[size_t(k)], i);
                    face.push_back(uint32_t(i));
                }
                f.faces.push_back(face);
            }
        } else if (tok[0] == "v") {
            for (int k = 1; k <= 3; ++k) cb::parse_double(tok[size_t(k)], f.xyz.emplace_back());
        } else if (tok[0] == "f") {
            std::vector<uint32_t> face;
            for (size_t k = 1; k < tok.size(); ++k) {
                long long i;
                cb::parse_int(tok[k].substr(0, tok[k].find('/')), i);
                face.push_back(uint32_t(i > 0 ? i - 1 : (long long)(f.xyz.size() / 3) + i));
            }
            f.faces.push_back(face);
        }
    }
    return f;
}

// Twice the area vector of a polygon (its Newell normal).
std::array<double, 3> area_vector(const std::vector<float>& xyz, const uint32_t* face, size_t n) {
    std::array<double, 3> sum = {0, 0, 0};
    const float* o = &xyz[size_t(face[0]) * 3];
    for (size_t i = 1; i + 1 < n; ++i) {
        const float *p = &xyz[size_t(face[i]) * 3], *q = &xyz[size_t(face[i + 1]) * 3];
        double a[3] = {double(p[0]) - o[0], double(p[1]) - o[1], double(p[2]) - o[2]};
        double b[3] = {double(q[0]) - o[0], double(q[1]) - o[1], double(q[2]) - o[2]};
        sum[0] += a[1] * b[2] - a[2] * b[1];
        sum[1] += a[2] * b[0] - a[0] * b[2];
        sum[2] += a[0] * b[1] - a[1] * b[0];
    }
    return sum;
}

// Areas of a face seen along the axis its normal points at most along (where the triangulator works, and
// where a face that float rounding made slightly non-planar still has one area): the face's own, and the
// sum of its triangles' each counted positive, which exceeds the face's when triangles fold over.
struct FaceAreas {
    double face = 0, triangles = 0;
};

FaceAreas face_areas(const std::vector<float>& xyz, const std::vector<uint32_t>& face, const uint32_t* tris,
                     size_t count) {
    std::array<double, 3> n = area_vector(xyz, face.data(), face.size());
    int axis = 0;
    for (int k = 1; k < 3; ++k)
        if (std::fabs(n[size_t(k)]) > std::fabs(n[size_t(axis)])) axis = k;
    FaceAreas a;
    a.face = 0.5 * std::fabs(n[size_t(axis)]);
    for (size_t t = 0; t < count; ++t) a.triangles += 0.5 * std::fabs(area_vector(xyz, tris + 3 * t, 3)[size_t(axis)]);
    return a;
}

}  // namespace

TEST(Polygons, SharedScenesWithPolygons) {
    // Real polygon files: a building solid with concave walls and near-collinear vertices, a wall with
    // holes cut as concave outlines, and (from assimp-testmodels, when installed) a concave LightWave face.
    fs::path shared(CB_SHARED_DATA);
    std::vector<fs::path> files = {shared / "hard/nearly-collinear.off", shared / "hard/wallhole.obj",
                                   fs::path(CB_ASSIMP_MODELS) / "OBJ/concave_polygon.obj"};
    int found = 0;
    for (const fs::path& file : files) {
        if (!fs::exists(file)) {
            std::printf("[  SKIPPED ] %s is absent\n", file.string().c_str());
            continue;
        }
        ++found;
        SCOPED_TRACE(file.string());
        cb::Scene scene = cb::load_scene(file.string());
        cb::SceneInfo info = cb::describe(scene);
        const cb::Mesh& mesh = scene.meshes[0];
        Faces written = read_faces(file);
        ASSERT_EQ(written.xyz.size(), mesh.positions.size());
        // Face by face (these files repeat no vertex, so face f has n - 2 triangles, in file order): the
        // triangles' area is the face's; the fan's is more.
        double faces = 0, triangles = 0, fans = 0;
        uint64_t count = 0;
        size_t next = 0;
        for (const auto& face : written.faces) {
            size_t n = face.size() - 2;
            ASSERT_LE(3 * (next + n), mesh.indices.size());
            for (size_t k = 3 * next; k < 3 * (next + n); ++k)
                ASSERT_NE(std::find(face.begin(), face.end(), mesh.indices[k]), face.end());
            FaceAreas mine = face_areas(mesh.positions, face, &mesh.indices[3 * next], n);
            std::vector<uint32_t> fan = fan_of(face);
            faces += mine.face;
            triangles += mine.triangles;
            fans += face_areas(mesh.positions, face, fan.data(), n).triangles;
            count += face.size() > 3;
            next += n;
        }
        EXPECT_EQ(3 * next, mesh.indices.size());
        std::printf("  %s: polygons %llu (%llu concave, %llu not simple), area %.9g, triangles %.9g, fan %.9g\n",
                    file.filename().string().c_str(), (unsigned long long)info.polygons.total,
                    (unsigned long long)info.polygons.concave, (unsigned long long)info.polygons.not_simple, faces,
                    triangles, fans);
        EXPECT_EQ(info.polygons.total, count);
        EXPECT_GT(info.polygons.concave, 0u);
        EXPECT_EQ(info.polygons.not_simple, 0u);
        EXPECT_NEAR(triangles, faces, 1e-9 * faces);
        EXPECT_GT(fans, faces * (1 + 1e-6));
    }
    if (!found) GTEST_SKIP() << "no shared scene with polygons is present";
}
