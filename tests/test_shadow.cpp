// The runtime's exact predicates and shadow queries against CGAL: orientation signs, the segment test's
// semantics, and whole queries over baked assets against a brute-force exact oracle.
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <detail/cb_exact.h>
#include <cb_instance_shadow.h>
#include <cb_shadow.h>

#include <cstring>
#include <filesystem>
#include <memory>
#include <random>

#include "bake.h"
#include "hard_cases.h"
#include "load.h"
#include "scene_oracle.h"
#include "shadow_oracle.h"

namespace fs = std::filesystem;
using Epick = CGAL::Exact_predicates_inexact_constructions_kernel;
using cb::test::bake;
using cb::test::Baked;
using cb::test::oracle;
using cb::test::sample_scene;
using cb::test::SceneOracle;
using cb::test::WorldSample;

namespace {

int cgal_orient(const double* a, const double* b, const double* c, const double* d) {
    // CGAL: positive when d is on the positive side of plane a, b, c (sign of | b-a, c-a, d-a |).
    // cb::exact::orient3d(a, b, c, d) is the sign of | a-d, b-d, c-d |, which is minus that.
    CGAL::Orientation o = CGAL::orientation(Epick::Point_3(a[0], a[1], a[2]), Epick::Point_3(b[0], b[1], b[2]),
                                            Epick::Point_3(c[0], c[1], c[2]), Epick::Point_3(d[0], d[1], d[2]));
    return -int(o);
}

// Values of T for the lane tests: one in `special_in` of zeros, infinities, NaN or 1 (lane i takes the i-th
// modulo 6), else a mantissa in (-1, 1) scaled by 2^e, e drawn from [lowest, highest].
template <class T>
struct LaneValues {
    std::mt19937_64 rng;
    int special_in;
    std::uniform_real_distribution<T> mantissa{-1, 1};
    std::uniform_int_distribution<int> order;
    LaneValues(uint64_t seed, int special_in, int lowest, int highest)
        : rng(seed), special_in(special_in), order(lowest, highest) {}
    T operator()(uint32_t i) {
        const T special[6] = {T(0), -T(0), T(INFINITY), -T(INFINITY), T(NAN), T(1)};
        if (rng() % special_in == 0) return special[i % 6];
        return std::ldexp(mantissa(rng), order(rng));
    }
};

}  // namespace

// Each test build runs the filters on the lanes it was meant for (tests/CMakeLists.txt), so every width is
// checked where the machine has it.
TEST(Lanes, BuiltForTheIntendedWidth) {
    EXPECT_EQ(cb::simd::width, uint32_t(CB_EXPECTED_LANES));
#ifdef CB_NO_SIMD
#ifdef CB_SIMD_SSE2
    ADD_FAILURE() << "CB_NO_SIMD still selected SSE2";
#endif
#endif
}

// The double lanes (a tile's set-up in an instance's frame) give, lane by lane, the bits of the same operations
// on one double: fused multiply-adds as std::fma, square roots, quotients, comparisons and selects by lane
// masks, and the reductions. Values across 600 binary orders, with zeros, infinities and NaN among them.
TEST(Lanes, DoubleLanesGiveTheScalarBits) {
    using cb::simd::Doubles;
    constexpr uint32_t w = cb::simd::dwidth;
    LaneValues<double> draw(7, 16, -300, 300);
    std::mt19937_64& rng = draw.rng;
    auto same = [](double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0 || (a != a && b != b); };
    for (int round = 0; round < 2000; ++round) {
        alignas(64) double a[w], b[w], c[w], out[w];
        for (uint32_t i = 0; i < w; ++i) {
            a[i] = draw(i);
            b[i] = draw(i + 1);
            c[i] = draw(i + 2);
        }
        const Doubles x = cb::simd::load(a), y = cb::simd::load(b), z = cb::simd::load(c);
        cb::simd::store(out, cb::simd::fused(x, y, z));
        for (uint32_t i = 0; i < w; ++i) EXPECT_TRUE(same(out[i], std::fma(a[i], b[i], c[i]))) << a[i] << " " << b[i];
        cb::simd::store(out, cb::simd::sqrt(cb::simd::abs(x)) + y / z - x * y);
        for (uint32_t i = 0; i < w; ++i)
            EXPECT_TRUE(same(out[i], std::sqrt(std::fabs(a[i])) + b[i] / c[i] - a[i] * b[i])) << a[i];
        const uint32_t lanes = uint32_t(rng()) & ((1u << w) - 1);
        const uint32_t less = cb::simd::bits(x < y), greater = cb::simd::bits(x > y), most = cb::simd::bits(x <= y);
        cb::simd::store(out, cb::simd::select(cb::simd::double_lanes(lanes) & (x <= y), x, y));
        double lo = a[0], hi = a[0], sum = 0;
        for (uint32_t i = 0; i < w; ++i) {
            EXPECT_EQ(less >> i & 1, uint32_t(a[i] < b[i]));
            EXPECT_EQ(greater >> i & 1, uint32_t(a[i] > b[i]));
            EXPECT_EQ(most >> i & 1, uint32_t(a[i] <= b[i]));
            EXPECT_TRUE(same(out[i], (lanes >> i & 1) && a[i] <= b[i] ? a[i] : b[i]));
            lo = a[i] < lo ? a[i] : lo;
            hi = a[i] > hi ? a[i] : hi;
            sum += a[i];
        }
        EXPECT_TRUE(same(cb::simd::lane_min(x), lo));
        EXPECT_TRUE(same(cb::simd::lane_max(x), hi));
        EXPECT_TRUE(same(cb::simd::lane_sum(x), sum));
    }
}

// The float lanes' selects by comparison masks, and their maximum with the operands swapped: max(b, a) gives
// std::max(a, b)'s bits lane by lane, NaN and signed zeros included (light_triangles takes its edges' largest
// terms so). Values across 260 binary orders, with zeros, infinities and NaN among them.
TEST(Lanes, FloatSelectAndSwappedMaxGiveTheScalarBits) {
    using cb::simd::Floats;
    constexpr uint32_t w = cb::simd::width;
    LaneValues<float> draw(11, 8, -140, 120);
    auto same = [](float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; };
    for (int round = 0; round < 2000; ++round) {
        alignas(64) float a[w], b[w], out[w];
        for (uint32_t i = 0; i < w; ++i) {
            a[i] = draw(i);
            b[i] = draw(i + 3);
        }
        const Floats x = cb::simd::load(a), y = cb::simd::load(b);
        cb::simd::store(out, cb::simd::max(y, x));
        for (uint32_t i = 0; i < w; ++i) EXPECT_TRUE(same(out[i], std::max(a[i], b[i]))) << a[i] << " " << b[i];
        cb::simd::store(out, cb::simd::select(x < y, x, y));
        for (uint32_t i = 0; i < w; ++i) EXPECT_TRUE(same(out[i], a[i] < b[i] ? a[i] : b[i])) << a[i] << " " << b[i];
    }
}

// The inlined next float (rounding outward without a library call) against std::nextafter: zeros,
// subnormals, the ends of the normal range, infinities and random bit patterns, both ways.
TEST(Exact, NextFloatMatchesNextafter) {
    std::vector<float> values = {0.0f,
                                 -0.0f,
                                 1.0f,
                                 -1.0f,
                                 std::numeric_limits<float>::denorm_min(),
                                 -std::numeric_limits<float>::denorm_min(),
                                 std::numeric_limits<float>::min(),
                                 -std::numeric_limits<float>::min(),
                                 std::numeric_limits<float>::max(),
                                 -std::numeric_limits<float>::max(),
                                 INFINITY,
                                 -INFINITY};
    std::mt19937 rng(5);
    while (values.size() < 100000) {
        uint32_t bits = uint32_t(rng());
        float f;
        std::memcpy(&f, &bits, sizeof f);
        if (f == f) values.push_back(f);
    }
    auto bits_of = [](float f) {
        uint32_t b;
        std::memcpy(&b, &f, sizeof b);
        return b;
    };
    size_t wrong = 0;
    for (float f : values)
        for (bool up : {false, true}) {
            if (up && f == INFINITY) continue;  // nothing beyond: not asked of it (round_up never is)
            if (!up && f == -INFINITY) continue;
            wrong += bits_of(cb::math::next_float(f, up)) != bits_of(std::nextafter(f, up ? INFINITY : -INFINITY));
        }
    EXPECT_EQ(wrong, 0u);
}

TEST(Shadow, BatchOrderSortsByKeyStably) {
    // batch_order_from_keys sorts few points by comparison and many by radix: both give the indices ordered by
    // the key's 23 bits, ties in index order. Keys drawn from a few values (many ties), with bits above the 23.
    std::mt19937 rng(23);
    for (size_t n : {size_t(0), size_t(1), size_t(7), size_t(255), size_t(256), size_t(257), size_t(5000)})
        for (uint32_t values : {3u, 1000u, 1u << 23}) {
            std::vector<uint32_t> keys(n), order(n), scratch(cb::batch_order_scratch_size(n)), expected(n);
            for (uint32_t& k : keys) k = uint32_t(rng()) % values | (uint32_t(rng()) & 0xff800000u);
            cb::batch_order_from_keys(keys.data(), n, order.data(), scratch.data());
            for (size_t i = 0; i < n; ++i) expected[i] = uint32_t(i);
            std::stable_sort(expected.begin(), expected.end(),
                             [&](uint32_t a, uint32_t b) { return (keys[a] & 0x7fffffu) < (keys[b] & 0x7fffffu); });
            EXPECT_EQ(order, expected) << n << " points, " << values << " key values";
        }
}

TEST(Exact, OrientationAgreesWithCgal) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-1, 1);
    std::uniform_int_distribution<int> small(-4, 4);
    size_t exact_path = 0, zeros = 0;
    for (int i = 0; i < 200000; ++i) {
        double pts[4][3];
        int kind = i % 4;
        for (auto& p : pts)
            for (double& x : p) x = u(rng);
        if (kind == 1) {  // exactly coplanar: z = x + 2y on small integers, then offset far away
            for (auto& p : pts) {
                p[0] = small(rng);
                p[1] = small(rng);
                p[2] = p[0] + 2 * p[1];
                for (double& x : p) x += 1e7;
            }
        } else if (kind == 2) {  // coplanar, moved off zero (subnormals are outside the predicate's domain),
                                 // then the last point nudged by one ulp
            for (auto& p : pts) {
                p[0] = small(rng) * 0.5 + 10;
                p[1] = small(rng) * 0.25 + 10;
                p[2] = p[0] - p[1] + 10;
            }
            pts[3][2] = std::nextafter(pts[3][2], 100.0);
        } else if (kind == 3) {  // float coordinates far out, as assets hold them
            for (auto& p : pts)
                for (double& x : p) x = double(float(4e6 + 3 * u(rng)));
        }
        int ours = cb::exact::orient3d(pts[0], pts[1], pts[2], pts[3]);
        int theirs = cgal_orient(pts[0], pts[1], pts[2], pts[3]);
        ASSERT_EQ(ours, theirs) << "case " << i;
        zeros += ours == 0;
        exact_path += cb::exact::sign(cb::exact::orient3d_exact(pts[0], pts[1], pts[2], pts[3])) != ours;
    }
    EXPECT_EQ(exact_path, 0u) << "filtered and exact evaluations disagree";
    EXPECT_GT(zeros, 40000u);  // the coplanar family really is coplanar
}

TEST(Exact, ZeroBoundIsAnExactZero) {
    // Four points on a plane of constant x, y or z, and the fourth point equal to one of the others: every
    // product of the estimate has a zero difference, so its bound is zero and the sign is settled as zero
    // without the exact path. CGAL agrees.
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1e3, 1e3);
    size_t settled = 0;
    const int cases = 30000;
    for (int i = 0; i < cases; ++i) {
        double pts[4][3];
        for (auto& p : pts)
            for (double& x : p) x = u(rng);
        if (i % 2 == 0)
            for (auto& p : pts) p[i / 2 % 3] = pts[0][i / 2 % 3];
        else
            std::copy_n(pts[i / 2 % 3], 3, pts[3]);
        double bound, det = cb::exact::orient3d_estimate(pts[0], pts[1], pts[2], pts[3], bound);
        settled += cb::exact::settled_sign(det, bound) == 0;
        ASSERT_EQ(cb::exact::orient3d(pts[0], pts[1], pts[2], pts[3]), 0) << "case " << i;
        ASSERT_EQ(cgal_orient(pts[0], pts[1], pts[2], pts[3]), 0) << "case " << i;
    }
    EXPECT_EQ(settled, size_t(cases));
    // A bound above zero is never settled as zero, however small the estimate.
    const double a[3] = {0, 0, 0}, b[3] = {1, 0, 0}, c[3] = {0, 1, 0}, d[3] = {0.25, 0.25, 1e-80};
    double bound, det = cb::exact::orient3d_estimate(a, b, c, d, bound);
    EXPECT_NE(cb::exact::settled_sign(det, bound), 0);
    EXPECT_EQ(cb::exact::orient3d(a, b, c, d), cgal_orient(a, b, c, d));
}

TEST(Exact, SegmentTestAgreesWithCgalOracle) {
    std::mt19937 rng(9);
    std::uniform_int_distribution<int> grid(-3, 3);  // small integer grids: many exact contacts
    std::uniform_real_distribution<double> u(-2, 2);
    size_t touching = 0, blocks = 0, checked = 0;
    for (int i = 0; i < 60000; ++i) {
        double p[3], q[3], a[3], b[3], c[3];
        bool on_grid = i % 2 == 0;
        for (double* v : {p, q, a, b, c})
            for (int k = 0; k < 3; ++k) v[k] = on_grid ? grid(rng) : u(rng);
        if (i % 6 == 1) {  // the query point on the triangle (self-shadowing), light anywhere
            double s = (i % 5) * 0.125, t = (i % 3) * 0.25;
            for (int k = 0; k < 3; ++k) p[k] = a[k] + s * (b[k] - a[k]) + t * (c[k] - a[k]);
        }
        bool two_sided = i % 3 != 2;
        // Where contacts start: powers of two and not, tiny and large, zero (a point on the triangle then
        // shadows itself), past the light, and the rule's own value for a bias.
        const double froms[] = {1.0 / 8192, 0.3, 1e-9 * (1 + std::fabs(u(rng))), 0.0, 1.0, 1.5, 0.125 + 1e-3 * u(rng)};
        const double from = i % 8 == 7 ? cb::shadow_from(p, q, 0.05) : froms[i % 8];
        cb::SegmentTest ours = cb::segment_triangle(p, q, a, b, c, from, two_sided),
                        theirs = oracle(p, q, a, b, c, from, two_sided);
        ASSERT_EQ(ours.blocks, theirs.blocks) << "case " << i;
        ASSERT_EQ(ours.touching, theirs.touching) << "case " << i;
        touching += ours.touching;
        blocks += ours.blocks;
        ++checked;
    }
    std::printf("%zu segment tests: %zu block, %zu touching\n", checked, blocks, touching);
    EXPECT_GT(touching, 1000u);
    EXPECT_GT(blocks, 1000u);
}

