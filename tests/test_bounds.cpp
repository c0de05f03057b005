// Bounding volumes: containment of every vertex in every stored (float) volume, checked in double; cone
// soundness checked with CGAL's exact orientation predicate; the hard cases one by one.
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>
#include <random>

#include "baked.h"
#include "bounds.h"
#include "cluster.h"
#include "load.h"
#include "shared_scenes.h"

namespace fs = std::filesystem;
using K = CGAL::Exact_predicates_inexact_constructions_kernel;

namespace {

struct Soup {
    std::vector<float> positions;
    std::vector<uint32_t> indices;
    std::vector<uint32_t> all() const {
        std::vector<uint32_t> t(indices.size() / 3);
        std::iota(t.begin(), t.end(), 0u);
        return t;
    }
};

bool finite(const cb::ClusterBounds& b) {
    const float* begin = reinterpret_cast<const float*>(&b.obb);
    for (size_t i = 0; i < sizeof(cb::Obb) / 4; ++i)
        if (!std::isfinite(begin[i])) return false;
    const float* s = reinterpret_cast<const float*>(&b.sphere);
    for (size_t i = 0; i < 4; ++i)
        if (!std::isfinite(s[i])) return false;
    if (b.has_capsule)
        for (float v : {b.capsule.a[0], b.capsule.a[1], b.capsule.a[2], b.capsule.b[0], b.capsule.b[1], b.capsule.b[2],
                        b.capsule.radius})
            if (!std::isfinite(v)) return false;
    for (float v : {b.slab.axis[0], b.slab.axis[1], b.slab.axis[2], b.slab.low, b.slab.high})
        if (!std::isfinite(v)) return false;
    if (b.cone.valid)
        for (float v : {b.cone.front_apex[0], b.cone.front_apex[1], b.cone.front_apex[2], b.cone.back_apex[0],
                        b.cone.back_apex[1], b.cone.back_apex[2], b.cone.axis[0], b.cone.axis[1], b.cone.axis[2],
                        b.cone.cos_half_angle, b.cone.sin_half_angle})
            if (!std::isfinite(v)) return false;
    return true;
}

double segment_distance(const double p[3], const float a[3], const float b[3]) {
    double ab[3], ap[3], len2 = 0, t = 0;
    for (int k = 0; k < 3; ++k) {
        ab[k] = double(b[k]) - a[k];
        ap[k] = p[k] - a[k];
        len2 += ab[k] * ab[k];
        t += ap[k] * ab[k];
    }
    t = len2 > 0 ? std::clamp(t / len2, 0.0, 1.0) : 0.0;
    double d2 = 0;  // from differences only: absolute coordinates would round at 1e-11 near 1e5
    for (int k = 0; k < 3; ++k) d2 += (ap[k] - t * ab[k]) * (ap[k] - t * ab[k]);
    return std::sqrt(d2);
}

// Counts vertices outside each stored volume (all must be zero).
size_t containment_misses(const cb::ClusterBounds& b, const float* positions, const uint32_t* indices,
                          const uint32_t* tris, size_t count) {
    size_t misses = 0;
    for (size_t i = 0; i < count; ++i)
        for (int k = 0; k < 3; ++k) {
            const float* q = positions + size_t(indices[size_t(tris[i]) * 3 + k]) * 3;
            double p[3] = {q[0], q[1], q[2]};
            for (int a = 0; a < 3; ++a) {
                double d = 0;
                for (int j = 0; j < 3; ++j) d += (p[j] - b.obb.center[j]) * double(b.obb.axis[a][j]);
                misses += std::fabs(d) > b.obb.half[a];
            }
            double r2 = 0;
            for (int j = 0; j < 3; ++j) r2 += (p[j] - b.sphere.center[j]) * (p[j] - b.sphere.center[j]);
            misses += std::sqrt(r2) > b.sphere.radius;
            if (b.has_capsule) misses += segment_distance(p, b.capsule.a, b.capsule.b) > b.capsule.radius;
            double s = p[0] * double(b.slab.axis[0]) + p[1] * double(b.slab.axis[1]) + p[2] * double(b.slab.axis[2]);
            misses += s < b.slab.low || s > b.slab.high;
        }
    return misses;
}

// Random points strictly inside the front cone must see every non-degenerate triangle from the front, and
// points inside the back cone from the back, by CGAL's exact orientation. Returns the violations.
size_t cone_violations(const cb::ClusterBounds& b, const float* positions, const uint32_t* indices,
                       const uint32_t* tris, size_t count, std::mt19937& rng, int samples) {
    if (!b.cone.valid) return 0;
    double axis[3] = {b.cone.axis[0], b.cone.axis[1], b.cone.axis[2]};
    double len = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
    for (double& a : axis) a /= len;
    // Two unit vectors across the axis.
    double helper[3] = {std::fabs(axis[0]) < 0.9 ? 1.0 : 0.0, std::fabs(axis[0]) < 0.9 ? 0.0 : 1.0, 0.0};
    double u[3] = {axis[1] * helper[2] - axis[2] * helper[1], axis[2] * helper[0] - axis[0] * helper[2],
                   axis[0] * helper[1] - axis[1] * helper[0]};
    double ul = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    for (double& x : u) x /= ul;
    double w[3] = {axis[1] * u[2] - axis[2] * u[1], axis[2] * u[0] - axis[0] * u[2], axis[0] * u[1] - axis[1] * u[0]};
    double half = std::atan2(double(b.cone.sin_half_angle), double(b.cone.cos_half_angle));
    double reach = 4.0 * (b.sphere.radius + 1e-3f);
    std::uniform_real_distribution<double> unit(0, 1);
    size_t bad = 0;
    for (int s = 0; s < samples; ++s)
        for (int side : {+1, -1}) {
            double theta = half * 0.999 * unit(rng), phi = 2 * M_PI * unit(rng), t = reach * (1e-6 + unit(rng));
            double dir[3];
            for (int k = 0; k < 3; ++k)
                dir[k] = std::cos(theta) * axis[k] + std::sin(theta) * (std::cos(phi) * u[k] + std::sin(phi) * w[k]);
            const float* apex = side > 0 ? b.cone.front_apex : b.cone.back_apex;
            K::Point_3 p(apex[0] + side * t * dir[0], apex[1] + side * t * dir[1], apex[2] + side * t * dir[2]);
            for (size_t i = 0; i < count; ++i) {
                K::Point_3 v[3];
                for (int k = 0; k < 3; ++k) {
                    const float* q = positions + size_t(indices[size_t(tris[i]) * 3 + k]) * 3;
                    v[k] = K::Point_3(q[0], q[1], q[2]);
                }
                if (CGAL::collinear(v[0], v[1], v[2])) continue;  // zero area: no front side
                CGAL::Orientation o = CGAL::orientation(v[0], v[1], v[2], p);
                bad += side > 0 ? o != CGAL::POSITIVE : o != CGAL::NEGATIVE;
            }
        }
    return bad;
}

// expect_cone: 1 valid, 0 invalid, -1 either (inputs whose floats may collapse)
void check_all(const Soup& s, const char* what, int expect_cone) {
    SCOPED_TRACE(what);
    std::vector<uint32_t> tris = s.all();
    for (cb::ObbMethod method :
         {cb::ObbMethod::pca, cb::ObbMethod::pca_area, cb::ObbMethod::refined, cb::ObbMethod::cgal_optimal}) {
        cb::BoundsOptions o;
        o.obb = method;
        cb::ClusterBounds b = cb::fit_bounds(s.positions.data(), s.indices.data(), tris.data(), tris.size(), o);
        EXPECT_TRUE(finite(b));
        EXPECT_EQ(containment_misses(b, s.positions.data(), s.indices.data(), tris.data(), tris.size()), 0u)
            << int(method);
        std::mt19937 rng(1);
        EXPECT_EQ(cone_violations(b, s.positions.data(), s.indices.data(), tris.data(), tris.size(), rng, 50), 0u);
        if (expect_cone >= 0) {
            EXPECT_EQ(bool(b.cone.valid), expect_cone == 1);
        }
    }
}

Soup translated(Soup s, double by) {
    for (float& p : s.positions) p = float(double(p) + by);
    return s;
}

Soup bumpy_patch(int n, float size, float bump) {  // a height field facing +z: a valid cone
    Soup s;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i)
            s.positions.insert(s.positions.end(),
                               {size * i / n, size * j / n, bump * std::sin(float(i * 1.3 + j * 0.7))});
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            uint32_t a = uint32_t(j * (n + 1) + i), b = a + 1, c = a + uint32_t(n + 1), d = c + 1;
            s.indices.insert(s.indices.end(), {a, b, c, b, d, c});
        }
    return s;
}

}  // namespace

