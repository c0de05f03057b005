// The metric-tree traversal (runtime/detail/cb_metric_tree.h): its cones hold their clusters, its splits hold
// every volume below them, its answers are the exact oracle's on the shared scenes and generated hard
// cases, with the fitted spheres and capsules (bake --bounds all) and with those about the boxes, and its
// trees take at most half the TOP-trees' bytes.
#include <gtest/gtest.h>

#include <cb_instance_shadow.h>
#include <detail/cb_metric_tree.h>
#include <cb_shadow.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "baked.h"
#include "hard_cases.h"
#include "scene_oracle.h"

namespace fs = std::filesystem;
using cb::test::Baked;
using cb::test::SceneOracle;
using cb::test::WorldSample;

namespace {

constexpr uint32_t all_volumes = cb::bounds_all;

Baked bake_file(const std::string& path, uint32_t bounds) {
    return cb::test::bake_scene(cb::load_scene(path), {}, bounds, 1);
}

// A scene of one mesh and one identity instance, small clusters.
Baked bake_mesh(std::vector<float> positions, std::vector<uint32_t> indices, uint32_t bounds) {
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
    return cb::test::bake_scene(scene, co, bounds, 1);
}

std::vector<std::string> scene_files() {
    std::vector<std::string> files = {std::string(CB_SOURCE_DIR) + "/data/default_scene.glb"};
    for (const char* f :
         {"scanned/bunny_npm.obj", "scanned/dragon_vrip_res4.ply", "hard/tube.obj", "hard/3dfier_testarea/testarea.obj",
          "gltf/CesiumMilkTruck/CesiumMilkTruck.gltf", "gltf/SpheresScaledInstances/spheres_scaled_instances.gltf"})
        if (fs::exists(fs::path(CB_SHARED_DATA) / f)) files.push_back((fs::path(CB_SHARED_DATA) / f).string());
    return files;
}

// Lights: far outside, grazing the top of the bounds, inside them, and on a surface point.
std::vector<std::array<double, 3>> scene_lights(const WorldSample& w) {
    const double *lo = w.lo, *hi = w.hi, size = w.size();
    const auto& s = w.surface[w.surface.size() / 3];
    return {{lo[0] - size, hi[1] + 2 * size, lo[2] - 0.5 * size},
            {0.5 * (lo[0] + hi[0]), hi[1] + 1e-3 * size, 0.5 * (lo[2] + hi[2])},
            {lo[0] + 0.45 * (hi[0] - lo[0]), lo[1] + 0.55 * (hi[1] - lo[1]), lo[2] + 0.5 * (hi[2] - lo[2])},
            {s[0], s[1], s[2]}};
}

std::vector<double> scene_points(const WorldSample& w, size_t n, std::mt19937& rng) {
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<double> points;
    for (size_t k = 0; k < n; ++k) {
        if (k % 2 == 0) {
            const auto& s = w.surface[(k * 104729) % w.surface.size()];
            points.insert(points.end(), s.begin(), s.end());
        } else {
            for (int j = 0; j < 3; ++j) points.push_back(w.lo[j] + (w.hi[j] - w.lo[j]) * (1.2 * u(rng) - 0.1));
        }
    }
    return points;
}

struct Variant {
    cb::Traversal traversal;
    cb::MetricBuild build;
    double capsule_aspect;
};

const Variant variants[] = {
    {cb::Traversal::mtsv_one, cb::MetricBuild::heuristic, 2.0},
    {cb::Traversal::mtsv_one, cb::MetricBuild::reference, 2.0},
    {cb::Traversal::mtsv_one, cb::MetricBuild::heuristic, 1.0},
    {cb::Traversal::mtsv_one, cb::MetricBuild::heuristic, INFINITY},
    {cb::Traversal::mtsv_two, cb::MetricBuild::heuristic, 2.0},
    {cb::Traversal::mtsv_two, cb::MetricBuild::reference, 1.0},
};

// Counts disagreements of every variant's batch and per-point walk with the exact answers, for one light.
struct Tally {
    size_t queries = 0, shadowed = 0, bad_batch = 0, bad_walk = 0, capsules = 0;
};

void check_light(const cb::AssetView& v, const double* light, const std::vector<double>& points,
                 const std::vector<uint8_t>& exact, bool one_sided, Tally& t) {
    const size_t n = exact.size();
    const double bias = cb::test::asset_bias(v);
    for (const Variant& variant : variants) {
        std::vector<cb::InstanceShadow> trees(v.instance_count);
        for (uint32_t i = 0; i < v.instance_count; ++i) {
            trees[i].build(v, i, light,
                           {.traversal = variant.traversal,
                            .one_sided = one_sided,
                            .bias = bias,
                            .capsule_aspect = variant.capsule_aspect,
                            .metric_build = variant.build});
        }
        std::vector<uint32_t> scratch(cb::batch_scratch_size(trees.data(), trees.size(), n));
        std::vector<uint8_t> batch(n);
        cb::occluded_batch(trees.data(), trees.size(), points.data(), n, batch.data(), scratch.data());
        for (size_t k = 0; k < n; ++k) {
            bool walk = false;
            for (const cb::InstanceShadow& tree : trees) walk = walk || tree.occluded(&points[k * 3], scratch.data());
            t.bad_batch += batch[k] != exact[k];
            t.bad_walk += walk != bool(exact[k]);
            t.shadowed += exact[k];
            ++t.queries;
        }
    }
}

// The directions from the light of every vertex of a node's cluster lie in its cone, and the cluster no
// nearer the light than its `near`.
template <class Visit>
void for_each_vertex(const cb::AssetView& v, const cb::MeshRecord& m, uint32_t f, Visit visit) {
    const cb::FineCluster& c = v.fine[m.first_fine + f];
    for (uint32_t t = c.first_triangle; t < c.first_triangle + c.triangle_count; ++t) {
        uint32_t id[3];
        v.triangle(m, f, t, id);
        for (uint32_t vertex : id) {
            const float* p = v.position(m, vertex);
            const double q[3] = {p[0], p[1], p[2]};
            visit(q);
        }
    }
}

}  // namespace