TEST(Exact, RayTestAgreesWithCgalOracle) {
    // The sun's ray test (cb::ray_triangle) against CGAL's exact ray-triangle intersection: random and grid
    // cases, the point on the triangle, the ray parallel to the triangle's plane (in it, or beside it), and
    // `from` tiny, a power of two or not, zero and large (a ray has no far end).
    std::mt19937 rng(19);
    std::uniform_int_distribution<int> grid(-3, 3);
    std::uniform_real_distribution<double> u(-2, 2);
    size_t touching = 0, blocks = 0, parallel = 0;
    for (int i = 0; i < 60000; ++i) {
        double p[3], d[3], a[3], b[3], c[3];
        const bool on_grid = i % 2 == 0;
        for (double* v : {p, d, a, b, c})
            for (int k = 0; k < 3; ++k) v[k] = on_grid ? grid(rng) : u(rng);
        if (i % 6 == 1) {  // the point on the triangle
            const double s = (i % 5) * 0.125, t = (i % 3) * 0.25;
            for (int k = 0; k < 3; ++k) p[k] = a[k] + s * (b[k] - a[k]) + t * (c[k] - a[k]);
        }
        if (i % 7 == 3) {  // the ray parallel to the plane: along an edge, or a sum of two (exact on the grid)
            for (int k = 0; k < 3; ++k) d[k] = i % 2 ? b[k] - a[k] : (b[k] - a[k]) + (c[k] - a[k]);
            ++parallel;
        }
        const bool two_sided = i % 3 != 2;
        const double froms[] = {1.0 / 8192, 0.3, 1e-9 * (1 + std::fabs(u(rng))), 0.0, 7.5, 0.125 + 1e-3 * u(rng)};
        const double from = i % 7 == 6 ? cb::sun_from(d, 0.05) : froms[i % 6];
        const cb::SegmentTest ours = cb::ray_triangle(p, d, a, b, c, from, two_sided),
                              theirs = cb::test::oracle_ray(p, d, a, b, c, from, two_sided);
        ASSERT_EQ(ours.blocks, theirs.blocks) << "case " << i;
        ASSERT_EQ(ours.touching, theirs.touching) << "case " << i;
        touching += ours.touching;
        blocks += ours.blocks;
    }
    std::printf("60000 ray tests (%zu parallel to the plane): %zu block, %zu touching\n", parallel, blocks, touching);
    EXPECT_GT(touching, 100u);  // boundary contacts that count (245 with this seed)
    EXPECT_GT(blocks, 1000u);
}

TEST(Shadow, ReferenceQueryAgreesWithExactOracle) {
    std::vector<std::string> files = {std::string(CB_SOURCE_DIR) + "/data/default_scene.glb"};
    for (const char* f : {"scanned/spot_low_resolution.obj", "scanned/bunny_npm.obj", "hard/tube.obj", "hard/v405.off"})
        if (fs::exists(fs::path(CB_SHARED_DATA) / f)) files.push_back((fs::path(CB_SHARED_DATA) / f).string());
    size_t queries = 0, disagreements = 0, touching = 0, shadowed = 0, one_sided_differs = 0;
    for (const std::string& file : files) {
        SCOPED_TRACE(file);
        Baked b = bake(file);
        ASSERT_GT(b.view.mesh_count, 0u) << "bake failed";
        const cb::AssetView& v = b.view;
        const double bias = cb::test::asset_bias(v);  // the builds' default
        WorldSample world = sample_scene(b.scene, 3);
        SceneOracle exact_oracle(b.scene, bias);
        const double *lo = world.lo, *hi = world.hi;
        const auto& surface = world.surface;
        double size = world.size();
        std::mt19937 rng(11);
        std::uniform_real_distribution<double> u(0, 1);
        // Lights: far outside, grazing the top of the bounds, inside the bounds, and exactly on a vertex
        // (so on the planes of every triangle around it).
        const cb::MeshRecord& m0 = v.meshes[v.instances[0].mesh];
        const float* on = v.positions + (size_t(m0.first_vertex) + m0.vertex_count / 2) * 3;
        double on_vertex[3] = {on[0], on[1], on[2]}, on_world[3];
        cb::apply_instance(v.instances[0].transform, on_vertex, on_world);
        double lights[4][3] = {
            {lo[0] - 2 * size, hi[1] + 3 * size, lo[2] - size},
            {0.5 * (lo[0] + hi[0]), hi[1] + 1e-3 * size, 0.5 * (lo[2] + hi[2])},
            {lo[0] + 0.4 * (hi[0] - lo[0]), lo[1] + 0.6 * (hi[1] - lo[1]), lo[2] + 0.5 * (hi[2] - lo[2])},
            {on_world[0], on_world[1], on_world[2]}};
        size_t per_light = v.triangle_count > 20000 ? 60 : 400;
        for (const auto& light : lights)
            for (size_t k = 0; k < per_light; ++k) {
                double p[3];
                if (k % 2 == 0) {
                    const auto& s = surface[(k * 7919) % surface.size()];
                    p[0] = s[0];
                    p[1] = s[1];
                    p[2] = s[2];
                } else {
                    for (int j = 0; j < 3; ++j) p[j] = lo[j] + (hi[j] - lo[j]) * (1.2 * u(rng) - 0.1);
                }
                for (bool one_sided : {false, true}) {
                    cb::QueryStats stats;
                    bool ours = cb::occluded_reference(v, p, light, bias, one_sided, &stats);
                    cb::test::OracleAnswer exact_answer = exact_oracle.occluded(p, light, one_sided);
                    bool exact = exact_answer.blocked;
                    disagreements += ours != exact;
                    touching += exact_answer.touching;
                    shadowed += exact;
                    one_sided_differs += one_sided && ours != cb::occluded_reference(v, p, light, bias, false);
                    ++queries;
                }
            }
    }
    std::printf(
        "%zu queries (two-sided and one-sided), %zu in shadow, %zu touching (per the oracle), %zu disagreements; "
        "one-sided answer differs from two-sided for %zu\n",
        queries, shadowed, touching, disagreements, one_sided_differs);
    EXPECT_GT(one_sided_differs, 0u);  // the mode is really exercised
    EXPECT_EQ(disagreements, 0u);
    EXPECT_GT(shadowed, queries / 10);
    EXPECT_LT(shadowed, queries * 9 / 10);
}

TEST(Shadow, ShadowVolumesHoldEverythingTheirBoxCanShadow) {
    // Random boxes and lights; every point p beyond a point X of the box, on the ray from the light through
    // X, must be inside the volume. Lights inside or level with the box must give an invalid volume
    // (which means: always test the cluster).
    std::mt19937 rng(21);
    std::uniform_real_distribution<double> u(-1, 1), pos(0, 1);
    size_t valid = 0, invalid = 0, misses = 0, rejected = 0, samples = 0;
    for (int i = 0; i < 20000; ++i) {
        cb::Obb box{};
        double a[3] = {u(rng), u(rng), u(rng)}, b[3] = {u(rng), u(rng), u(rng)};
        double al = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
        for (double& x : a) x /= al;
        double ab = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        for (int k = 0; k < 3; ++k) b[k] -= ab * a[k];
        double bl = std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
        for (double& x : b) x /= bl;
        double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
        double scale = i % 3 == 0 ? 1e6 : 1;  // far from the origin too
        for (int k = 0; k < 3; ++k) {
            box.axis[0][k] = float(a[k]);
            box.axis[1][k] = float(b[k]);
            box.axis[2][k] = float(c[k]);
            box.center[k] = float(u(rng) * 10 + scale);
        }
        for (int k = 0; k < 3; ++k) box.half[k] = float(i % 7 == 0 ? 0.0 : 0.01 + 3 * pos(rng));  // flat boxes too
        double light[3];
        for (int k = 0; k < 3; ++k) light[k] = box.center[k] + u(rng) * (i % 4 == 0 ? 3.0 : 40.0);
        cb::ShadowVolume v = cb::make_shadow_volume(box, light);
        valid += v.valid;
        invalid += !v.valid;
        for (int s = 0; s < 20; ++s) {
            double x[3], p[3], t = 1 + 5 * pos(rng) * pos(rng);
            for (int k = 0; k < 3; ++k) x[k] = box.center[k];
            for (int j = 0; j < 3; ++j) {
                double r = (s < 8 ? ((s >> (j % 3)) & 1 ? 1 : -1) : u(rng)) * box.half[j];  // corners and inside
                for (int k = 0; k < 3; ++k) x[k] += r * box.axis[j][k];
            }
            for (int k = 0; k < 3; ++k) p[k] = light[k] + t * (x[k] - light[k]);
            misses += !cb::inside_shadow_volume(v, light, p);
            ++samples;
        }
        // The box's point nearest the light (where the closing distance is tight), itself and beyond.
        double nearest[3] = {box.center[0], box.center[1], box.center[2]};
        for (int j = 0; j < 3; ++j) {
            double t = 0;
            for (int k = 0; k < 3; ++k) t += (light[k] - box.center[k]) * box.axis[j][k];
            t = std::clamp(t, -double(box.half[j]), double(box.half[j]));
            for (int k = 0; k < 3; ++k) nearest[k] += t * box.axis[j][k];
        }
        for (double t : {1.0, 1.5}) {
            double p[3];
            for (int k = 0; k < 3; ++k) p[k] = light[k] + t * (nearest[k] - light[k]);
            misses += !cb::inside_shadow_volume(v, light, p);
            ++samples;
        }
        // And it does cull: the point halfway between the light and the box's nearest point is outside.
        if (v.valid) {
            double mid[3];
            for (int k = 0; k < 3; ++k)
                mid[k] = light[k] +
                    0.5 * v.near /
                        std::sqrt((box.center[0] - light[0]) * (box.center[0] - light[0]) +
                                  (box.center[1] - light[1]) * (box.center[1] - light[1]) +
                                  (box.center[2] - light[2]) * (box.center[2] - light[2])) *
                        (box.center[k] - light[k]);
            rejected += !cb::inside_shadow_volume(v, light, mid);
        }
    }
    std::printf("%zu valid volumes, %zu lights inside or level (invalid), %zu samples, %zu missed\n", valid, invalid,
                samples, misses);
    EXPECT_EQ(misses, 0u);
    EXPECT_GT(valid, 10000u);
    EXPECT_GT(invalid, 100u);
    EXPECT_EQ(rejected, valid);
}

TEST(Shadow, InstanceShadowAnswersLikeTheReference) {
    std::vector<std::string> files = {std::string(CB_SOURCE_DIR) + "/data/default_scene.glb"};
    for (const char* f : {"scanned/bunny_npm.obj", "scanned/dragon_vrip_res4.ply", "hard/tube.obj",
                          "hard/3dfier_testarea/testarea.obj", "gltf/CesiumMilkTruck/CesiumMilkTruck.gltf"})
        if (fs::exists(fs::path(CB_SHARED_DATA) / f)) files.push_back((fs::path(CB_SHARED_DATA) / f).string());
    size_t queries = 0, disagreements = 0, batch_disagreements = 0, ordered_disagreements = 0, shadowed = 0,
           skipped = 0;
    uint64_t tested_tree = 0, tested_reference = 0;
    for (const std::string& file : files) {
        SCOPED_TRACE(file);
        Baked b = bake(file);
        ASSERT_GT(b.view.mesh_count, 0u) << "bake failed";
        const cb::AssetView& v = b.view;
        const double bias = cb::test::asset_bias(v);  // the builds' default
        WorldSample world = sample_scene(b.scene, 1);
        const double *lo = world.lo, *hi = world.hi;
        const auto& surface = world.surface;
        double size = world.size();
        std::mt19937 rng(17);
        std::uniform_real_distribution<double> u(0, 1);
        const auto& sv = surface[surface.size() / 3];
        double lights[4][3] = {
            {lo[0] - size, hi[1] + 2 * size, lo[2] - 0.5 * size},
            {0.5 * (lo[0] + hi[0]), hi[1] + 1e-3 * size, 0.5 * (lo[2] + hi[2])},
            {lo[0] + 0.45 * (hi[0] - lo[0]), lo[1] + 0.55 * (hi[1] - lo[1]), lo[2] + 0.5 * (hi[2] - lo[2])},
            {sv[0], sv[1], sv[2]}};
        const std::vector<cb::ScanBounds> bounds = cb::make_scan_bounds(v);
        for (int variant = 0; variant < 40; ++variant) {  // scan, trees, one tree, mtsv, mtsv two levels
            const double* light = lights[variant % 4];
            bool one_sided = variant / 4 % 2 == 1;
            auto level = cb::Traversal(variant / 8);
            const auto build = variant % 3 ? cb::MetricBuild::heuristic : cb::MetricBuild::reference;
            std::vector<cb::InstanceShadow> trees(v.instance_count);
            size_t stack = 0;
            for (uint32_t i = 0; i < v.instance_count; ++i) {  // half the scans share the bounds, half make their own
                trees[i].build(v, i, light,
                               {.traversal = level,
                                .one_sided = one_sided,
                                .bounds = variant % 2 == 0 ? bounds.data() : nullptr,
                                .capsule_aspect = variant % 2 ? 1.0 : 2.0,
                                .metric_build = build});
                stack = std::max(stack, trees[i].stack_size());
                skipped += trees[i].skipped_clusters();
            }
            std::vector<uint32_t> scratch(stack);
            std::vector<double> points;
            std::vector<bool> references;
            for (int k = 0; k < 800; ++k) {
                double p[3];
                if (k % 2 == 0) {
                    const auto& s = surface[size_t(k * 104729) % surface.size()];
                    p[0] = s[0];
                    p[1] = s[1];
                    p[2] = s[2];
                } else {
                    for (int j = 0; j < 3; ++j) p[j] = lo[j] + (hi[j] - lo[j]) * (1.2 * u(rng) - 0.1);
                }
                cb::QueryStats a, r;
                bool tree = false;
                for (const cb::InstanceShadow& t : trees)
                    if (t.occluded(p, scratch.data(), &a)) {
                        tree = true;
                        break;
                    }
                bool reference = cb::occluded_reference(v, p, light, bias, one_sided, &r);
                disagreements += tree != reference;
                shadowed += reference;
                tested_tree += a.triangles_tested;
                tested_reference += r.triangles_tested;
                ++queries;
                points.insert(points.end(), p, p + 3);
                references.push_back(reference);
            }
            // The same points as one batch over every instance's tree.
            std::vector<uint32_t> batch_scratch(cb::batch_scratch_size(trees.data(), trees.size(), references.size()));
            std::vector<uint8_t> batch(references.size());
            cb::occluded_batch(trees.data(), trees.size(), points.data(), batch.size(), batch.data(),
                               batch_scratch.data());
            for (size_t k = 0; k < batch.size(); ++k) batch_disagreements += bool(batch[k]) != references[k];
            // And ordered once, then answered in uneven ranges of the order, the last first (as threads would
            // take them): every range of the order gives the same answers.
            const size_t n = references.size();
            std::vector<uint32_t> order(n), order_scratch(cb::batch_order_scratch_size(n));
            cb::batch_order(light, points.data(), n, order.data(), order_scratch.data());
            std::vector<uint32_t> sorted(order);
            std::sort(sorted.begin(), sorted.end());
            for (size_t k = 0; k < n; ++k) ordered_disagreements += sorted[k] != k;  // a permutation
            // The keys made in two parts (as two threads would), then sorted: the same order.
            std::vector<uint32_t> keys(n), from_keys(n);
            cb::batch_keys(light, points.data(), 0, n / 3, keys.data());
            cb::batch_keys(light, points.data(), n / 3, n, keys.data() + n / 3);
            cb::batch_order_from_keys(keys.data(), n, from_keys.data(), order_scratch.data());
            ordered_disagreements += from_keys != order;
            std::vector<uint32_t> ordered_scratch(cb::ordered_scratch_size(trees.data(), trees.size()));
            std::vector<uint8_t> ordered(n, 2);
            for (size_t end = n; end > 0;) {
                const size_t begin = end > 101 ? end - 101 : 0;
                cb::occluded_ordered(trees.data(), trees.size(), points.data(), &order[begin], end - begin,
                                     ordered.data(), ordered_scratch.data());
                end = begin;
            }
            for (size_t k = 0; k < n; ++k) ordered_disagreements += ordered[k] != batch[k];
        }
    }
    std::printf(
        "%zu queries (fine scan, fine trees, one tree, metric trees of one and two levels; two- and one-sided), %zu "
        "in shadow, %zu disagreements; "
        "triangles tested per query: tree %.1f, "
        "reference %.1f; one-sided builds skipped %zu clusters (light in their front cone)\n",
        queries, shadowed, disagreements, double(tested_tree) / double(queries),
        double(tested_reference) / double(queries), skipped);
    EXPECT_EQ(disagreements, 0u);
    EXPECT_EQ(batch_disagreements, 0u);
    EXPECT_EQ(ordered_disagreements, 0u);
    EXPECT_GT(skipped, 0u);
    if (fs::exists(CB_SHARED_DATA))  // every listed scene was found and asked
        EXPECT_EQ(files.size(), 6u) << "a scene of ../shared/data is missing";
    else
        std::printf("../shared/data is absent: the default scene alone (the shared scenes are not asked)\n");
}