TEST(Bounds, OneTriangle) { check_all({{0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2}}, "one triangle", true); }

TEST(Bounds, ZeroAreaAndRepeatedIndex) {
    check_all({{0, 0, 0, 1, 0, 0, 2, 0, 0}, {0, 1, 2, 0, 0, 1}}, "only zero-area triangles", false);
    check_all({{0, 0, 0, 1, 0, 0, 0, 1, 0, 2, 0, 0}, {0, 1, 2, 0, 1, 3, 2, 2, 2}}, "mixed", true);
}

TEST(Bounds, AllCoplanar) { check_all(bumpy_patch(4, 1, 0), "flat patch", true); }

TEST(Bounds, AllCollinear) {
    Soup s;
    for (int i = 0; i < 10; ++i) s.positions.insert(s.positions.end(), {float(i), float(2 * i), float(3 * i)});
    for (uint32_t i = 0; i + 2 < 10; ++i) s.indices.insert(s.indices.end(), {i, i + 1, i + 2});
    check_all(s, "collinear", false);
}

TEST(Bounds, DuplicateVertices) {
    Soup s = bumpy_patch(3, 1, 0.2f);
    size_t n = s.positions.size();
    s.positions.insert(s.positions.end(), s.positions.begin(),
                       s.positions.begin() + std::ptrdiff_t(n));  // every vertex twice
    size_t half = s.indices.size();
    for (size_t i = 0; i < half; ++i) s.indices.push_back(s.indices[i] + uint32_t(n / 3));
    check_all(s, "duplicates", true);
}