TEST(MetricTree, AnswersAreTheExactOraclesOnSharedScenes) {
    Tally all;
    size_t scenes = 0;
    for (const std::string& file : scene_files()) {
        SCOPED_TRACE(file);
        for (uint32_t bounds : {all_volumes, cb::bounds_auto}) {  // fitted spheres and capsules; about the boxes
            Baked b = bake_file(file, bounds);
            ASSERT_GT(b.view.mesh_count, 0u) << "bake failed";
            SceneOracle oracle(b.scene, cb::test::asset_bias(b.view));
            WorldSample w = cb::test::sample_scene(b.scene, 1);
            std::mt19937 rng(23);
            const size_t n = b.view.triangle_count > 20000 ? 150 : 300;
            for (const auto& light : scene_lights(w)) {
                const std::vector<double> points = scene_points(w, n, rng);
                for (bool one_sided : {false, true}) {
                    std::vector<uint8_t> exact(n);
                    for (size_t k = 0; k < n; ++k)
                        exact[k] = oracle.occluded(&points[k * 3], light.data(), one_sided).blocked;
                    check_light(b.view, light.data(), points, exact, one_sided, all);
                }
            }
        }
        ++scenes;
    }
    std::printf(
        "%zu queries on %zu scenes (6 metric-tree variants, 2 volume sources, both modes), %zu in shadow; "
        "disagreements: batch %zu, walk %zu\n",
        all.queries, scenes, all.shadowed, all.bad_batch, all.bad_walk);
    EXPECT_EQ(all.bad_batch, 0u);
    EXPECT_EQ(all.bad_walk, 0u);
    EXPECT_GT(all.shadowed, all.queries / 10);
    if (fs::exists(CB_SHARED_DATA))
        EXPECT_EQ(scenes, 7u) << "a scene of ../shared/data is missing";
    else
        std::printf("../shared/data is absent: the default scene alone (the shared scenes are not asked)\n");
}