TEST(Shadow, PointsAndLightsThatAreNotFiniteAreNeverInShadow) {
    // Found by fuzz_asset: a NaN point reached the exact expansions, whose terms then grew past their
    // capacity. Such points are now lit by definition, in every path; a light that is not finite lights
    // nothing.
    Baked b = bake(std::string(CB_SOURCE_DIR) + "/data/default_scene.glb");
    ASSERT_GT(b.view.mesh_count, 0u);
    const cb::AssetView& v = b.view;
    const double bias = cb::test::asset_bias(v);  // the builds' default
    WorldSample world = sample_scene(b.scene, 1);
    const double light[3] = {world.lo[0] - world.size(), world.hi[1] + 2 * world.size(), world.lo[2]};
    std::vector<double> points;
    for (size_t k = 0; k < 200; ++k)
        points.insert(points.end(), world.surface[k * 7 % world.surface.size()].begin(),
                      world.surface[k * 7 % world.surface.size()].end());
    const double bad[4][3] = {{NAN, 0, 0}, {0, INFINITY, 0}, {-INFINITY, 1, 2}, {1e308, -1e308, NAN}};
    for (const auto& p : bad) points.insert(points.end(), p, p + 3);
    const size_t n = points.size() / 3;
    using cb::Traversal;
    for (Traversal traversal :
         {Traversal::scan, Traversal::top_two, Traversal::top_one, Traversal::mtsv_one, Traversal::mtsv_two}) {
        SCOPED_TRACE(int(traversal));
        std::vector<cb::InstanceShadow> trees(v.instance_count);
        for (uint32_t i = 0; i < v.instance_count; ++i) trees[i].build(v, i, light, {.traversal = traversal});
        std::vector<uint32_t> scratch(cb::batch_scratch_size(trees.data(), trees.size(), n));
        std::vector<uint8_t> out(n);
        cb::occluded_batch(trees.data(), trees.size(), points.data(), n, out.data(), scratch.data());
        size_t shadowed = 0;
        for (size_t k = 0; k < n; ++k) shadowed += out[k];
        EXPECT_GT(shadowed, 0u);  // the finite points are really answered
        for (size_t k = n - 4; k < n; ++k) {
            EXPECT_EQ(out[k], 0) << k;
            EXPECT_FALSE(cb::occluded_reference(v, &points[k * 3], light, bias));
            for (const cb::InstanceShadow& t : trees) EXPECT_FALSE(t.occluded(&points[k * 3], scratch.data()));
        }
        const double nan_light[3] = {0, NAN, 0};
        cb::InstanceShadow dark;
        dark.build(v, 0, nan_light, {.traversal = traversal});
        EXPECT_EQ(dark.node_count(), 0u);
        EXPECT_FALSE(dark.occluded(&points[0], scratch.data()));
        EXPECT_FALSE(cb::occluded_reference(v, &points[0], nan_light, bias));
    }
}

TEST(Shadow, ReusedBuildScratchGivesTheSameTree) {
    // Working arrays kept from builds of other instances and another light (as an engine keeps them between
    // frames) leave nothing behind: the same nodes, counts and answers as a build with fresh arrays.
    std::vector<std::string> files = {std::string(CB_SOURCE_DIR) + "/data/default_scene.glb"};
    if (fs::exists(fs::path(CB_SHARED_DATA) / "scanned/dragon_vrip_res4.ply"))
        files.push_back((fs::path(CB_SHARED_DATA) / "scanned/dragon_vrip_res4.ply").string());
    size_t compared = 0, many_trees = 0;
    for (const std::string& file : files) {
        SCOPED_TRACE(file);
        cb::ClusterOptions co;
        co.coarse_size = 256;  // many coarse clusters: many fine trees laid out
        Baked b = cb::test::bake_scene(cb::load_scene(file), co);
        ASSERT_GT(b.view.mesh_count, 0u) << "bake failed";
        const cb::AssetView& v = b.view;
        for (uint32_t i = 0; i < v.instance_count; ++i) many_trees += v.meshes[v.instances[i].mesh].coarse_count >= 24;
        WorldSample world = sample_scene(b.scene, 1);
        double size = world.size();
        std::vector<double> points;
        for (size_t k = 0; k < world.surface.size(); k += 3)
            points.insert(points.end(), world.surface[k].begin(), world.surface[k].end());
        const double light[3] = {world.lo[0] - size, world.hi[1] + 2 * size, world.lo[2] - 0.5 * size};
        for (bool one_sided : {false, true}) {
            std::vector<cb::InstanceShadow> fresh(v.instance_count), reused(v.instance_count);
            cb::BuildScratch kept;
            const double other_light[3] = {light[0] + 0.3 * size, light[1] - 2.5 * size, light[2] + 0.7 * size};
            for (uint32_t i = 0; i < v.instance_count; ++i)
                reused[i].build(v, i, other_light, {.traversal = cb::Traversal::top_two, .scratch = &kept});
            for (uint32_t i = 0; i < v.instance_count; ++i) {
                fresh[i].build(v, i, light, {.traversal = cb::Traversal::top_two, .one_sided = one_sided});
                reused[i].build(v, i, light,
                                {.traversal = cb::Traversal::top_two, .one_sided = one_sided, .scratch = &kept});
                EXPECT_EQ(fresh[i].node_count(), reused[i].node_count());
                EXPECT_EQ(fresh[i].stack_size(), reused[i].stack_size());
                EXPECT_EQ(fresh[i].always_tested(), reused[i].always_tested());
                EXPECT_EQ(fresh[i].skipped_clusters(), reused[i].skipped_clusters());
            }
            size_t n = points.size() / 3;
            std::vector<uint32_t> scratch(cb::batch_scratch_size(fresh.data(), fresh.size(), n));
            std::vector<uint8_t> a(n), c(n);
            cb::QueryStats sa, sc;
            cb::occluded_batch(fresh.data(), fresh.size(), points.data(), n, a.data(), scratch.data(), &sa);
            cb::occluded_batch(reused.data(), reused.size(), points.data(), n, c.data(), scratch.data(), &sc);
            EXPECT_EQ(a, c);
            EXPECT_EQ(sa.nodes_visited, sc.nodes_visited);  // the same nodes in the same order
            EXPECT_EQ(sa.clusters_tested, sc.clusters_tested);
            compared += n;
        }
    }
    EXPECT_GT(compared, 1000u);
    EXPECT_GT(many_trees, 0u);  // some instance has many fine trees
}

// An asset with coarse boxes but no fine ones: the coarse tree is built, and every fine cluster of an entered
// coarse cluster is tested (scan: spheres that hold everything; fine trees: every fine cluster without a
// volume). Answers as the reference's, which tests every cluster then.
TEST(Shadow, CoarseBoxesWithoutFineBoxes) {
    Baked b = cb::test::bake_scene(cb::load_scene(std::string(CB_SOURCE_DIR) + "/data/default_scene.glb"), {},
                                   cb::bounds_auto, 1,
                                   /*fine_bounds=*/false);
    ASSERT_GT(b.view.mesh_count, 0u) << "bake failed";
    const cb::AssetView& v = b.view;
    const double bias = cb::test::asset_bias(v);  // the builds' default
    ASSERT_TRUE(v.coarse_bounds.obbs != nullptr);
    ASSERT_TRUE(v.fine_bounds.obbs == nullptr);
    WorldSample world = sample_scene(b.scene, 1);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<double> points;
    for (int k = 0; k < 1500; ++k) {
        if (k % 2 == 0) {
            const auto& s = world.surface[size_t(k) * 7919 % world.surface.size()];
            points.insert(points.end(), s.begin(), s.end());
        } else {
            for (int j = 0; j < 3; ++j)
                points.push_back(world.lo[j] + (world.hi[j] - world.lo[j]) * (1.2 * u(rng) - 0.1));
        }
    }
    const size_t n = points.size() / 3;
    const double light[3] = {-4, 30, 2};
    std::vector<uint8_t> reference(n);
    size_t shadowed = 0;
    for (size_t k = 0; k < n; ++k) shadowed += reference[k] = cb::occluded_reference(v, &points[k * 3], light, bias);
    EXPECT_GT(shadowed, 50u);
    using Level = cb::Traversal;
    for (Level level : {Level::scan, Level::top_two, Level::top_one, Level::mtsv_one, Level::mtsv_two}) {
        std::vector<cb::InstanceShadow> trees(v.instance_count);
        for (uint32_t i = 0; i < v.instance_count; ++i) trees[i].build(v, i, light, {.traversal = level});
        std::vector<uint32_t> scratch(cb::batch_scratch_size(trees.data(), trees.size(), n));
        std::vector<uint8_t> batch(n);
        cb::occluded_batch(trees.data(), trees.size(), points.data(), n, batch.data(), scratch.data());
        size_t bad = 0, bad_walk = 0;
        for (size_t k = 0; k < n; ++k) {
            bool walk = false;
            for (const cb::InstanceShadow& t : trees) walk = walk || t.occluded(&points[k * 3], scratch.data());
            bad += batch[k] != reference[k];
            bad_walk += walk != bool(reference[k]);
        }
        EXPECT_EQ(bad, 0u) << "traversal " << int(level);
        EXPECT_EQ(bad_walk, 0u) << "traversal " << int(level);
    }
}

namespace {

// A scene of one mesh and one identity instance, baked in memory with small clusters.
Baked bake_mesh(std::vector<float> positions, std::vector<uint32_t> indices) {
    cb::Scene scene;
    cb::Mesh m;
    m.positions = std::move(positions);
    m.indices = std::move(indices);
    m.primitives.push_back({0, uint32_t(m.triangle_count()), false});
    scene.meshes.push_back(std::move(m));
    scene.instances.push_back({0, cb::identity_transform(), "hard"});
    cb::ClusterOptions co;
    co.fine_size = 8;
    co.coarse_size = 64;
    return cb::test::bake_scene(scene, co, cb::bounds_auto, 1);
}

// Calls visit(position) for every corner of every triangle of fine clusters [first, first + count) of mesh r.
template <class Visit>
void for_each_corner(const cb::AssetView& v, const cb::MeshRecord& r, uint32_t first, uint32_t count, Visit visit) {
    for (uint32_t f = first; f < first + count; ++f) {
        const cb::FineCluster& c = v.fine[r.first_fine + f];
        for (uint32_t t = c.first_triangle; t < c.first_triangle + c.triangle_count; ++t) {
            uint32_t id[3];
            v.triangle(r, f, t, id);
            for (uint32_t vertex : id) visit(v.position(r, vertex));
        }
    }
}

// A bumpy grid of 6 x 6 cells, dx by dy, float coordinates around (offset, offset, offset): heights
// `height` sin(wave i + j), baked as bake_mesh does.
Baked bumpy_grid(double offset, double dx, double dy, double height, double wave) {
    std::vector<float> pos;
    std::vector<uint32_t> idx;
    for (int j = 0; j <= 6; ++j)
        for (int i = 0; i <= 6; ++i)
            pos.insert(
                pos.end(),
                {float(offset + i * dx), float(offset + j * dy), float(offset + height * std::sin(i * wave + j))});
    for (uint32_t j = 0; j < 6; ++j)
        for (uint32_t i = 0; i < 6; ++i) {
            uint32_t a = j * 7 + i;
            idx.insert(idx.end(), {a, a + 1, a + 7, a + 1, a + 8, a + 7});
        }
    return bake_mesh(pos, idx);
}

}  // namespace