TEST(Bounds, FarFromTheOrigin) {
    for (double offset : {1e6, 1e7, -3e7}) {
        check_all(translated(bumpy_patch(4, 10, 1), offset), "10-unit patch far away", -1);
        // A cluster of size 1e-6 far from the origin: its floats collapse onto one or a few points.
        check_all(translated(bumpy_patch(2, 1e-6f, 2e-7f), offset), "tiny patch far away", -1);
    }
}

TEST(Bounds, TinyNearTheOrigin) { check_all(bumpy_patch(3, 1e-6f, 3e-7f), "tiny patch", true); }

TEST(Bounds, NeedleTriangles) {
    Soup s;
    for (int i = 0; i < 8; ++i) {
        uint32_t b = uint32_t(s.positions.size() / 3);
        float y = float(i) * 1e-3f;
        s.positions.insert(s.positions.end(), {0, y, 0, 100, y + 1e-4f, 0, 50, y, 1e-5f});
        s.indices.insert(s.indices.end(), {b, b + 1, b + 2});
    }
    check_all(s, "needles", true);
}

TEST(Bounds, NormalsThatCancel) {
    // Both faces of a square: the mean normal is zero, so there is no cone: never cull.
    check_all({{0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, {0, 1, 2, 0, 2, 3, 0, 2, 1, 0, 3, 2}}, "two-sided square", false);
    // A closed box: normals spread over every direction.
    Soup box;
    box.positions = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
    box.indices = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                   2, 3, 7, 2, 7, 6, 1, 2, 6, 1, 6, 5, 0, 4, 7, 0, 7, 3};
    check_all(box, "closed box", false);
}

TEST(Bounds, RotatedBoxIsFoundExactly) {
    // The 8 corners of a 4 x 2 x 1 box turned by a rotation: the refined fit recovers the volume 8.
    double c = std::cos(0.4), s = std::sin(0.4), c2 = std::cos(1.1), s2 = std::sin(1.1);
    std::vector<double> pts;
    for (int i = 0; i < 8; ++i) {
        double x = (i & 1 ? 2 : -2), y = (i & 2 ? 1 : -1), z = (i & 4 ? 0.5 : -0.5);
        double x1 = c * x - s * y, y1 = s * x + c * y;        // about z
        double y2 = c2 * y1 - s2 * z, z2 = s2 * y1 + c2 * z;  // about x
        pts.insert(pts.end(), {x1, y2, z2});
    }
    double origin[3] = {0, 0, 0};
    // The stored rotation is a 16-bit quaternion (steps of about 2e-5 radians), so the stored box is up to a
    // few 1e-4 larger than the exact one; never smaller.
    cb::Obb refined = cb::fit_obb(pts.data(), 8, origin, cb::ObbMethod::refined);
    EXPECT_GE(cb::obb_volume(refined), 8.0);
    EXPECT_NEAR(cb::obb_volume(refined), 8.0, 8 * 3e-4);
    cb::Obb optimal = cb::fit_obb(pts.data(), 8, origin, cb::ObbMethod::cgal_optimal);
    EXPECT_NEAR(cb::obb_volume(optimal), 8.0, 8 * 3e-4);
}