// Flat grids (at the origin and at 1e6) with lights in their plane and inside their flat boxes, needles
// fanned about a light among them, two layers at 1e-12, a long thin ribbon (capsules) seen along its
// length: the cases where cones are widest, arcs shortest or angles smallest.
TEST(MetricTree, HardCasesAgreeWithTheOracle) {
    std::vector<cb::test::HardCase> cases = {cb::test::flat_grid(0), cb::test::flat_grid(1e6), cb::test::needles(),
                                             cb::test::two_layers(1e-12)};
    // A ribbon 200 long and 0.5 wide, wavy, with a wall behind it: its fine clusters are long capsules.
    cb::test::HardCase ribbon{"ribbon", {}, {}, {{-5, 0.2, 0.3}, {100, 0.25, 3}, {100, 0.25, 0.05}}};
    for (int i = 0; i <= 400; ++i)
        for (int j = 0; j <= 1; ++j)
            ribbon.positions.insert(ribbon.positions.end(),
                                    {float(0.5 * i), float(0.5 * j), float(0.2 * std::sin(0.3 * i))});
    for (uint32_t i = 0; i < 400; ++i) {
        uint32_t a = i * 2;
        ribbon.indices.insert(ribbon.indices.end(), {a, a + 2, a + 1, a + 1, a + 2, a + 3});
    }
    const uint32_t wall = uint32_t(ribbon.positions.size() / 3);
    ribbon.positions.insert(ribbon.positions.end(), {0, -3, -2, 200, -3, -2, 0, 3, -2, 200, 3, -2});
    ribbon.indices.insert(ribbon.indices.end(), {wall, wall + 1, wall + 2, wall + 1, wall + 3, wall + 2});
    cases.push_back(ribbon);

    Tally all;
    std::mt19937 rng(37);
    std::uniform_real_distribution<double> u(-1, 1);
    for (const cb::test::HardCase& c : cases) {
        SCOPED_TRACE(c.name);
        for (uint32_t bounds : {all_volumes, cb::bounds_auto}) {
            Baked b = bake_mesh(c.positions, c.indices, bounds);
            ASSERT_GT(b.view.mesh_count, 0u) << "bake failed";
            SceneOracle oracle(b.scene, cb::test::asset_bias(b.view));
            WorldSample w = cb::test::sample_scene(b.scene, 1);
            for (const auto& light : c.lights) {
                std::vector<double> points;
                for (int k = 0; k < 200; ++k) {
                    double p[3];
                    if (k % 3 == 0) {
                        const auto& s = w.surface[size_t(k) % w.surface.size()];
                        p[0] = s[0];
                        p[1] = s[1];
                        p[2] = s[2];
                    } else if (k % 5 == 4) {  // beyond a point of the bounds, seen from the light
                        for (int j = 0; j < 3; ++j) {
                            double target = w.lo[j] + (w.hi[j] - w.lo[j]) * (u(rng) + 1) / 2;
                            p[j] = light[j] + 2 * (target - light[j]);
                        }
                    } else {
                        for (int j = 0; j < 3; ++j) p[j] = 0.5 * (w.lo[j] + w.hi[j]) + (w.hi[j] - w.lo[j] + 2) * u(rng);
                    }
                    points.insert(points.end(), p, p + 3);
                }
                for (bool one_sided : {false, true}) {
                    std::vector<uint8_t> exact(points.size() / 3);
                    for (size_t k = 0; k < exact.size(); ++k)
                        exact[k] = oracle.occluded(&points[k * 3], light.data(), one_sided).blocked;
                    check_light(b.view, light.data(), points, exact, one_sided, all);
                }
            }
        }
    }
    std::printf("%zu hard-case queries, %zu in shadow; disagreements: batch %zu, walk %zu\n", all.queries, all.shadowed,
                all.bad_batch, all.bad_walk);
    EXPECT_EQ(all.bad_batch, 0u);
    EXPECT_EQ(all.bad_walk, 0u);
    EXPECT_GT(all.shadowed, all.queries / 20);
}