TEST(Shadow, SunAgreesWithExactOracle) {
    // Suns over the default scene, the hard cases (flat grids at the origin and 1e6 from it, layers 1e-12 and
    // 1e-23 apart, needles) and shared scenes when present: overhead, low, grazing a flat grid (1e-9 off its
    // plane), exactly in a triangle's plane (points on faces parallel to the sun), and along a triangle's
    // edge; points on the surfaces, in the grids' plane, and around; both modes.
    std::vector<std::pair<std::string, Baked>> scenes;
    scenes.emplace_back("default scene", bake(std::string(CB_SOURCE_DIR) + "/data/default_scene.glb"));
    for (const cb::test::HardCase& c : {cb::test::flat_grid(0), cb::test::flat_grid(1e6), cb::test::two_layers(1e-12),
                                        cb::test::two_layers(1e-23), cb::test::needles()})
        scenes.emplace_back(c.name, bake_mesh(c.positions, c.indices));
    for (const char* f : {"scanned/bunny_npm.obj", "hard/tube.obj", "hard/v405.off"})
        if (fs::exists(fs::path(CB_SHARED_DATA) / f))
            scenes.emplace_back(f, bake((fs::path(CB_SHARED_DATA) / f).string()));
        else
            std::printf("skipped %s: ../shared/data is not here\n", f);
    std::mt19937 rng(43);
    std::uniform_real_distribution<double> u(-1, 1);
    size_t queries = 0, wrong = 0, shadowed = 0, touching = 0, brute_wrong = 0, traversal_wrong = 0, skipped = 0,
           trees_built = 0;
    for (const auto& [name, b] : scenes) {
        SCOPED_TRACE(name);
        ASSERT_GT(b.view.mesh_count, 0u) << "bake failed";
        const cb::AssetView& v = b.view;
        const double bias = cb::test::asset_bias(v);
        const SceneOracle oracle(b.scene, bias);
        const WorldSample world = sample_scene(b.scene, 1);
        // A triangle of the first instance, in world space: its plane and edge give the exact suns.
        const cb::MeshRecord& m0 = v.meshes[v.instances[0].mesh];
        uint32_t id[3];
        v.triangle(m0, 0, 0, id);
        double corner[3][3];
        for (int k = 0; k < 3; ++k) {
            const double local[3] = {v.position(m0, id[k])[0], v.position(m0, id[k])[1], v.position(m0, id[k])[2]};
            cb::apply_instance(v.instances[0].transform, local, corner[k]);
        }
        double edge[3], across[3], in_plane[3];
        for (int k = 0; k < 3; ++k) {
            edge[k] = corner[1][k] - corner[0][k];
            across[k] = corner[2][k] - corner[0][k];
        }
        for (int k = 0; k < 3; ++k) in_plane[k] = edge[k] + across[k];
        const double suns[][3] = {{0.1, 1, 0.2},
                                  {0.2, 0.3, 1},
                                  {1, 1e-9, 0.4},
                                  {1, 0.4, 1e-9},
                                  {in_plane[0], in_plane[1], in_plane[2]},
                                  {edge[0], edge[1], edge[2]}};
        for (const auto& sun : suns) {
            std::vector<double> asked;       // the points, for the sun's traversal afterwards
            std::vector<uint8_t> expect[2];  // the oracle's answers, two- then one-sided
            for (int k = 0; k < 120; ++k) {
                double p[3];
                if (k % 3 == 0) {
                    const auto& s = world.surface[size_t(k) * 7919 % world.surface.size()];
                    p[0] = s[0];
                    p[1] = s[1];
                    p[2] = s[2];
                } else if (k % 3 == 1) {  // on the first triangle's plane (to rounding), in and beyond it
                    const double s = 1.5 * std::fabs(u(rng)), t = 1.5 * std::fabs(u(rng));
                    for (int j = 0; j < 3; ++j) p[j] = corner[0][j] + s * edge[j] + t * across[j];
                } else {
                    for (int j = 0; j < 3; ++j)
                        p[j] = 0.5 * (world.lo[j] + world.hi[j]) + (world.hi[j] - world.lo[j] + 1) * u(rng);
                }
                asked.insert(asked.end(), p, p + 3);
                for (bool one_sided : {false, true}) {
                    const bool ours = cb::occluded_sun_reference(v, p, sun, bias, one_sided);
                    const cb::test::OracleAnswer exact = oracle.occluded_sun(p, sun, one_sided);
                    wrong += ours != exact.blocked;
                    shadowed += exact.blocked, touching += exact.touching, ++queries;
                    expect[one_sided].push_back(exact.blocked);
                    if (k % 10 == 0)
                        brute_wrong += oracle.occluded_sun_brute_force(p, sun, one_sided).blocked != exact.blocked;
                }
            }
            // The sun's traversal (cb_sun.h) on the same points, finding clusters by each traversal: as a batch
            // over every instance, and point by point.
            for (cb::Traversal traversal : {cb::Traversal::scan, cb::Traversal::top_two, cb::Traversal::top_one,
                                            cb::Traversal::mtsv_one, cb::Traversal::mtsv_two})
                for (bool one_sided : {false, true}) {
                    cb::ShadowBuildOptions o;
                    o.one_sided = one_sided;
                    o.bias = bias;
                    o.traversal = traversal;
                    std::vector<cb::InstanceShadow> shadows(v.instance_count);
                    for (uint32_t i = 0; i < v.instance_count; ++i) {
                        shadows[i].build_sun(v, i, sun, o);
                        if (traversal == cb::Traversal::scan) skipped += shadows[i].skipped_clusters();
                        trees_built += traversal != cb::Traversal::scan && shadows[i].node_count() > 0;
                    }
                    const size_t n = expect[one_sided].size();
                    std::vector<uint32_t> scratch(cb::batch_scratch_size(shadows.data(), shadows.size(), n));
                    std::vector<uint8_t> got(n, 2);
                    cb::occluded_batch(shadows.data(), shadows.size(), asked.data(), n, got.data(), scratch.data());
                    for (size_t k = 0; k < n; ++k) {
                        const size_t before = traversal_wrong;
                        traversal_wrong += got[k] != expect[one_sided][k];
                        bool alone = false;
                        for (const cb::InstanceShadow& sh : shadows)
                            alone = alone || sh.occluded(&asked[k * 3], scratch.data());
                        traversal_wrong += alone != bool(expect[one_sided][k]);
                        if (traversal_wrong != before && traversal_wrong < 10)
                            ADD_FAILURE()
                                << "traversal " << int(traversal) << (one_sided ? " one-sided" : "") << " point " << k;
                    }
                }
        }
    }
    std::printf(
        "%zu sun queries on %zu scenes: %zu in shadow, %zu touching; %zu disagreements; one-sided, %zu fine "
        "clusters facing the sun skipped\n",
        queries, scenes.size(), shadowed, touching, wrong, skipped);
    EXPECT_EQ(wrong, 0u);
    EXPECT_EQ(brute_wrong, 0u);
    EXPECT_EQ(traversal_wrong, 0u);     // the sun's traversal by each traversal, batched and point by point
    EXPECT_GT(trees_built, 0u);         // the trees were built, not passed over
    EXPECT_GT(skipped, 0u);             // one-sided, whole clusters facing the sun were left out
    EXPECT_GT(shadowed, queries / 20);  // 9.6% on the scenes of this repository alone
    EXPECT_GT(touching, 10u);
}

TEST(Shadow, HardCasesAgreeWithTheOracle) {
    std::mt19937 rng(31);
    std::uniform_real_distribution<double> u(-1, 1);
    const std::vector<cb::test::HardCase> cases = {cb::test::flat_grid(0), cb::test::flat_grid(1e6),
                                                   cb::test::two_layers(1e-12), cb::test::two_layers(1e-23),
                                                   cb::test::needles()};

    size_t queries = 0, disagreements = 0, tree_disagreements = 0, batch_disagreements = 0, touching = 0;
    for (const cb::test::HardCase& c : cases) {
        SCOPED_TRACE(c.name);
        Baked b = bake_mesh(c.positions, c.indices);
        ASSERT_GT(b.view.mesh_count, 0u) << "bake failed";
        const cb::AssetView& v = b.view;
        const double bias = cb::test::asset_bias(v);  // the builds' default
        WorldSample world = sample_scene(b.scene, 1);
        SceneOracle exact_oracle(b.scene, bias);
        for (const auto& light : c.lights)
            for (int variant = 0; variant < 10; ++variant) {  // scan, trees, one tree, mtsv, mtsv two levels
                bool one_sided = variant % 2 == 1;
                cb::InstanceShadow tree;
                tree.build(v, 0, light.data(), {.traversal = cb::Traversal(variant / 2), .one_sided = one_sided});
                std::vector<uint32_t> stack(tree.stack_size());
                std::vector<double> points;
                std::vector<bool> exact_answers;
                for (int k = 0; k < 300; ++k) {
                    double p[3];
                    if (k % 3 == 0) {  // on the surface: a vertex
                        const auto& s = world.surface[size_t(k) % world.surface.size()];
                        p[0] = s[0];
                        p[1] = s[1];
                        p[2] = s[2];
                    } else if (k % 5 == 4) {  // beyond a point of the bounds, seen from the light: twice as far, or
                        // 1e31 times (such points walk alone: beyond float's range)
                        double scale = k % 50 == 49 ? 1e31 : 2;
                        for (int j = 0; j < 3; ++j) {
                            double target = world.lo[j] + (world.hi[j] - world.lo[j]) * (u(rng) + 1) / 2;
                            p[j] = light[j] + scale * (target - light[j]);
                        }
                    } else if (k % 3 == 1) {  // in the plane z = 0 (coplanar with the flat grid)
                        p[0] = world.lo[0] + (world.hi[0] - world.lo[0]) * (1.4 * (u(rng) + 1) / 2 - 0.2);
                        p[1] = world.lo[1] + (world.hi[1] - world.lo[1]) * (1.4 * (u(rng) + 1) / 2 - 0.2);
                        p[2] = 0;
                    } else {  // around, below and above
                        for (int j = 0; j < 3; ++j)
                            p[j] = 0.5 * (world.lo[j] + world.hi[j]) + (world.hi[j] - world.lo[j] + 2) * u(rng);
                    }
                    cb::test::OracleAnswer exact_answer = exact_oracle.occluded(p, light.data(), one_sided);
                    bool exact = exact_answer.blocked;
                    bool ref = cb::occluded_reference(v, p, light.data(), bias, one_sided);
                    bool fast = tree.occluded(p, stack.data());
                    disagreements += ref != exact;
                    tree_disagreements += fast != exact;
                    touching += exact_answer.touching;
                    ++queries;
                    points.insert(points.end(), p, p + 3);
                    exact_answers.push_back(exact);
                }
                // The same points as one batch: tiles of close directions walk the tree together.
                std::vector<uint32_t> scratch(cb::batch_scratch_size(&tree, 1, exact_answers.size()));
                std::vector<uint8_t> batch(exact_answers.size());
                cb::occluded_batch(&tree, 1, points.data(), batch.size(), batch.data(), scratch.data());
                for (size_t k = 0; k < batch.size(); ++k) batch_disagreements += bool(batch[k]) != exact_answers[k];
            }
    }
    std::printf(
        "%zu hard-case queries, %zu touching; disagreements with the oracle: reference %zu, tree %zu, tree batch %zu\n",
        queries, touching, disagreements, tree_disagreements, batch_disagreements);
    EXPECT_EQ(disagreements, 0u);
    EXPECT_EQ(tree_disagreements, 0u);
    EXPECT_EQ(batch_disagreements, 0u);
    EXPECT_GT(touching, 100u);
}

namespace {
// Triangle `triangle` of fine cluster f (mesh-local indices), its corners in double.
void triangle_corners(const cb::AssetView& v, const cb::MeshRecord& m, uint32_t f, uint32_t triangle,
                      double (&q)[3][3]) {
    uint32_t corner[3];
    v.triangle(m, f, triangle, corner);
    for (int z = 0; z < 3; ++z)
        for (int j = 0; j < 3; ++j) q[z][j] = v.position(m, corner[z])[j];
}

// visit(offset, v, m, f, trial) for `trials` fine clusters f drawn from rng, of a bumpy grid (bumpy_grid's
// parameters) at each offset.
template <class Visit>
void for_each_grid_cluster(std::initializer_list<double> offsets, double dx, double dy, double height, double wave,
                           int trials, std::mt19937& rng, Visit visit) {
    for (double offset : offsets) {
        Baked b = bumpy_grid(offset, dx, dy, height, wave);
        const cb::AssetView& v = b.view;
        ASSERT_GT(v.mesh_count, 0u);
        const cb::MeshRecord& m = v.meshes[0];
        for (int trial = 0; trial < trials; ++trial) visit(offset, v, m, uint32_t(rng() % m.fine_count), trial);
    }
}
}  // namespace