TEST(Bounds, FineBoxesComeNearTheOptimum) {
    // Fine clusters whose best box PCA misses: 12 points in a random triangle, 1% as thick as wide, turned at
    // random. The best rectangle across the plate lies along an edge of the points' hull, rarely along PCA's
    // axes; the refined fit's rectangle and descent must come near CGAL's optimum.
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> unit(-1, 1);
    double sum = 0, worst = 0;
    const int sets = 200;
    for (int set = 0; set < sets; ++set) {
        double corner[3][2];
        for (auto& c : corner) c[0] = unit(rng), c[1] = unit(rng);
        double q[4] = {unit(rng), unit(rng), unit(rng), unit(rng)}, len = 0;
        for (double x : q) len += x * x;
        for (double& x : q) x /= std::sqrt(len);
        const double w = q[0], x = q[1], y = q[2], z = q[3];
        const double r[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
                                {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
                                {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}};
        std::vector<double> pts;
        for (int i = 0; i < 12; ++i) {
            double a = 0.5 * (unit(rng) + 1), b = 0.5 * (unit(rng) + 1);
            if (a + b > 1) a = 1 - a, b = 1 - b;
            const double p[3] = {corner[0][0] + a * (corner[1][0] - corner[0][0]) + b * (corner[2][0] - corner[0][0]),
                                 corner[0][1] + a * (corner[1][1] - corner[0][1]) + b * (corner[2][1] - corner[0][1]),
                                 0.01 * unit(rng)};
            for (int k = 0; k < 3; ++k) pts.push_back(r[k][0] * p[0] + r[k][1] * p[1] + r[k][2] * p[2]);
        }
        const double origin[3] = {0, 0, 0};
        const double refined = cb::obb_volume(cb::fit_obb(pts.data(), 12, origin, cb::ObbMethod::refined));
        const double optimal = cb::obb_volume(cb::fit_obb(pts.data(), 12, origin, cb::ObbMethod::cgal_optimal));
        ASSERT_GT(optimal, 0);
        sum += refined / optimal;
        worst = std::max(worst, refined / optimal);
    }
    std::printf("refined / optimal volume: mean %.4f, worst %.3f\n", sum / sets, worst);
    // Measured: mean 1.0099, worst 1.082; from the PCA frame without a rectangle 1.0153 and 1.199.
    EXPECT_LT(sum / sets, 1.0125);
    EXPECT_LT(worst, 1.15);
}

TEST(Bounds, BoxesAlongTheWorldAxesPackExactly) {
    // A flat face in the plane y = 0.25, longer along z than along x: PCA finds its axes in the order z, x, y,
    // a turn of the world axes. Stored as found, the 16-bit quaternion would turn it by a few 1e-5 radians and
    // the box would grow about 1e-5 thick to hold the face; stored under the identity it stays flat.
    std::vector<double> face;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 4; ++j) face.insert(face.end(), {0.5 * i, 0.25, 1.0 * j});
    // A 1 x 3 x 2 box, its sides in no order of size.
    std::vector<double> box;
    for (int i = 0; i < 8; ++i) box.insert(box.end(), {i & 1 ? 0.5 : -0.5, i & 2 ? 1.5 : -1.5, i & 4 ? 1.0 : -1.0});
    const double origin[3] = {0, 0, 0};
    for (cb::ObbMethod m : {cb::ObbMethod::refined, cb::ObbMethod::pca, cb::ObbMethod::pca_area}) {
        SCOPED_TRACE(cb::obb_method_name(m));
        const cb::Obb flat = cb::fit_obb(face.data(), 12, origin, m);
        EXPECT_LT(*std::min_element(flat.half, flat.half + 3), 1e-6);
        EXPECT_NEAR(*std::max_element(flat.half, flat.half + 3), 1.5, 1e-6);
        const cb::Obb b = cb::fit_obb(box.data(), 8, origin, m);
        EXPECT_GE(cb::obb_volume(b), 6.0);
        EXPECT_NEAR(cb::obb_volume(b), 6.0, 6 * 1e-5);
    }
}