// Every fine cluster's node: each vertex's direction from the light is within its cone (the walk's
// tolerance aside) and no nearer than its `near`; and every node's split holds the vertices of every volume
// below it: near child within [near_child_min, delta], far child within (delta, far_child_max], overlap child within
// [overlap_min, overlap_max].
TEST(MetricTree, ConesAndSplitsHoldTheirClusters) {
    std::vector<std::string> files = scene_files();
    size_t vertices = 0, outside = 0, split_misses = 0, capsules = 0, nodes_checked = 0;
    for (const std::string& file : files) {
        if (file.find("Spheres") != std::string::npos || file.find("testarea") != std::string::npos) continue;
        SCOPED_TRACE(file);
        for (uint32_t bounds : {all_volumes, cb::bounds_auto}) {
            Baked b = bake_file(file, bounds);
            const cb::AssetView& v = b.view;
            WorldSample w = cb::test::sample_scene(b.scene, 1);
            for (const auto& world_light : scene_lights(w))
                for (cb::MetricBuild build : {cb::MetricBuild::heuristic, cb::MetricBuild::reference}) {
                    cb::MetricTreeTraversal tree;
                    tree.build(v, 0, world_light.data(),
                               {.traversal = cb::Traversal::mtsv_one, .capsule_aspect = 1.5, .metric_build = build});
                    capsules += tree.capsules();
                    const cb::MeshRecord& m = v.meshes[v.instances[0].mesh];
                    double inverse[12], light[3];
                    ASSERT_TRUE(cb::invert_instance(v.instances[0].transform, inverse));
                    cb::apply_instance(inverse, world_light.data(), light);
                    const std::vector<cb::metric_tree::Node>& nodes = tree.nodes();
                    // s of every vertex of node k's cluster against node p.
                    auto each_s = [&](uint32_t k, const cb::metric_tree::Node& p, auto visit) {
                        const cb::metric_tree::Central c = cb::metric_tree::central_of(p);
                        for_each_vertex(v, m, nodes[k].cluster, [&](const double* q) {
                            double e[3] = {q[0] - light[0], q[1] - light[1], q[2] - light[2]};
                            const double d = std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
                            if (!(d > 0)) return;
                            for (double& x : e) x /= d;
                            visit(cb::metric_tree::distance<false>(c, e) - double(p.alpha), d);
                        });
                    };
                    const double tol = cb::metric_tree::tolerance;
                    for (uint32_t k = 0; k < nodes.size(); ++k) {
                        each_s(k, nodes[k], [&](double s, double d) {
                            ++vertices;
                            outside += s > tol || d < nodes[k].near;
                        });
                        // The subtree under each child, and the bound it must hold.
                        for (int child = 0; child < 3; ++child) {
                            std::vector<uint32_t> todo = {nodes[k].child[child]};
                            while (!todo.empty()) {
                                const uint32_t at = todo.back();
                                todo.pop_back();
                                if (at == cb::metric_tree::none) continue;
                                ++nodes_checked;
                                each_s(at, nodes[k], [&](double s, double) {
                                    const bool held = child == 0
                                        ? s <= nodes[k].delta + tol && s >= nodes[k].near_child_min - tol
                                        : child == 1
                                        ? s > nodes[k].delta - tol && s <= nodes[k].far_child_max + tol
                                        : s >= nodes[k].overlap_min - tol && s <= nodes[k].overlap_max + tol;
                                    split_misses += !held;
                                });
                                for (uint32_t c : nodes[at].child) todo.push_back(c);
                            }
                            if (nodes_checked > 400000) break;  // enough: the dragon's subtrees are long
                        }
                    }
                }
        }
    }
    std::printf(
        "%zu vertices checked against their cones, %zu outside; %zu subtree nodes against their ancestors' "
        "splits, %zu vertices outside; %zu capsule-cones\n",
        vertices, outside, nodes_checked, split_misses, capsules);
    EXPECT_GT(vertices, 1000u);
    EXPECT_EQ(outside, 0u);
    EXPECT_EQ(split_misses, 0u);
    EXPECT_GT(capsules, 0u);
}