// tile_line_tests decides a tile's line tests from the 4 rays that hold its points' directions: every
// triangle it leaves out of a point's may_meet must not block that point exactly, every one it says the line
// goes through must have the three exact edge orientations of one sign, and cluster_blocks_points must give
// the same answers with and without the tile. Lights within 1e-3 of a triangle (where the tile test decides,
// as the benchmark's lights inside the horse's bounds and on a triangle's plane) and farther, at offsets up to
// 3e7; tiles of 64 points, positive mixes of the rays at least 1/100 of the way in, some tiles' rays all
// within rounding of a triangle's edge plane.
TEST(Shadow, TileLineTestsDecideLikeTheExactTest) {
    std::mt19937 rng(17);
    std::uniform_real_distribution<double> u(0, 1);
    size_t tiles = 0, decided = 0, pairs_left_out = 0, surely_blocked = 0, wrong = 0, answers = 0, blocked = 0;
    for_each_grid_cluster(
        {0.0, 1e6, 3e7}, 1, 1, 0.3, 1.7, 90, rng,
        [&](double, const cb::AssetView& v, const cb::MeshRecord& m, uint32_t f, int trial) {
            const cb::FineCluster& c = v.fine[m.first_fine + f];
            uint32_t id[3];
            v.triangle(m, f, c.first_triangle + uint32_t(rng() % c.triangle_count), id);
            double a[3], bb[3], cc[3], normal[3], light[3];
            for (int k = 0; k < 3; ++k) {
                a[k] = v.position(m, id[0])[k];
                bb[k] = v.position(m, id[1])[k];
                cc[k] = v.position(m, id[2])[k];
            }
            const double e1[3] = {bb[0] - a[0], bb[1] - a[1], bb[2] - a[2]},
                         e2[3] = {cc[0] - a[0], cc[1] - a[1], cc[2] - a[2]};
            normal[0] = e1[1] * e2[2] - e1[2] * e2[1];
            normal[1] = e1[2] * e2[0] - e1[0] * e2[2];
            normal[2] = e1[0] * e2[1] - e1[1] * e2[0];
            const double nl = std::sqrt(normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]);
            const double s = u(rng), t = u(rng) * (1 - s);
            const double lift = trial % 3 == 0
                ? 0.0
                : (trial % 3 == 1 ? 1e-3 : 0.3) * (u(rng) < 0.5 ? -1 : 1);  // on the plane, near it, off it
            for (int k = 0; k < 3; ++k) light[k] = a[k] + s * e1[k] + t * e2[k] + lift * normal[k] / nl;
            // The rays: a small square cone about a random direction, or (one trial in four) a very thin one
            // aimed at a point of the triangle's edge a-b, so that every ray lies within rounding of that
            // edge's plane through the light.
            double d[3] = {u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5}, x[3], y[3];
            const bool at_edge = trial % 4 == 3;
            if (at_edge)
                for (int k = 0; k < 3; ++k) d[k] = a[k] + s * e1[k] - light[k];
            const double dl = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            for (double& q : d) q /= dl;
            const double pick[3] = {std::fabs(d[0]) < 0.5 ? 1.0 : 0.0, std::fabs(d[0]) < 0.5 ? 0.0 : 1.0, 0.0};
            x[0] = d[1] * pick[2] - d[2] * pick[1];
            x[1] = d[2] * pick[0] - d[0] * pick[2];
            x[2] = d[0] * pick[1] - d[1] * pick[0];
            const double xl = std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
            for (double& q : x) q /= xl;
            y[0] = d[1] * x[2] - d[2] * x[1];
            y[1] = d[2] * x[0] - d[0] * x[2];
            y[2] = d[0] * x[1] - d[1] * x[0];
            const double spread = at_edge ? 1e-9 : std::pow(10.0, -4 + 3 * u(rng));
            alignas(64) float rx[4], ry[4], rz[4];
            for (int j = 0; j < 4; ++j) {
                const double sx = (j == 0 || j == 3) ? -spread : spread, sy = j < 2 ? -spread : spread;
                double r[3], rl = 0;
                for (int k = 0; k < 3; ++k) {
                    r[k] = d[k] + sx * x[k] + sy * y[k];
                    rl += r[k] * r[k];
                }
                rl = std::sqrt(rl);
                rx[j] = float(r[0] / rl);
                ry[j] = float(r[1] / rl);
                rz[j] = float(r[2] / rl);
            }
            // 64 points, each a positive mix of the float rays (each weight at least 1/100 of the largest).
            double p[64][3];
            alignas(64) float ex[64], ey[64], ez[64], vl[64], keep[64];
            double l1[64], from[64];
            const double reach = std::pow(10.0, -2 + 3 * u(rng)), bias = 1e-4 * reach * u(rng);
            for (int i = 0; i < 64; ++i) {
                double w[4], e[3] = {0, 0, 0};
                for (double& q : w) q = (0.01 + u(rng)) * reach;
                for (int j = 0; j < 4; ++j) {
                    e[0] += w[j] * rx[j];
                    e[1] += w[j] * ry[j];
                    e[2] += w[j] * rz[j];
                }
                for (int k = 0; k < 3; ++k) p[i][k] = light[k] + e[k];
                const double f0 = p[i][0] - light[0], f1 = p[i][1] - light[1], f2 = p[i][2] - light[2];
                ex[i] = float(f0);
                ey[i] = float(f1);
                ez[i] = float(f2);
                l1[i] = std::fabs(f0) + std::fabs(f1) + std::fabs(f2);
                vl[i] = float(l1[i] * 1.000001);
                from[i] = cb::shadow_from(p[i], light, bias);
                keep[i] = float(1 - from[i]);
            }
            const cb::lit::TileView tile{
                ex, ey, ez, vl, keep, l1, *std::min_element(l1, l1 + 64), *std::max_element(l1, l1 + 64), rx, ry, rz};
            const uint64_t which = ~uint64_t(0);
            for (bool one_sided : {false, true}) {
                for (uint32_t first = 0; first < c.triangle_count; first += cb::lit::capacity) {
                    const uint32_t count = std::min<uint32_t>(cb::lit::capacity, c.triangle_count - first);
                    cb::lit::Triangles lit;
                    cb::lit::light_triangles(v, m, c, first, count, light, one_sided, lit);
                    uint32_t may_meet[64], through[64];
                    uint64_t sure = 0, left = 0;
                    ++tiles;
                    if (!cb::lit::tile_line_tests(lit, tile, which, may_meet, through, &sure, &left)) continue;
                    ++decided;
                    for (int i = 0; i < 64; ++i) {
                        bool blocks = false;  // exactly, by a triangle of this group
                        // Triangle k's place in `lit` (in order, less those edge-on to the light), if kept.
                        for (uint32_t k = 0, at = 0; k < count; ++k) {
                            double q[3][3];
                            triangle_corners(v, m, f, c.first_triangle + first + k, q);
                            bool kept = at < lit.count;
                            for (int z = 0; z < 3 && kept; ++z)
                                for (int j = 0; j < 3; ++j) kept = kept && double(lit.corner[at][z][j]) == q[z][j];
                            if (!kept) {  // edge-on: it must block nothing, whatever the side
                                wrong += cb::segment_triangle(p[i], light, q[0], q[1], q[2], from[i], true).blocks;
                                continue;
                            }
                            const uint32_t t = at++;
                            const bool meets = (left >> i & 1) && (may_meet[i] >> t & 1);
                            if (!(sure >> i & 1) && !meets) {
                                ++pairs_left_out;
                                wrong += cb::segment_triangle(p[i], light, q[0], q[1], q[2], from[i], true)
                                             .blocks;  // two-sided: the strictest
                            }
                            if (meets && (through[i] >> t & 1)) {
                                const int o0 = cb::exact::orient3d(p[i], light, q[0], q[1]),
                                          o1 = cb::exact::orient3d(p[i], light, q[1], q[2]),
                                          o2 = cb::exact::orient3d(p[i], light, q[2], q[0]);
                                wrong += !(o0 != 0 && o0 == o1 && o1 == o2);
                            }
                            blocks = blocks ||
                                cb::segment_triangle(p[i], light, q[0], q[1], q[2], from[i], lit.two_sided >> t & 1)
                                    .blocks;
                        }
                        surely_blocked += sure >> i & 1;
                        wrong += (sure >> i & 1) && !blocks;  // said blocked for sure, and is not
                    }
                }
                // Whole answers, with and without the tile, against the exact test of every triangle.
                const uint64_t with = cb::cluster_blocks_points(v, m, f, p, from, which, light, one_sided, nullptr,
                                                                nullptr, nullptr, nullptr, &tile);
                const uint64_t without = cb::cluster_blocks_points(v, m, f, p, from, which, light, one_sided, nullptr);
                for (int i = 0; i < 64; ++i) {
                    bool exact = false;
                    for (uint32_t k = c.first_triangle; k < c.first_triangle + c.triangle_count && !exact; ++k) {
                        double q[3][3];
                        triangle_corners(v, m, f, k, q);
                        exact = cb::segment_triangle(p[i], light, q[0], q[1], q[2], from[i], !one_sided).blocks;
                    }
                    ++answers, blocked += exact;
                    wrong += bool(with >> i & 1) != exact || bool(without >> i & 1) != exact;
                }
            }
        });
    std::printf(
        "%zu groups, %zu decided for the whole tile (%zu point and triangle pairs left out, %zu points surely "
        "blocked), %zu answers (%zu blocked)\n",
        tiles, decided, pairs_left_out, surely_blocked, answers, blocked);
    EXPECT_EQ(wrong, 0u);
    EXPECT_GT(decided, tiles / 10);
    EXPECT_GT(surely_blocked, 0u);
    EXPECT_GT(blocked, answers / 50);
    EXPECT_LT(blocked, answers - answers / 50);
}

// tile_points_line_tests runs line_tests across a tile's points, one triangle at a time: for every point it
// takes, the same points surely blocked, the same candidates, and for those the same may_meet and through.
// Points on the cluster's triangles, at their edges and corners, and up to 1e-3 and 0.3 off them; lights on a
// triangle's plane, near it and off it, at offsets up to 3e7, biases from 0 to 1e-3 of the points' reach;
// every point, random parts of the tile and lone points. A tile whose |e|_1 leaves the float tests' range for
// some points is refused (line_tests then takes it point by point).
TEST(Shadow, TilePointsLineTestsGiveLineTestsAnswers) {
    std::mt19937 rng(41);
    std::uniform_real_distribution<double> u(0, 1);
    size_t runs = 0, refused = 0, compared = 0, candidates = 0, blocked = 0, wrong = 0;
    for_each_grid_cluster(
        {0.0, 1e6, 3e7}, 1, 1, 0.3, 1.7, 60, rng,
        [&](double, const cb::AssetView& v, const cb::MeshRecord& m, uint32_t f, int trial) {
            const cb::FineCluster& c = v.fine[m.first_fine + f];
            auto random_point_on = [&](uint32_t k, double* out) {
                double q[3][3];
                triangle_corners(v, m, f, c.first_triangle + k, q);
                double s = u(rng), t = u(rng) * (1 - s);
                if (rng() % 4 == 0) s = std::round(s), t = rng() % 2 ? 0.0 : 1 - s;  // a corner or an edge
                for (int j = 0; j < 3; ++j) out[j] = q[0][j] + s * (q[1][j] - q[0][j]) + t * (q[2][j] - q[0][j]);
            };
            double light[3], mid[3];
            random_point_on(uint32_t(rng() % c.triangle_count), mid);
            const double lift = trial % 3 == 0 ? 0.0 : trial % 3 == 1 ? 1e-3 : 0.7 + 2 * u(rng);
            for (int k = 0; k < 3; ++k) light[k] = mid[k] + lift * (u(rng) - 0.5) + (trial % 3 == 2 ? lift : 0.0);
            double p[64][3], from[64], l1[64];
            alignas(64) float ex[64], ey[64], ez[64], vl[64], keep[64];
            const double bias = 1e-3 * u(rng) * u(rng);
            for (int i = 0; i < 64; ++i) {
                random_point_on(uint32_t(rng() % c.triangle_count), p[i]);
                const double off = i % 4 == 0 ? 0.0 : i % 4 == 1 ? 1e-9 : i % 4 == 2 ? 1e-3 : 0.3;
                for (double& q : p[i]) q += off * (u(rng) - 0.5);
                const double e[3] = {p[i][0] - light[0], p[i][1] - light[1], p[i][2] - light[2]};
                ex[i] = float(e[0]);
                ey[i] = float(e[1]);
                ez[i] = float(e[2]);
                l1[i] = std::fabs(e[0]) + std::fabs(e[1]) + std::fabs(e[2]);
                vl[i] = float(l1[i] * 1.000001);
                from[i] = cb::shadow_from(p[i], light, bias * l1[i]);
                keep[i] = float(1 - from[i]);
            }
            if (trial % 10 == 9) {  // one point at the light: its |e|_1 leaves the range
                for (int k = 0; k < 3; ++k) p[5][k] = light[k];
                ex[5] = ey[5] = ez[5] = vl[5] = 0.0f;
                l1[5] = 0;
                from[5] = 0;
                keep[5] = 1;
            }
            const cb::lit::TileView tile{
                ex,      ey,      ez,     vl, keep, l1, *std::min_element(l1, l1 + 64), *std::max_element(l1, l1 + 64),
                nullptr, nullptr, nullptr};
            const uint64_t parts[3] = {~uint64_t(0), uint64_t(rng()) << 32 | rng(), uint64_t(1) << (rng() % 64)};
            for (bool one_sided : {false, true})
                for (uint32_t first = 0; first < c.triangle_count; first += cb::lit::capacity) {
                    const uint32_t count = std::min<uint32_t>(cb::lit::capacity, c.triangle_count - first);
                    cb::lit::Triangles lit;
                    cb::lit::light_triangles(v, m, c, first, count, light, one_sided, lit);
                    for (uint64_t which : parts) {
                        if (!which) continue;
                        ++runs;
                        uint32_t may_meet[64], through[64], may_meet_1[64], through_1[64];
                        uint64_t sure = 0, left = 0, left_1 = 0;
                        if (!cb::lit::tile_points_line_tests(lit, tile, which, may_meet, through, &sure, &left)) {
                            ++refused;
                            wrong += trial % 10 != 9 && cb::lit::line_test_usable(tile.l1_lo, lit.max_scale) &&
                                cb::lit::line_test_usable(tile.l1_hi, lit.max_scale) &&
                                cb::lit::plane_test_usable(tile.l1_lo, lit.plane_scale) ==
                                    cb::lit::plane_test_usable(tile.l1_hi, lit.plane_scale);  // refused needlessly
                            continue;
                        }
                        const uint64_t sure_1 =
                            cb::lit::line_tests(lit, p, from, which, light, may_meet_1, through_1, &left_1);
                        wrong += sure != sure_1 || left != left_1;
                        for (uint64_t w = left & left_1; w; w &= w - 1) {
                            const int i = __builtin_ctzll(w);
                            wrong += may_meet[i] != may_meet_1[i] || through[i] != through_1[i];
                        }
                        compared += __builtin_popcountll(which);
                        candidates += __builtin_popcountll(left);
                        blocked += __builtin_popcountll(sure);
                    }
                }
        });
    std::printf("%zu runs (%zu refused), %zu points compared: %zu candidates, %zu surely blocked\n", runs, refused,
                compared, candidates, blocked);
    EXPECT_EQ(wrong, 0u);
    EXPECT_GT(refused, 0u);
    EXPECT_LT(refused, runs / 4);
    EXPECT_GT(candidates, compared / 20);
    EXPECT_GT(blocked, compared / 50);
}