TEST(Bounds, MinimalSphereIsMinimal) {
    // Regular tetrahedron with circumradius 1, plus interior points: the minimal sphere has radius 1.
    std::vector<double> pts = {1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1, 0.1, 0.2, 0.1, -0.3, 0, 0.2};
    for (double& p : pts) p /= std::sqrt(3.0);
    double origin[3] = {0, 0, 0};
    cb::Sphere s = cb::fit_sphere(pts.data(), 6, origin);
    EXPECT_NEAR(s.radius, 1.0, 1e-6);
    cb::Sphere r = cb::ritter_sphere(pts.data(), 6, origin);
    EXPECT_GE(r.radius, s.radius);
}

TEST(Bounds, EveryClusterOfEverySharedFile) {
    if (!fs::exists(CB_SHARED_DATA)) GTEST_SKIP() << "../shared/data is absent";
    size_t clusters = 0, misses = 0, violations = 0, cones = 0;
    std::mt19937 rng(7);
    cb::test::for_each_shared_scene([&](const std::string& path, const cb::Scene& scene) {
        for (const cb::Mesh& m : scene.meshes) {
            cb::ClusterOptions co;
            cb::Hierarchy h =
                cb::build_hierarchy(m.positions.data(), m.vertex_count(), m.indices.data(), m.triangle_count(), co);
            auto check = [&](uint32_t first, uint32_t count, int samples) {
                cb::ClusterBounds b =
                    cb::fit_bounds(m.positions.data(), m.indices.data(), h.order.data() + first, count, {});
                ++clusters;
                cones += b.cone.valid;
                EXPECT_TRUE(finite(b)) << path;
                misses += containment_misses(b, m.positions.data(), m.indices.data(), h.order.data() + first, count);
                violations += cone_violations(b, m.positions.data(), m.indices.data(), h.order.data() + first, count,
                                              rng, samples);
            };
            for (size_t f = 0; f < h.fine_count(); ++f)
                check(h.fine_offsets[f], h.fine_offsets[f + 1] - h.fine_offsets[f], 1);
            for (size_t c = 0; c < h.coarse_count(); ++c) {
                uint32_t a = h.fine_offsets[h.coarse_offsets[c]], b = h.fine_offsets[h.coarse_offsets[c + 1]];
                check(a, b - a, 2);
            }
        }
    });
    std::printf("%zu clusters, %zu with a valid cone\n", clusters, cones);
    EXPECT_GT(clusters, 40000u);
    EXPECT_EQ(misses, 0u);
    EXPECT_EQ(violations, 0u);
    EXPECT_GT(cones, clusters / 2);
}