// The memory claim of the thesis's chapter 3, on our trees: one 72-byte node per volume against a TOP-tree's four plane
// nodes and a cluster node of 32 bytes each.
TEST(MetricTree, TakesAtMostHalfTheTopTreesBytes) {
    for (const std::string& file : scene_files()) {
        SCOPED_TRACE(file);
        Baked b = bake_file(file, cb::bounds_auto);
        WorldSample w = cb::test::sample_scene(b.scene, 1);
        const auto light = scene_lights(w)[0];
        cb::InstanceShadow metric, top;
        metric.build(b.view, 0, light.data(), {.traversal = cb::Traversal::mtsv_one});
        top.build(b.view, 0, light.data(), {.traversal = cb::Traversal::top_one});
        EXPECT_GT(metric.node_count(), 0u);
        EXPECT_LE(2 * metric.memory_bytes(), top.memory_bytes())
            << "metric " << metric.memory_bytes() << " B, TOP-tree " << top.memory_bytes() << " B";
    }
}

// The walk takes its angles from fast_angle and compares them with a tolerance of 1e-7 radians: its error
// must stay far below that, at every angle and scale (small angles, near pi, axes, huge and tiny values).
TEST(MetricTree, FastAngleStaysWithinItsBound) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-1, 1), e(-30, 30);
    double worst = 0;
    auto check = [&](double y, double x) {
        const double error = std::fabs(cb::metric_tree::fast_angle(y, x) - std::atan2(y, x));
        worst = std::max(worst, error);
    };
    for (int k = 0; k < 2000000; ++k) {
        const double scale = std::pow(10.0, e(rng));
        check(std::fabs(u(rng)) * scale, u(rng) * scale);
    }
    for (double t = 1e-12; t < M_PI; t *= 1.001) {  // along the whole range, ratios near 0, 1 and infinity
        check(std::sin(t), std::cos(t));
        check(t, 1);
        check(1, t);
        check(t, -1);
        check(1, -t);
    }
    for (double x : {0.0, 1.0, -1.0, 1e-300, -1e300}) {
        check(0, x);
        check(1, x);
        check(1e-300, x);
    }
    std::printf("fast_angle's largest error against std::atan2: %.3g radians\n", worst);
    EXPECT_LT(worst, 1e-8);
    EXPECT_LT(worst, cb::metric_tree::tolerance / 10);
}

// The cone filters take these as bounds from above: a value below the true one would drop a point from a
// cone it lies in.
TEST(MetricTree, AngleAndSineBoundsHoldFromAbove) {
    std::mt19937 rng(6);
    std::uniform_real_distribution<double> u(-1, 1);
    double below = 0, loosest = 0;
    for (int k = 0; k < 1000000; ++k) {
        double a[3] = {u(rng), u(rng), u(rng)}, b[3] = {u(rng), u(rng), u(rng)};
        if (k % 2) {  // nearby directions, as in a tile
            const double near = std::pow(10.0, -1 - 6 * std::fabs(u(rng)));
            for (int j = 0; j < 3; ++j) b[j] = a[j] + near * b[j];
        }
        const double exact = cb::metric_tree::angle(a, b), above = cb::metric_tree::angle_above(a, b);
        below = std::max(below, exact - above);
        if (exact > 1e-3 && exact < M_PI / 4)
            loosest = std::max(loosest, (above - exact) / std::max(exact * exact * exact, 1e-300));
    }
    std::printf("angle_above: at most %.3g below the angle; above it by up to %.3g of its cube\n", below, loosest);
    EXPECT_LT(below, 1e-8);    // fast_angle's error beyond 45 degrees, far inside the walk's tolerance
    EXPECT_LT(loosest, 0.45);  // (tan(a) - a) / a^3 grows from 1/3 to 0.443 at 45 degrees
    for (double a = 0; a <= M_PI / 2; a += 1e-5) {
        const double s = cb::metric_tree::sine_above(a);
        EXPECT_GE(s, std::sin(a) * (1 - 4e-16)) << a;  // the same within double rounding at small angles
        EXPECT_LE(s - std::sin(a), std::pow(a, 7) / 5040 + 1e-16) << a;
    }
}