// A flat group (lit::group_plane: a floor's, a CAD face's) settles a point's segment for all its triangles
// only when no triangle of it blocks that segment exactly, and cluster_blocks_points still answers as the exact
// test. Level grids (every corner in one plane exactly) and tilted ones (corners rounded to float off their
// plane) at offsets up to 3e7; points on the triangles and within 1e-9 to 1e-3 of them on either side, a few
// far off; lights grazing the plane (1e-4 to 0.5 radians), in it, and overhead; biases from 0 to 1e-3.
TEST(Shadow, FlatGroupsSettleOnlySegmentsThatMissEveryTriangle) {
    std::mt19937 rng(29);
    std::uniform_real_distribution<double> u(0, 1);
    auto cache = std::make_unique<cb::lit::Cache>();  // (about 280 KB)
    size_t groups = 0, flat = 0, queries = 0, settled = 0, wrong = 0, blocked = 0;
    for (double offset : {0.0, 1e6, 3e7})
        for (double tilt : {0.0, 0.37}) {
            std::vector<float> pos;
            std::vector<uint32_t> idx;
            for (int j = 0; j <= 6; ++j)
                for (int i = 0; i <= 6; ++i)
                    pos.insert(pos.end(), {float(offset + i), float(offset + j), float(offset + tilt * (i + 0.5 * j))});
            for (uint32_t j = 0; j < 6; ++j)
                for (uint32_t i = 0; i < 6; ++i) {
                    const uint32_t a = j * 7 + i;
                    idx.insert(idx.end(), {a, a + 1, a + 7, a + 1, a + 8, a + 7});
                }
            const Baked b = bake_mesh(pos, idx);
            const cb::AssetView& v = b.view;
            ASSERT_GT(v.mesh_count, 0u);
            const cb::MeshRecord& m = v.meshes[0];
            for (uint32_t f = 0; f < m.fine_count; ++f)
                for (int trial = 0; trial < 12; ++trial) {
                    const cb::FineCluster& c = v.fine[m.first_fine + f];
                    double q[3][3], n[3];
                    triangle_corners(v, m, f, c.first_triangle + uint32_t(rng() % c.triangle_count), q);
                    const double e1[3] = {q[1][0] - q[0][0], q[1][1] - q[0][1], q[1][2] - q[0][2]},
                                 e2[3] = {q[2][0] - q[0][0], q[2][1] - q[0][1], q[2][2] - q[0][2]};
                    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
                    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
                    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
                    const double nl = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
                    for (double& x : n) x /= nl;
                    // The light: 20 units away along the plane, raised by an angle, or in the plane, or overhead.
                    const double along[3] = {e1[0] / std::sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]), 0, 0};
                    const double angle = trial % 4 == 0 ? 0.0
                        : trial % 4 == 3                ? 1.5
                                                        : std::pow(10.0, -4 + 3.7 * u(rng));
                    const double up = (trial % 2 ? 1 : -1) * std::sin(angle), flat_part = std::cos(angle);
                    double light[3];
                    for (int k = 0; k < 3; ++k)
                        light[k] = q[0][k] + 20 * (flat_part * (k == 0 ? along[0] : 0.0) + up * n[k]) +
                            (k == 1 ? 20 * flat_part * 0.3 : 0.0);
                    const double bias = trial % 3 == 0 ? 0.0 : std::pow(10.0, -6 + 3 * u(rng));
                    double p[64][3], from[64];
                    for (int i = 0; i < 64; ++i) {
                        const double s = u(rng), t = u(rng) * (1 - s);
                        const double lift = i % 4 == 0 ? 0.0
                            : i % 4 == 3               ? (u(rng) - 0.5) * 4
                                                       : (u(rng) < 0.5 ? -1 : 1) * std::pow(10.0, -9 + 6 * u(rng));
                        double r[3];
                        triangle_corners(v, m, f, c.first_triangle + uint32_t(rng() % c.triangle_count), q);
                        for (int k = 0; k < 3; ++k) {
                            r[k] = q[0][k] + s * (q[1][k] - q[0][k]) + t * (q[2][k] - q[0][k]) + lift * n[k];
                            p[i][k] = r[k];
                        }
                        from[i] = cb::shadow_from(p[i], light, bias);
                    }
                    uint64_t which = 0;
                    for (int i = 0; i < 64; ++i) which |= uint64_t(cb::may_block(from[i])) << i;
                    for (uint32_t first = 0; first < c.triangle_count; first += cb::lit::capacity) {
                        const uint32_t count = std::min<uint32_t>(cb::lit::capacity, c.triangle_count - first);
                        cb::lit::Triangles lit;
                        cb::lit::light_triangles(v, m, c, first, count, light, false, lit);
                        cb::lit::group_plane(lit);
                        ++groups;
                        if (!lit.flat) continue;
                        ++flat;
                        const uint64_t beside = cb::lit::beside_flat(lit, p, from, which, light);
                        for (int i = 0; i < 64; ++i) {
                            if (!(beside >> i & 1)) continue;
                            ++settled;
                            for (uint32_t k = 0; k < count; ++k) {
                                triangle_corners(v, m, f, c.first_triangle + first + k, q);
                                wrong += cb::segment_triangle(p[i], light, q[0], q[1], q[2], from[i], true).blocks;
                            }
                        }
                    }
                    for (bool one_sided : {false, true}) {
                        // Without a cache, and twice through one: the second call finds the group's plane made.
                        cache->clear();
                        uint64_t answer[3];
                        answer[0] = cb::cluster_blocks_points(v, m, f, p, from, which, light, one_sided, nullptr);
                        for (int call = 1; call < 3; ++call)
                            answer[call] = cb::cluster_blocks_points(v, m, f, p, from, which, light, one_sided, nullptr,
                                                                     nullptr, cache.get(), cache.get());
                        for (int i = 0; i < 64; ++i) {
                            if (!(which >> i & 1)) continue;
                            bool exact = false;
                            for (uint32_t k = c.first_triangle; k < c.first_triangle + c.triangle_count && !exact;
                                 ++k) {
                                triangle_corners(v, m, f, k, q);
                                exact = cb::segment_triangle(p[i], light, q[0], q[1], q[2], from[i], !one_sided).blocks;
                            }
                            ++queries, blocked += exact;
                            for (uint64_t a : answer) wrong += bool(a >> i & 1) != exact;
                        }
                    }
                }
        }
    std::printf("%zu groups, %zu flat; %zu points settled by a flat group's plane; %zu answers (%zu blocked)\n", groups,
                flat, settled, queries, blocked);
    EXPECT_EQ(wrong, 0u);
    EXPECT_GT(flat, groups / 3);
    EXPECT_GT(settled, queries / 10);
    EXPECT_GT(blocked, 0u);
}

// The sun's float line test (cb_sun_triangles.h) rules a triangle out only when the ray misses it exactly,
// and cluster_blocks_sun_points answers as ray_triangle on every triangle. Suns in random directions, grazing
// a triangle's plane (within 1e-9), along one of its edges (in its plane) and of lengths from 1e-3 to 1e3;
// points on the triangle, on rays through one of its edges or corners (edge signs of zero), near the cluster
// and far back along the ray; grids at offsets up to 3e7.
TEST(Shadow, SunSphereTestKeepsEveryRayThatMeetsTheSphere) {
    // cb::sun_sphere_points, the float lane test of the sun's scan and of a level's sun tiles: spheres from
    // 1e-3 to 10 across, their centres up to 3e8 from the coordinates' origin, points within a few 1e-8 of the
    // radius across the direction (inside and out) and of the sphere's top along it, and some well outside.
    // Every point whose ray meets the sphere (decided in double on the coordinates the floats round) must be
    // kept with the documented slack; without it, float rounding drops some, so this test can fail.
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> unit(-1, 1), pos(0, 1);
    size_t meeting = 0, dropped = 0, dropped_without_slack = 0, ruled_out = 0, far = 0, far_kept = 0;
    for (double offset : {0.0, 1e3, 1e6, 3e8})
        for (int round = 0; round < 300; ++round) {
            const double r = std::pow(10.0, -3 + 4 * pos(rng));
            const double c[3] = {offset * unit(rng) + 5 * r * unit(rng), offset * unit(rng), offset * unit(rng)};
            alignas(64) float u[64], v[64], w[64];
            bool meets[64];
            double size = std::fabs(c[0]) + std::fabs(c[1]) + std::fabs(c[2]) + r;
            for (int i = 0; i < 64; ++i) {
                const bool outside = i % 8 == 7;  // well outside: across, or above the top
                const double across = outside && i % 16 == 7 ? 1.5 * r : r * (1 + 3e-8 * unit(rng));
                const double up = outside && i % 16 == 15 ? c[2] + 1.5 * r : c[2] + r * (1 + 3e-8 * unit(rng));
                const double a = 6.283185307179586 * pos(rng);
                const double q[3] = {c[0] + across * std::cos(a), c[1] + across * std::sin(a),
                                     i % 2 ? up : c[2] - 10 * r * pos(rng)};
                u[i] = float(q[0]);
                v[i] = float(q[1]);
                w[i] = float(q[2]);
                size = std::max(size, std::fabs(q[0]) + std::fabs(q[1]) + std::fabs(q[2]));
                const double du = q[0] - c[0], dv = q[1] - c[1];
                meets[i] = du * du + dv * dv <= r * r && q[2] <= c[2] + r;
            }
            const uint64_t all = ~uint64_t(0);
            const uint64_t keep = cb::sun_sphere_points(c[0], c[1], c[2], r, 1e-6 * size, all, u, v, w);
            const uint64_t bare = cb::sun_sphere_points(c[0], c[1], c[2], r, 0.0, all, u, v, w);
            for (int i = 0; i < 64; ++i) {
                meeting += meets[i];
                dropped += meets[i] && !(keep >> i & 1);
                dropped_without_slack += meets[i] && !(bare >> i & 1);
                ruled_out += !(keep >> i & 1);
                if (offset == 0 && i % 8 == 7) {  // well outside; the slack is a few 1e-6 of r
                    ++far;
                    far_kept += keep >> i & 1;
                }
            }
        }
    std::printf("%zu rays meet their sphere: %zu dropped (%zu without the slack); %zu of %zu rays ruled out\n", meeting,
                dropped, dropped_without_slack, ruled_out, size_t(4 * 300 * 64));
    EXPECT_GT(meeting, 4u * 300 * 64 / 8);
    EXPECT_EQ(dropped, 0u);
    EXPECT_GT(dropped_without_slack, 0u);  // the slack is needed
    EXPECT_GT(far, 0u);
    EXPECT_EQ(far_kept, 0u);  // and near the origin, what lies well outside is ruled out
}

TEST(Shadow, SunLineTestsDecideLikeTheExactTest) {
    // Every triangle the float tests rule out must be missed by ray_triangle, every one they find surely
    // blocking must block it; the tests across the points (sun_points_line_tests) give the point-by-point
    // answers.
    std::mt19937 rng(23);
    std::uniform_real_distribution<double> u(0, 1);
    size_t pairs = 0, ruled_out = 0, sure = 0, wrong = 0, answers = 0, blocked = 0, compared = 0;
    for_each_grid_cluster(
        {0.0, 1e6, 3e7}, 1, 1, 0.3, 1.7, 120, rng,
        [&](double, const cb::AssetView& v, const cb::MeshRecord& m, uint32_t f, int trial) {
            const cb::FineCluster& c = v.fine[m.first_fine + f];
            double q[3][3];
            triangle_corners(v, m, f, c.first_triangle + uint32_t(rng() % c.triangle_count), q);
            double e1[3], e2[3], normal[3], toward[3], frame[3][3];
            for (int k = 0; k < 3; ++k) {
                e1[k] = q[1][k] - q[0][k];
                e2[k] = q[2][k] - q[0][k];
            }
            cb::math::cross3(e1, e2, normal);
            const double nl = std::sqrt(cb::math::dot3(normal, normal)), el = std::sqrt(cb::math::dot3(e1, e1));
            for (int k = 0; k < 3; ++k) toward[k] = u(rng) - 0.5;
            if (trial % 4 == 1) {  // grazing: in the plane, tilted by 1e-9 out of it
                const double along = cb::math::dot3(toward, normal) / (nl * nl), tilt = u(rng) < 0.5 ? -1e-9 : 1e-9;
                for (int k = 0; k < 3; ++k) toward[k] += (tilt - along) * normal[k];
            } else if (trial % 4 == 2) {  // along the edge from corner 0 to corner 1, either way
                for (int k = 0; k < 3; ++k) toward[k] = (trial % 8 == 2 ? 1 : -1) * e1[k];
            } else if (trial % 4 == 3) {
                for (double& x : toward) x *= std::pow(10.0, 6 * u(rng) - 3);
            }
            if (!cb::direction_frame(toward, frame)) return;
            const double from = trial % 5 == 0 ? 0.0 : cb::sun_from(toward, 1e-4 * el * u(rng));
            const double tl = std::sqrt(cb::math::dot3(toward, toward));
            double p[64][3];
            for (int i = 0; i < 64; ++i) {
                const double s = u(rng), t = u(rng) * (1 - s), back = el * std::pow(10.0, 4 * u(rng) - 2) / tl;
                for (int k = 0; k < 3; ++k) {
                    const double on = q[0][k] + s * e1[k] + t * e2[k];
                    switch (i % 5) {
                        case 0: p[i][k] = on; break;                                      // on the triangle
                        case 1: p[i][k] = q[0][k] + s * e1[k] - back * toward[k]; break;  // its ray through an edge
                        case 2: p[i][k] = q[i % 3][k] - back * toward[k]; break;          // through a corner
                        case 3: p[i][k] = on + el * (u(rng) - 0.5) - back * toward[k]; break;
                        default: p[i][k] = on + el * (u(rng) - 0.5) - 1e4 * back * toward[k];  // far back
                    }
                }
            }
            for (bool one_sided : {false, true}) {
                for (uint32_t first = 0; first < c.triangle_count; first += cb::sun_lit::capacity) {
                    const uint32_t count = std::min<uint32_t>(cb::sun_lit::capacity, c.triangle_count - first);
                    cb::sun_lit::SunTriangles lit;
                    cb::sun_lit::sun_triangles(v, m, c, first, count, toward, frame[0], one_sided, lit);
                    const double lift[3] = {from * toward[0], from * toward[1], from * toward[2]};
                    // Across the points, for every point and for a random part of them: the same answers.
                    const uint64_t parts[2] = {~uint64_t(0), uint64_t(rng()) << 32 | rng()};
                    for (uint64_t which : parts) {
                        uint32_t across[64];
                        const uint64_t surely = cb::sun_lit::sun_points_line_tests(lit, p, which, lift, across);
                        for (int i = 0; i < 64; ++i) {
                            if (!(which >> i & 1)) continue;
                            uint32_t blocks;
                            const uint32_t kept = cb::sun_lit::sun_line_tests(lit, p[i], lift, blocks);
                            wrong += bool(surely >> i & 1) != (blocks != 0);
                            if (!blocks) wrong += across[i] != kept;
                            ++compared;
                        }
                    }
                    for (int i = 0; i < 64; ++i) {
                        uint32_t blocks;
                        const uint32_t kept = cb::sun_lit::sun_line_tests(lit, p[i], lift, blocks);
                        for (uint32_t k = 0; k < count; ++k) {
                            ++pairs;
                            const bool out = !(kept >> k & 1), in = blocks >> k & 1;
                            if (!out && !in) continue;
                            ruled_out += out;
                            sure += in;
                            double x[3][3];
                            triangle_corners(v, m, f, c.first_triangle + first + k, x);
                            wrong += (out && in) ||
                                cb::ray_triangle(p[i], toward, x[0], x[1], x[2], from, !one_sided).blocks != in;
                        }
                    }
                }
                const uint64_t ours =
                    cb::cluster_blocks_sun_points(v, m, f, p, ~uint64_t(0), toward, frame[0], from, one_sided, nullptr);
                for (int i = 0; i < 64; ++i) {
                    bool exact = false;
                    for (uint32_t k = c.first_triangle; k < c.first_triangle + c.triangle_count && !exact; ++k) {
                        double x[3][3];
                        triangle_corners(v, m, f, k, x);
                        exact = cb::ray_triangle(p[i], toward, x[0], x[1], x[2], from, !one_sided).blocks;
                    }
                    ++answers;
                    blocked += exact;
                    wrong += bool(ours >> i & 1) != exact;
                }
            }
        });
    std::printf(
        "%zu point and triangle pairs, %zu ruled out and %zu found blocking in float; %zu answers (%zu "
        "blocked); %zu points compared across\n",
        pairs, ruled_out, sure, answers, blocked, compared);
    EXPECT_EQ(wrong, 0u);
    EXPECT_GT(compared, pairs / 16);
    EXPECT_GT(ruled_out, pairs / 2);
    EXPECT_GT(sure, blocked / 4);
    EXPECT_GT(blocked, answers / 20);
    EXPECT_LT(blocked, answers - answers / 20);
}