TEST(Bounds, AssetBoundsContainEveryVertexOfTheirCluster) {
    cb::test::Baked baked = cb::test::bake_scene(cb::load_scene(std::string(CB_SOURCE_DIR) + "/data/default_scene.glb"),
                                                 {}, cb::bounds_all, 2);
    ASSERT_GT(baked.view.mesh_count, 0u) << "bake failed";
    const cb::AssetView& view = baked.view;
    size_t misses = 0, violations = 0, checked = 0;
    std::mt19937 rng(3);
    for (uint32_t m = 0; m < view.mesh_count; ++m) {
        const cb::MeshRecord& r = view.meshes[m];
        const float* positions = view.positions + size_t(r.first_vertex) * 3;
        // The decoded triangles, in cluster order, as plain indices for the checks.
        std::vector<uint32_t> tris;
        for (uint32_t f = 0; f < r.fine_count; ++f) {
            const cb::FineCluster& c = view.fine[r.first_fine + f];
            for (uint32_t t = c.first_triangle; t < c.first_triangle + c.triangle_count; ++t) {
                uint32_t id[3];
                view.triangle(r, f, t, id);
                tris.insert(tris.end(), id, id + 3);
            }
        }
        std::vector<uint32_t> ids(r.triangle_count);
        std::iota(ids.begin(), ids.end(), 0u);
        auto check = [&](const cb::LevelBounds& level, uint32_t cluster, uint32_t first, uint32_t count) {
            cb::ClusterBounds b{};
            b.obb = level.obb(cluster);
            b.sphere = level.spheres[cluster];
            b.capsule = level.capsules[cluster];
            b.has_capsule = true;  // a sphere-as-capsule must contain the cluster too
            b.cone = level.cone(cluster);
            b.slab = level.slabs[cluster];
            misses += containment_misses(b, positions, tris.data(), ids.data() + first, count);
            violations += cone_violations(b, positions, tris.data(), ids.data() + first, count, rng, 2);
            ++checked;
        };
        for (uint32_t f = 0; f < r.fine_count; ++f) {
            const cb::FineCluster& c = view.fine[r.first_fine + f];
            check(view.fine_bounds, r.first_fine + f, c.first_triangle, c.triangle_count);
        }
        for (uint32_t c = 0; c < r.coarse_count; ++c) {
            const cb::ClusterRange& range = view.coarse[r.first_coarse + c];
            const cb::FineCluster& a = view.fine[r.first_fine + range.first];
            const cb::FineCluster& z = view.fine[r.first_fine + range.first + range.count - 1];
            check(view.coarse_bounds, r.first_coarse + c, a.first_triangle,
                  z.first_triangle + z.triangle_count - a.first_triangle);
        }
    }
    EXPECT_EQ(checked, size_t(view.fine_count) + view.coarse_count);
    EXPECT_EQ(misses, 0u);
    EXPECT_EQ(violations, 0u);
}

// Capsules far from the origin, checked exactly: every vertex's squared distance to the stored segment, in
// CGAL's exact arithmetic over the stored floats, at most the stored radius squared. Elongated single
// triangles (as `--fine 1` makes) at 1e5 to 1e7, where the rounding of an absolute coordinate is larger
// than a margin taken relative to the cluster's size.
TEST(Bounds, CapsulesFarFromTheOriginHoldEveryVertexExactly) {
    using E = CGAL::Exact_predicates_exact_constructions_kernel;
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> unit(-1, 1);
    cb::BoundsOptions options;
    options.mask = cb::bounds_capsule;
    size_t capsules = 0, misses = 0;
    for (double offset : {1e5, 4e5, 3e6, 1e7})
        for (int i = 0; i < 2000; ++i) {
            // A sliver: two corners far apart along a random direction, the third near the middle.
            double dir[3] = {unit(rng), unit(rng), unit(rng)}, len = 0.5 + 20 * std::fabs(unit(rng));
            double o[3] = {offset + 50 * unit(rng), -offset + 50 * unit(rng), offset * 0.5 + 50 * unit(rng)};
            std::vector<float> p = {float(o[0]),
                                    float(o[1]),
                                    float(o[2]),
                                    float(o[0] + len * dir[0]),
                                    float(o[1] + len * dir[1]),
                                    float(o[2] + len * dir[2]),
                                    float(o[0] + 0.5 * len * dir[0] + 0.01 * unit(rng)),
                                    float(o[1] + 0.5 * len * dir[1] + 0.01 * unit(rng)),
                                    float(o[2] + 0.5 * len * dir[2] + 0.01 * unit(rng))};
            std::vector<uint32_t> indices = {0, 1, 2}, tris = {0};
            cb::ClusterBounds b = cb::fit_bounds(p.data(), indices.data(), tris.data(), 1, options);
            if (!b.has_capsule) continue;
            ++capsules;
            E::Segment_3 axis(E::Point_3(b.capsule.a[0], b.capsule.a[1], b.capsule.a[2]),
                              E::Point_3(b.capsule.b[0], b.capsule.b[1], b.capsule.b[2]));
            E::FT r = b.capsule.radius;
            for (int v = 0; v < 3; ++v) {
                E::Point_3 q(p[v * 3], p[v * 3 + 1], p[v * 3 + 2]);
                misses += CGAL::squared_distance(q, axis) > r * r;
            }
        }
    EXPECT_GT(capsules, 7000u);
    EXPECT_EQ(misses, 0u) << "vertices outside their capsule, exactly, of " << capsules << " capsules";
}