TEST(Shadow, ClusterFilterDecidesLikeTheExactTestNearDegeneracies) {
    // cluster_blocks decides most triangles in double with error bounds; segments built to pass within
    // rounding of a triangle's plane, of its edge lines, or with the light on the plane, or to cross a
    // triangle within rounding of the self-shadowing threshold, at offsets where double evaluation alone
    // gets signs wrong, must still get segment_triangle's exact answers.
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(0, 1);
    size_t tests = 0, disagreements = 0, blocked = 0;
    for (double offset : {0.0, 1e6, 3e7}) {
        Baked b = bumpy_grid(offset, 1, 1, 0.3, 1.7);  // cells of 1 unit
        const cb::AssetView& v = b.view;
        ASSERT_GT(v.mesh_count, 0u);
        const cb::MeshRecord& m = v.meshes[0];
        for (int trial = 0; trial < 20000; ++trial) {
            uint32_t f = uint32_t(rng() % m.fine_count);
            const cb::FineCluster& c = v.fine[m.first_fine + f];
            uint32_t id[3];
            v.triangle(m, f, c.first_triangle + uint32_t(rng() % c.triangle_count), id);
            double a[3], bb[3], cc[3], p[3], light[3];
            for (int k = 0; k < 3; ++k) {
                a[k] = v.position(m, id[0])[k];
                bb[k] = v.position(m, id[1])[k];
                cc[k] = v.position(m, id[2])[k];
            }
            double s = u(rng), t = u(rng) * (1 - s),
                   far[3] = {offset + 20 * u(rng) - 7, offset + 20 * u(rng) - 7, offset + 5 + 5 * u(rng)};
            double bias = 1e-4 * (1 + u(rng));  // a world distance: cells are 1 unit
            switch (trial % 4) {
                case 0:  // p within rounding of the triangle's plane, the light above or below
                    for (int k = 0; k < 3; ++k) {
                        p[k] = a[k] + s * (bb[k] - a[k]) + t * (cc[k] - a[k]);
                        light[k] = far[k];
                    }
                    if (trial % 2) std::swap(p, light);
                    break;
                case 1:  // the light within rounding of the plane of p, a and b: the segment grazes edge a-b
                    for (int k = 0; k < 3; ++k) {
                        p[k] = far[k];
                        light[k] = a[k] + s * (bb[k] - a[k]) + 1.5 * (a[k] + s * (bb[k] - a[k]) - far[k]);
                    }
                    break;
                case 2:  // both within rounding of the triangle's plane (edge-on, nearly)
                    for (int k = 0; k < 3; ++k) {
                        p[k] = a[k] + 3 * s * (bb[k] - a[k]) - t * (cc[k] - a[k]);
                        light[k] = a[k] - 2 * t * (bb[k] - a[k]) + 4 * s * (cc[k] - a[k]);
                    }
                    break;
                default: {  // the segment crosses the triangle within rounding of where contacts start to count
                    const double f0 = 1.0 / (8192 + 3 * u(rng));
                    double d2 = 0;
                    for (int k = 0; k < 3; ++k) {
                        double x = a[k] + s * (bb[k] - a[k]) + t * (cc[k] - a[k]);
                        light[k] = far[k];
                        p[k] = (x - f0 * far[k]) / (1 - f0);
                        d2 += (far[k] - p[k]) * (far[k] - p[k]);
                    }
                    bias = f0 * std::sqrt(d2);  // from = bias / |light - p| is f0 to rounding
                }
            }
            const double from = cb::shadow_from(p, light, bias);
            if (!cb::may_block(from)) continue;
            for (bool one_sided : {false, true}) {
                bool fast = cb::cluster_blocks(v, m, f, p, from, light, one_sided, nullptr);
                bool exact = false;
                for (uint32_t tt = c.first_triangle; tt < c.first_triangle + c.triangle_count && !exact; ++tt) {
                    double x[3][3];
                    triangle_corners(v, m, f, tt, x);
                    exact = cb::segment_triangle(p, light, x[0], x[1], x[2], from, !one_sided).blocks;
                }
                ++tests;
                blocked += exact;
                disagreements += fast != exact;
            }
        }
    }
    EXPECT_EQ(disagreements, 0u) << "of " << tests;
    EXPECT_GT(blocked, tests / 20);
}

TEST(Shadow, TrianglesEdgeOnToTheLightAreLeftOutExactly) {
    // A light exactly in a triangle's plane and outside it: no segment ending at the light meets that triangle
    // where it could block, and light_triangles leaves it out. Triangles with integer corners in planes of
    // every tilt, lights placed in one triangle's plane by exact dyadic mixes of its corners (outside, on an
    // edge, at a corner, inside), points on that plane (inside and outside the triangle) and off it:
    // cluster_blocks gives segment_triangle's exact answers, and edge-on triangles (and those with no area) were
    // left out.
    std::mt19937 rng(41);
    std::uniform_int_distribution<int> coord(-20, 20);
    std::vector<float> positions;
    std::vector<uint32_t> indices;
    for (uint32_t t = 0; t < 60; ++t) {
        for (int k = 0; k < 6; ++k) positions.push_back(float(coord(rng)));
        for (int k = 0; k < 3; ++k) {  // every seventh with no area: its corners in a line, or two the same
            const float a = positions[positions.size() - 6], b = positions[positions.size() - 3];
            positions.push_back(t % 7 == 3 ? 2 * b - a : t % 7 == 5 ? b : float(coord(rng)));
        }
        indices.insert(indices.end(), {3 * t, 3 * t + 1, 3 * t + 2});
    }
    Baked b = bake_mesh(positions, indices);
    ASSERT_GT(b.view.mesh_count, 0u);
    const cb::AssetView& v = b.view;
    const cb::MeshRecord& m = v.meshes[0];
    const double mixes[][2] = {{-1, 0.5}, {2, -1}, {1.5, 1.5}, {0.5, 0}, {0, 0}, {0.25, 0.25}, {-0.5, -0.5}};
    const double spots[][2] = {{0.25, 0.5}, {0.5, 0.5}, {1, 1}, {-2, 0.5}, {0, 0.75}, {3, -1}};
    size_t tests = 0, disagreements = 0, blocked = 0, left_out = 0, kept_inside = 0;
    for (uint32_t f = 0; f < m.fine_count; ++f) {
        const cb::FineCluster& c = v.fine[m.first_fine + f];
        for (uint32_t tt = c.first_triangle; tt < c.first_triangle + c.triangle_count; ++tt) {
            double x[3][3];
            triangle_corners(v, m, f, tt, x);
            for (const auto& mix : mixes) {
                double light[3];
                for (int k = 0; k < 3; ++k)
                    light[k] = x[0][k] + mix[0] * (x[1][k] - x[0][k]) + mix[1] * (x[2][k] - x[0][k]);
                cb::lit::Triangles lit;
                const uint32_t count = std::min<uint32_t>(cb::lit::capacity, c.triangle_count);
                cb::lit::light_triangles(v, m, c, 0, count, light, false, lit);
                left_out += count - lit.count;
                const bool inside = mix[0] > 0 && mix[1] > 0 && mix[0] + mix[1] < 1;
                if (inside && tt - c.first_triangle < count)  // the triangle holding the light stays
                    for (uint32_t t = 0; t < lit.count; ++t) {
                        double y[3][3];
                        for (int k = 0; k < 3; ++k)
                            for (int j = 0; j < 3; ++j) y[k][j] = lit.corner[t][k][j];
                        kept_inside += std::equal(&y[0][0], &y[0][0] + 9, &x[0][0]);
                    }
                std::vector<std::array<double, 3>> points;
                for (const auto& spot : spots) {  // on the plane, exactly
                    std::array<double, 3> p;
                    for (int k = 0; k < 3; ++k)
                        p[k] = x[0][k] + spot[0] * (x[1][k] - x[0][k]) + spot[1] * (x[2][k] - x[0][k]);
                    points.push_back(p);
                }
                for (int i = 0; i < 6; ++i)  // off it, and on the cluster's other corners
                    points.push_back({double(coord(rng)) + 0.5, double(coord(rng)), double(coord(rng))});
                for (int i = 0; i < 3; ++i) points.push_back({x[i][0], x[i][1], x[i][2]});
                for (const auto& p : points) {
                    const double from = cb::shadow_from(p.data(), light, 1e-3);
                    if (!cb::may_block(from)) continue;
                    for (bool one_sided : {false, true}) {
                        const bool fast = cb::cluster_blocks(v, m, f, p.data(), from, light, one_sided, nullptr);
                        bool exact = false;
                        for (uint32_t u = c.first_triangle; u < c.first_triangle + c.triangle_count && !exact; ++u) {
                            double y[3][3];
                            triangle_corners(v, m, f, u, y);
                            exact = cb::segment_triangle(p.data(), light, y[0], y[1], y[2], from, !one_sided).blocks;
                        }
                        ++tests;
                        blocked += exact;
                        disagreements += fast != exact;
                    }
                }
            }
        }
    }
    std::printf("%zu edge-on segment tests, %zu blocked; %zu triangles left out, %zu holding the light kept\n", tests,
                blocked, left_out, kept_inside);
    EXPECT_EQ(disagreements, 0u) << "of " << tests;
    EXPECT_GT(blocked, tests / 10);
    EXPECT_GT(left_out, 100u);
    EXPECT_GT(kept_inside, 10u);
}

// Groups of triangles of bumpy grids at offsets up to 3e7, lit from random lights, and per triangle 4
// points: on its plane (to rounding), barely off it, and off it (error bounds are needed most near zero).
// visit(lit, t, corner, light, points) for each triangle t of each group.
template <class Visit>
void for_each_lit_plane_sample(uint32_t seed, Visit visit) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    for_each_grid_cluster({0.0, 1e3, 1e6, 3e7}, 0.7, 1.3, 0.4, 1.9, 300, rng,
                          [&](double offset, const cb::AssetView& v, const cb::MeshRecord& m, uint32_t f, int trial) {
                              const cb::FineCluster& c = v.fine[m.first_fine + f];
                              const double light[3] = {offset + 10 * u(rng) - 3, offset + 10 * u(rng) - 3,
                                                       offset + (trial % 2 ? 0.2 : 6) * u(rng)};
                              cb::lit::Triangles lit;
                              const uint32_t count = std::min<uint32_t>(cb::lit::capacity, c.triangle_count);
                              cb::lit::light_triangles(v, m, c, 0, count, light, false, lit);
                              for (uint32_t t = 0; t < lit.count; ++t) {
                                  double corner[3][3], e1[3], e2[3], n[3], points[4][3];
                                  for (int k = 0; k < 3; ++k)
                                      for (int j = 0; j < 3; ++j) corner[k][j] = lit.corner[t][k][j];
                                  for (int j = 0; j < 3; ++j) {
                                      e1[j] = corner[1][j] - corner[0][j];
                                      e2[j] = corner[2][j] - corner[0][j];
                                  }
                                  cb::math::cross3(e1, e2, n);
                                  for (int k = 0; k < 4; ++k) {
                                      const double s = u(rng), w = u(rng) * (1 - s), lift[4] = {0, 1e-12, 1e-6, 0.3};
                                      for (int j = 0; j < 3; ++j)
                                          points[k][j] = corner[0][j] + s * e1[j] + w * e2[j] + lift[k] * n[j];
                                  }
                                  visit(lit, t, corner, light, points);
                              }
                          });
}

TEST(Shadow, LitTrianglePlaneSidesStayWithinTheirBounds) {
    // The cluster test decides a segment end's side of a triangle's plane in double whenever the value clears
    // its error bound (plane_side for points, dq and bq for the light): the bound must hold the exact
    // orient3d, checked here with exact expansions, for points on, near and off the planes, at large offsets.
    size_t checked = 0, outside = 0, inexact = 0;
    auto within = [&](const double* a, const double* b, const double* c, const double* x, double value, double bound) {
        cb::exact::Expansion low = cb::exact::orient3d_exact(a, b, c, x), high = low;
        cb::exact::grow(low, -value), cb::exact::grow(low, bound);     // exact - value + bound >= 0
        cb::exact::grow(high, -value), cb::exact::grow(high, -bound);  // exact - value - bound <= 0
        cb::exact::Expansion error = cb::exact::orient3d_exact(a, b, c, x);
        cb::exact::grow(error, -value);
        inexact += cb::exact::sign(error) != 0;
        ++checked;
        outside += cb::exact::sign(low) < 0 || cb::exact::sign(high) > 0;
    };
    for_each_lit_plane_sample(11,
                              [&](const cb::lit::Triangles& lit, uint32_t t, const double(&corner)[3][3],
                                  const double* light, const double(&points)[4][3]) {
                                  cb::lit::TriangleTerms terms;
                                  cb::lit::plane_terms(lit, t, light, terms);
                                  within(corner[0], corner[1], corner[2], light, terms.dq, terms.bq);
                                  for (const double* x : points) {
                                      double bound;
                                      const double value = cb::lit::plane_side(terms, x, bound);
                                      within(corner[0], corner[1], corner[2], x, value, bound);
                                  }
                              });
    EXPECT_EQ(outside, 0u) << "of " << checked;
    EXPECT_GT(inexact, checked / 10) << "the double values were exact too often for the bound to be tested";
}

TEST(Shadow, LitTriangleFloatPlaneTestsStayWithinTheirBounds) {
    // The float line tests rule a triangle out when the segment's crossing value mix = dq - (1 - f) N . e
    // (f the point's `from`; the exact value is f orient3d(a, b, c, light) + (1 - f) orient3d(a, b, c, x))
    // clears qbound + |e|_1 pbound with dq's sign, and dq clears qbound: both bounds must hold the exact
    // values, checked here with exact expansions, for points on, near and off the planes, at large offsets,
    // with `from` tiny, a power of two or not, and near 1. The float values are computed as the lanes do.
    size_t checked = 0, outside = 0, usable = 0;
    double worst = 0;                                                            // the largest |error| / bound seen
    auto within = [&](cb::exact::Expansion exact, double value, double bound) {  // |exact - value| <= bound
        cb::exact::Expansion low = exact, high = exact;
        cb::exact::grow(low, -value), cb::exact::grow(low, bound);
        cb::exact::grow(high, -value), cb::exact::grow(high, -bound);
        ++checked;
        outside += cb::exact::sign(low) < 0 || cb::exact::sign(high) > 0;
        cb::exact::Expansion error = exact;
        cb::exact::grow(error, -value);
        double e = 0;
        for (int k = 0; k < error.n; ++k) e += error.t[k];
        worst = std::max(worst, std::fabs(e) / bound);
    };
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(0, 1);
    for_each_lit_plane_sample(
        12,
        [&](const cb::lit::Triangles& lit, uint32_t t, const double(&corner)[3][3], const double* light,
            const double(&points)[4][3]) {
            if (!(lit.qbound[t] < INFINITY)) return;
            ++usable;
            const cb::exact::Expansion q = cb::exact::orient3d_exact(corner[0], corner[1], corner[2], light);
            within(q, lit.dq[t], lit.qbound[t]);
            for (const double* x : points) {
                const double e[3] = {x[0] - light[0], x[1] - light[1], x[2] - light[2]};
                const double e_l1 = std::fabs(e[0]) + std::fabs(e[1]) + std::fabs(e[2]);
                if (!(e_l1 * lit.plane_scale < 1e30 && e_l1 * lit.plane_scale > 1e-20)) continue;  // as the lanes skip
                const float v0 = float(e[0]), v1 = float(e[1]), v2 = float(e[2]), vl = float(e_l1 * 1.000001);
                const double froms[4] = {1.0 / 8192, 1e-9 * u(rng), 0.3 * u(rng), 1 - 1e-3 * u(rng)};
                const double f = froms[checked % 4];
                // As crossing_signs: one fused multiply-add of -(1 - f) in float.
                const float mix = std::fma(-float(1 - f), v0 * lit.nx[t] + v1 * lit.ny[t] + v2 * lit.nz[t], lit.dq[t]);
                const float bound = lit.qbound[t] + vl * lit.pbound[t];
                // mix = f q + (1 - f) side = side + f (q - side), exactly
                const cb::exact::Expansion side = cb::exact::orient3d_exact(corner[0], corner[1], corner[2], x);
                cb::exact::Expansion apart = q;
                cb::exact::add(apart, cb::exact::negated(side));
                cb::exact::Expansion value = cb::exact::scaled(cb::exact::compressed(apart), f);
                cb::exact::add(value, side);
                within(value, double(mix), double(bound));
            }
        });
    std::printf("%zu values checked (%zu usable planes); largest error: %.3f of its bound\n", checked, usable, worst);
    EXPECT_EQ(outside, 0u) << "of " << checked;
    EXPECT_GT(usable, 3000u);
    EXPECT_GT(worst, 0.01) << "the float values were too close to exact for the bounds to be tested";
}

TEST(Shadow, PaddedBoxCornersHoldEveryClusterVertex) {
    // Shadow volumes and culling take a box as center + sum of +-half[i] axis[i]; the format's box is the
    // slab intersection |dot(v - center, axis[i])| <= half[i], with axes orthonormal only to float
    // precision. For the boxes of real scenes, with their half extents made as tight as that contract
    // allows (a writer may store them so), every cluster vertex must lie within the padded half extents in
    // the axes' own coordinates (solving with the inverse of the axis matrix).
    std::vector<std::string> files = {std::string(CB_SOURCE_DIR) + "/data/default_scene.glb"};
    for (const char* f : {"hard/comments.off", "hard/wallhole.obj", "scanned/bunny_npm.obj", "scanned/fandisk.obj"})
        if (fs::exists(fs::path(CB_SHARED_DATA) / f)) files.push_back((fs::path(CB_SHARED_DATA) / f).string());
    size_t checked = 0, outside = 0, beyond_tight = 0;
    for (const std::string& file : files) {
        Baked b = cb::test::bake(file);
        const cb::AssetView& v = b.view;
        ASSERT_GT(v.mesh_count, 0u) << file;
        for (uint32_t m = 0; m < v.mesh_count; ++m) {
            const cb::MeshRecord& r = v.meshes[m];
            auto check = [&](cb::Obb box, uint32_t first_fine, uint32_t fine_count) {
                std::vector<Eigen::Vector3d> offsets;
                for_each_corner(v, r, first_fine, fine_count, [&](const float* q) {
                    offsets.emplace_back(double(q[0]) - box.center[0], double(q[1]) - box.center[1],
                                         double(q[2]) - box.center[2]);
                });
                Eigen::Matrix3d axes;  // rows are the axes
                for (int i = 0; i < 3; ++i)
                    for (int k = 0; k < 3; ++k) axes(i, k) = box.axis[i][k];
                // Tightest half extents the contract allows, rounded up to float.
                for (int i = 0; i < 3; ++i) {
                    double h = 0;
                    for (const Eigen::Vector3d& d : offsets) h = std::max(h, std::fabs(axes.row(i).dot(d)));
                    box.half[i] = float(h);
                    if (double(box.half[i]) < h) box.half[i] = std::nextafter(box.half[i], INFINITY);
                }
                double padded[3];
                cb::padded_halves(box, padded);
                Eigen::Matrix3d to_coefficients = axes.inverse().transpose();  // d = sum z_i axis_i
                for (const Eigen::Vector3d& d : offsets) {
                    Eigen::Vector3d z = to_coefficients * d;
                    for (int i = 0; i < 3; ++i) {
                        outside += std::fabs(z[i]) > padded[i];
                        beyond_tight += std::fabs(z[i]) > double(box.half[i]);
                    }
                    ++checked;
                }
            };
            for (uint32_t f = 0; f < r.fine_count; ++f) check(v.fine_bounds.obb(r.first_fine + f), f, 1);
            for (uint32_t c = 0; c < r.coarse_count; ++c) {
                const cb::ClusterRange& range = v.coarse[r.first_coarse + c];
                check(v.coarse_bounds.obb(r.first_coarse + c), range.first, range.count);
            }
        }
    }
    std::printf(
        "%zu cluster vertices checked against their boxes' padded corners; %zu coefficients beyond the "
        "unpadded half extents\n",
        checked, beyond_tight);
    EXPECT_GT(checked, 100000u);
    EXPECT_GT(beyond_tight, 0u);  // the padding is needed
    EXPECT_EQ(outside, 0u);
}

TEST(Shadow, ScanBoundsHoldTheirClusters) {
    // The scan's spheres are stored in float from an origin in the mesh: each must still hold every vertex
    // of its cluster, far from the frame's origin (1e6) and at tiny scales (1e-23) as well. Its decoded boxes
    // must be the asset's, bit for bit.
    std::vector<Baked> scenes;
    for (const char* f : {"scanned/bunny_npm.obj", "hard/wallhole.obj"})
        if (fs::exists(fs::path(CB_SHARED_DATA) / f))
            scenes.push_back(cb::test::bake((fs::path(CB_SHARED_DATA) / f).string()));
    scenes.push_back(cb::test::bake(std::string(CB_SOURCE_DIR) + "/data/default_scene.glb"));
    scenes.push_back(bumpy_grid(1e6, 1.5, 1, 0.7, 0.9));
    scenes.push_back(bumpy_grid(0, 3e-23, 2e-23, 1e-23, 1.3));
    size_t checked = 0, outside = 0, boxes = 0, other_boxes = 0;
    double widest = 0;  // the largest radius over the farthest vertex's distance
    for (const Baked& b : scenes) {
        const cb::AssetView& v = b.view;
        ASSERT_GT(v.mesh_count, 0u);
        const std::vector<cb::ScanBounds> bounds = cb::make_scan_bounds(v);
        for (uint32_t m = 0; m < v.mesh_count; ++m) {
            const cb::MeshRecord& r = v.meshes[m];
            const cb::ScanBounds& s = bounds[m];
            ASSERT_TRUE(s.made_from(v, r));
            ASSERT_LT(s.extent, 1e9);
            ASSERT_EQ(s.fine_obbs.size(), r.fine_count);
            ASSERT_EQ(s.coarse_obbs.size(), r.coarse_count);
            auto same = [](const cb::Obb& a, const cb::Obb& b) { return std::memcmp(&a, &b, sizeof a) == 0; };
            for (uint32_t f = 0; f < r.fine_count; ++f, ++boxes)
                other_boxes += !same(s.fine_obbs[f], v.fine_bounds.obb(r.first_fine + f));
            for (uint32_t c = 0; c < r.coarse_count; ++c, ++boxes)
                other_boxes += !same(s.coarse_obbs[c], v.coarse_bounds.obb(r.first_coarse + c));
            auto check = [&](uint32_t sphere, uint32_t first_fine, uint32_t fine_count) {
                const double c[3] = {s.origin[0] + s.x[sphere], s.origin[1] + s.y[sphere], s.origin[2] + s.z[sphere]};
                double farthest = 0;
                for_each_corner(v, r, first_fine, fine_count, [&](const float* q) {
                    const double d = std::hypot(q[0] - c[0], q[1] - c[1], q[2] - c[2]);
                    outside += d > double(s.r[sphere]);
                    farthest = std::max(farthest, d);
                    ++checked;
                });
                if (farthest > 0) widest = std::max(widest, double(s.r[sphere]) / farthest);
            };
            for (uint32_t f = 0; f < r.fine_count; ++f) check(f, f, 1);
            for (uint32_t c = 0; c < r.coarse_count; ++c)
                check(s.coarse_first + c, v.coarse[r.first_coarse + c].first, v.coarse[r.first_coarse + c].count);
        }
    }
    std::printf(
        "%zu cluster vertices checked against their spheres; radius up to %.2f times the farthest vertex's distance; "
        "%zu decoded boxes\n",
        checked, widest, boxes);
    EXPECT_GT(checked, 100000u);
    EXPECT_EQ(outside, 0u);
    EXPECT_EQ(other_boxes, 0u);
    EXPECT_LT(widest, 3.0);  // about the box: at most its diagonal over its longest half extent, sqrt(3), and rounding
}

TEST(Shadow, SharedScanBoundsGiveTheTreesOwnAnswers) {
    // Trees given the asset's scan bounds, none (they make their own), or bounds made from another view of the
    // same scene (not theirs: ignored) answer alike; only the first share them.
    const std::string file = std::string(CB_SOURCE_DIR) + "/data/default_scene.glb";
    Baked b = cb::test::bake(file), other = cb::test::bake(file);
    const cb::AssetView& v = b.view;
    const std::vector<cb::ScanBounds> shared = cb::make_scan_bounds(v), foreign = cb::make_scan_bounds(other.view);
    WorldSample world = sample_scene(b.scene, 1);
    std::vector<double> points;
    for (size_t k = 0; k < world.surface.size(); k += 7)
        points.insert(points.end(), world.surface[k].begin(), world.surface[k].end());
    const size_t n = points.size() / 3;
    const double light[3] = {world.lo[0] - world.size(), world.hi[1] + world.size(), world.lo[2]};
    std::vector<uint8_t> answers[3];
    size_t bytes[3] = {0, 0, 0};
    const cb::ScanBounds* given[3] = {shared.data(), nullptr, foreign.data()};
    for (int k = 0; k < 3; ++k) {
        std::vector<cb::InstanceShadow> trees(v.instance_count);
        for (uint32_t i = 0; i < v.instance_count; ++i) {
            trees[i].build(v, i, light, {.traversal = cb::Traversal::scan, .bounds = given[k]});
            bytes[k] += trees[i].memory_bytes();
        }
        std::vector<uint32_t> scratch(cb::batch_scratch_size(trees.data(), trees.size(), n));
        answers[k].resize(n);
        cb::occluded_batch(trees.data(), trees.size(), points.data(), n, answers[k].data(), scratch.data());
    }
    size_t shadowed = 0;
    for (uint8_t a : answers[0]) shadowed += a;
    EXPECT_GT(n, 1000u);
    EXPECT_GT(shadowed, n / 20);
    EXPECT_EQ(answers[0], answers[1]);
    EXPECT_EQ(answers[0], answers[2]);
    EXPECT_LT(bytes[0], bytes[1]);
    EXPECT_EQ(bytes[1], bytes[2]);
}

TEST(Shadow, SegmentBoxFilterNeverMissesATouch) {
    // segment_may_touch_box may say "maybe" too often but never "misses" when the closed segment meets the
    // box {|dot(x - center, axis_i)| <= half_i} (with the stored float values, exactly). Segments are built
    // to graze faces, edges and corners, at offsets up to 1e6; the exact answer clips the segment's
    // parameter range against the three slabs in rational arithmetic.
    using FT = CGAL::Exact_predicates_exact_constructions_kernel::FT;
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1, 1);
    size_t touching = 0, missed = 0, tests = 0;
    for (int trial = 0; trial < 20000; ++trial) {
        double offset = trial % 3 == 0 ? 0 : trial % 3 == 1 ? 1e3 : 1e6;
        cb::PackedObb packed{};
        for (int k = 0; k < 3; ++k) {
            packed.center[k] = float(offset + u(rng));
            packed.half[k] = float(trial % 7 == 0 ? 0.0 : 0.01 + std::fabs(u(rng)));
            packed.rotation[k] = int16_t(u(rng) * 23000);
        }
        packed.largest = uint16_t(rng() % 4);
        cb::Obb box = cb::unpack_obb(packed);
        // A point on the box's boundary (a face, edge or corner in box coordinates), then a segment through
        // or beside it.
        double on[3], dir[3], p[3], q[3];
        double coeff[3];
        for (int i = 0; i < 3; ++i) coeff[i] = (rng() % 3 == 0 ? (rng() % 2 ? 1.0 : -1.0) : u(rng)) * box.half[i];
        int face = trial % 3;
        coeff[face] = (rng() % 2 ? 1.0 : -1.0) * box.half[face];
        for (int k = 0; k < 3; ++k) {
            on[k] = box.center[k];
            for (int i = 0; i < 3; ++i) on[k] += coeff[i] * box.axis[i][k];
            dir[k] = u(rng);
        }
        double s = 0.5 + u(rng), len = 3 * std::fabs(u(rng)) + 1e-3;
        for (int k = 0; k < 3; ++k) {
            p[k] = on[k] - s * len * dir[k];
            q[k] = on[k] + (1 - s) * len * dir[k];
        }
        if (trial % 4 == 3) {
            // Along a face, within rounding of its plane: from the face's centre (dot with the axis equal to
            // the half extent up to rounding), across the face's other axis.
            const float* a = box.axis[face];
            const float* b = box.axis[(face + 1) % 3];
            double a2 = double(a[0]) * a[0] + double(a[1]) * a[1] + double(a[2]) * a[2];
            double w[3] = {double(a[1]) * b[2] - double(a[2]) * b[1], double(a[2]) * b[0] - double(a[0]) * b[2],
                           double(a[0]) * b[1] - double(a[1]) * b[0]};
            for (int k = 0; k < 3; ++k) {
                p[k] = box.center[k] + a[k] * (coeff[face] / a2);
                q[k] = p[k] + len * w[k];
            }
        }
        // Exact clipping of the whole segment, and of its part from `from` on (where a contact can block: the
        // filter clipped at blocking_start(from) must keep those).
        for (double from : {0.0, 1.0 / 8192, 0.0123 * (1 + u(rng))}) {
            FT t0 = from, t1 = 1;
            bool meets = true;
            for (int i = 0; i < 3 && meets; ++i) {
                FT dp = 0, dq = 0;
                for (int k = 0; k < 3; ++k) {
                    dp += (FT(p[k]) - FT(box.center[k])) * FT(box.axis[i][k]);
                    dq += (FT(q[k]) - FT(box.center[k])) * FT(box.axis[i][k]);
                }
                FT h = box.half[i], d = dq - dp;
                if (d == 0) {
                    meets = CGAL::abs(dp) <= h;
                    continue;
                }
                FT ta = (-h - dp) / d, tb = (h - dp) / d;
                if (ta > tb) std::swap(ta, tb);
                t0 = CGAL::max(t0, ta);
                t1 = CGAL::min(t1, tb);
                meets = t0 <= t1;
            }
            ++tests;
            touching += meets;
            if (meets && !cb::segment_may_touch_box(box, p, q, cb::blocking_start(from))) ++missed;
        }
    }
    std::printf("%zu segments, %zu meet their box exactly; filter said 'misses' for %zu of those\n", tests, touching,
                missed);
    EXPECT_GT(touching, tests / 10);
    EXPECT_EQ(missed, 0u);
}
