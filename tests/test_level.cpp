// The runtime's level (cb_level.h): instances of several assets under the caller's transforms, moved,
// removed and added between frames, answered through the hierarchy's culling with the exact oracle's
// answers, by every traversal, one- and two-sided, from many threads at once; and camera culling through
// the same hierarchy.
#include <gtest/gtest.h>

#include <cb_level.h>

#include <array>
#include <memory>
#include <cmath>
#include <random>
#include <thread>
#include <vector>

#include "baked.h"
#include "city.h"
#include "scene_oracle.h"

namespace {

using cb::test::SceneOracle;
using Points = std::vector<std::array<double, 3>>;

constexpr cb::Traversal all_traversals[] = {cb::Traversal::scan, cb::Traversal::top_two, cb::Traversal::top_one,
                                            cb::Traversal::mtsv_one, cb::Traversal::mtsv_two};

// The loaded scene the exact oracle reads for the level's live instances: the baked meshes (the asset
// stores them in the same frames) under each instance's transform. `assets` holds the scene each asset
// was baked from, in the level's asset order.
cb::Scene oracle_scene(const cb::Level& level, const std::vector<const cb::Scene*>& assets) {
    cb::Scene out;
    std::vector<uint32_t> first(assets.size());
    for (size_t a = 0; a < assets.size(); ++a) {
        first[a] = uint32_t(out.meshes.size());
        out.meshes.insert(out.meshes.end(), assets[a]->meshes.begin(), assets[a]->meshes.end());
    }
    for (uint32_t h = 0; h < level.handle_limit(); ++h) {
        if (!level.alive(h)) continue;
        cb::Instance inst;
        inst.mesh = first[level.asset_of(h)] + level.mesh_of(h);
        const double* m = level.transform_of(h);
        for (int col = 0; col < 4; ++col)
            for (int row = 0; row < 3; ++row) inst.world[size_t(col) * 4 + row] = m[col * 3 + row];
        inst.world[3] = inst.world[7] = inst.world[11] = 0;
        inst.world[15] = 1;
        out.instances.push_back(inst);
    }
    return out;
}

// Points on the surfaces (vertices of the instances, then random points on the ground and just above
// it), as a camera's visible points would be.
Points level_points(const cb::Scene& world, size_t extra, uint64_t seed) {
    cb::test::WorldSample s = cb::test::sample_scene(world, 3);
    Points p(s.surface.begin(), s.surface.end());
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    for (size_t i = 0; i < extra; ++i)
        p.push_back({s.lo[0] + (s.hi[0] - s.lo[0]) * u(rng), s.lo[1] + (s.hi[1] - s.lo[1]) * u(rng),
                     i % 3 == 0 ? 0.0 : (s.hi[2] - s.lo[2]) * u(rng) * 0.5});
    return p;
}

std::vector<uint8_t> answer(cb::Level& level, const double* light, const Points& p, cb::Traversal traversal,
                            bool one_sided, cb::QueryStats* stats = nullptr) {
    cb::LevelShadow shadow;
    cb::ShadowBuildOptions o;
    o.traversal = traversal;
    o.one_sided = one_sided;
    std::vector<uint8_t> out(p.size(), 2);
    shadow.occluded_batch(level, light, p[0].data(), p.size(), out.data(), o, stats);
    return out;
}

// The level's answers for a sun in direction `toward`.
std::vector<uint8_t> answer_sun(cb::Level& level, const double* toward, const Points& p, bool one_sided,
                                cb::QueryStats* stats = nullptr, cb::Traversal traversal = cb::Traversal::scan) {
    cb::LevelShadow shadow;
    cb::ShadowBuildOptions o;
    o.one_sided = one_sided;
    o.traversal = traversal;
    std::vector<uint8_t> out(p.size(), 2);
    shadow.occluded_sun_batch(level, toward, p[0].data(), p.size(), out.data(), o, stats);
    return out;
}

// Counts the points whose answer differs from the exact oracle's (for the sun in direction `light` with `sun`).
size_t disagreements(const SceneOracle& oracle, const double* light, const Points& p, const std::vector<uint8_t>& got,
                     bool one_sided, size_t* shadowed = nullptr, bool sun = false) {
    size_t wrong = 0, dark = 0;
    for (size_t i = 0; i < p.size(); ++i) {
        const bool expect =
            (sun ? oracle.occluded_sun(p[i].data(), light, one_sided) : oracle.occluded(p[i].data(), light, one_sided))
                .blocked;
        wrong += got[i] != uint8_t(expect);
        dark += expect;
    }
    if (shadowed) *shadowed = dark;
    return wrong;
}

// A generated city of `buildings`, baked, in a level of its instances as baked. Held by pointer: the level
// reads the baked bytes in place.
struct CityLevel {
    cb::Scene city;
    cb::test::Baked baked;
    cb::Level level;
};
std::unique_ptr<CityLevel> city_level(uint32_t buildings, uint64_t seed) {
    auto c = std::make_unique<CityLevel>();
    c->city = cb::generate::city(buildings, seed);
    c->baked = cb::test::bake_scene(c->city);
    c->level.add_baked(c->level.add_asset(c->baked.view));
    c->level.commit();
    return c;
}

// Every traversal's answers for `light`, one- and two-sided, equal to the exact oracle's; the scan's two-sided
// ones shadow more than one point in `some` (shadows to get wrong).
void expect_exact(cb::Level& level, const SceneOracle& oracle, const double* light, const Points& p, size_t some) {
    for (bool one_sided : {false, true}) {
        for (cb::Traversal t : all_traversals) {
            size_t dark = 0;
            const size_t wrong =
                disagreements(oracle, light, p, answer(level, light, p, t, one_sided), one_sided, &dark);
            EXPECT_EQ(wrong, 0u) << "light " << light[0] << "," << light[1] << "," << light[2] << " traversal "
                                 << int(t) << (one_sided ? " one-sided" : "");
            if (t == cb::Traversal::scan && !one_sided) EXPECT_GT(dark, p.size() / some);
        }
    }
}

TEST(Level, CityAnswersEqualTheExactOracle) {
    const std::unique_ptr<CityLevel> c = city_level(60, 3);
    const cb::Scene& city = c->city;
    const cb::test::Baked& baked = c->baked;
    cb::Level& level = c->level;
    ASSERT_GT(baked.view.mesh_count, 0u);
    EXPECT_EQ(level.instance_count(), city.instances.size());
    const SceneOracle oracle(city, level.shadow_bias());
    const Points p = level_points(city, 3000, 5);
    const double lights[][3] = {
        {40, 30, 120}, {-500, 20, 30}, {3, -4, 12}, {2000, 1500, 1}};  // overhead, low, inside, grazing
    for (const auto& light : lights) expect_exact(level, oracle, light, p, 50);
}

// A level of at most 24 instances is not culled per tile for a point light: every tile lists every instance,
// and the spheres' and world boxes' float tests alone pick the points that enter each. A city of 6 buildings
// (one mirrored) and its ground, every traversal, one- and two-sided, against the exact oracle; cities of 23
// buildings (every instance listed) and of 24 (culled), for the count of instances met.
TEST(Level, FewInstancesUnculledAnswerAsTheExactOracle) {
    const std::unique_ptr<CityLevel> c = city_level(6, 4);
    cb::Level& level = c->level;
    ASSERT_EQ(level.instance_count(), 7u);
    const SceneOracle oracle(c->city, level.shadow_bias());
    const Points p = level_points(c->city, 2000, 9);
    const double lights[][3] = {{10, 8, 90}, {-300, 10, 20}, {3, -4, 12}, {900, 700, 1}};
    for (const auto& light : lights) {
        expect_exact(level, oracle, light, p, 100);
        cb::LevelShadow shadow;
        std::vector<uint8_t> out(p.size());
        shadow.occluded_batch(level, light, p[0].data(), p.size(), out.data());
        EXPECT_EQ(shadow.instances_met(), shadow.tile_count() * 7);  // every tile lists all of them
    }
    const double light[3] = {10, 8, 90};
    for (uint32_t buildings : {23u, 24u}) {  // 24 instances: listed; 25: culled
        const std::unique_ptr<CityLevel> more = city_level(buildings, 4);
        cb::LevelShadow shadow;
        const Points q = level_points(more->city, 2000, 9);
        std::vector<uint8_t> out(q.size());
        shadow.occluded_batch(more->level, light, q[0].data(), q.size(), out.data());
        if (buildings == 23)
            EXPECT_EQ(shadow.instances_met(), shadow.tile_count() * 24);
        else
            EXPECT_LT(shadow.instances_met(), shadow.tile_count() * 25);
    }
}

TEST(Level, SunAnswersEqualTheExactOracle) {
    // Suns over the city: overhead, low, grazing the ground (1e-9 off its plane), exactly along the ground,
    // straight down the walls, and along a diagonal of the grid; points on the surfaces, on the ground and
    // above it; both modes; the scan against the oracle, every tree against the scan.
    const std::unique_ptr<CityLevel> c = city_level(60, 3);
    cb::Level& level = c->level;
    const SceneOracle oracle(c->city, level.shadow_bias());
    const Points p = level_points(c->city, 3000, 7);
    const double suns[][3] = {{0.3, 0.2, 1}, {-1, 0.05, 0.12}, {1, 0.7, 1e-9}, {1, 0.3, 0}, {0, 0, 1}, {1, 1, 0.5}};
    for (const auto& sun : suns) {
        for (bool one_sided : {false, true}) {
            size_t dark = 0;
            const std::vector<uint8_t> got = answer_sun(level, sun, p, one_sided);
            EXPECT_EQ(disagreements(oracle, sun, p, got, one_sided, &dark, true), 0u)
                << "sun " << sun[0] << "," << sun[1] << "," << sun[2] << (one_sided ? " one-sided" : "");
            for (cb::Traversal t :
                 {cb::Traversal::top_two, cb::Traversal::top_one, cb::Traversal::mtsv_one, cb::Traversal::mtsv_two})
                EXPECT_EQ(answer_sun(level, sun, p, one_sided, nullptr, t), got)
                    << "traversal " << int(t) << " sun " << sun[0] << "," << sun[1] << "," << sun[2]
                    << (one_sided ? " one-sided" : "");
            if (!one_sided && sun[2] > 0.1) {
                EXPECT_GT(dark, p.size() / 50);  // shadows to get wrong
            }
        }
    }
}

TEST(Level, MovedRemovedAndAddedInstancesOfTwoAssets) {
    // Two assets: the city, and a second one of three towers; instances moved to mirrored and sheared
    // transforms, some removed, some added, over three frames, each checked against the oracle of the
    // level as it then stands.
    const cb::Scene city = cb::generate::city(24, 7);
    cb::Scene towers;
    for (int i = 0; i < 3; ++i) {
        towers.meshes.push_back(cb::generate::tower("t", 4 + i, 5, 12 + 6 * i, 3 + i));
        cb::Transform m = cb::identity_transform();
        m[12] = 10.0 * i;
        towers.instances.push_back({uint32_t(i), m, "t"});
    }
    cb::test::Baked a = cb::test::bake_scene(city), b = cb::test::bake_scene(towers);
    cb::Level level;
    const uint32_t ca = level.add_asset(a.view), cb_ = level.add_asset(b.view);
    std::vector<uint32_t> city_handles(a.view.instance_count);
    level.add_baked(ca, nullptr, city_handles.data());
    const double lift[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1, 15, -20, 0};
    level.add_baked(cb_, lift);
    level.commit();
    std::mt19937_64 rng(9);
    std::uniform_real_distribution<double> u(-1, 1);
    const double light[3] = {60, 80, 90};
    for (int frame = 0; frame < 3; ++frame) {
        const cb::Scene world = oracle_scene(level, {&city, &towers});
        const SceneOracle oracle(world, level.shadow_bias());
        const Points p = level_points(world, 1500, 11 + frame);
        for (cb::Traversal t : {cb::Traversal::scan, cb::Traversal::top_two, cb::Traversal::mtsv_two})
            for (bool one_sided : {false, true})
                EXPECT_EQ(disagreements(oracle, light, p, answer(level, light, p, t, one_sided), one_sided), 0u)
                    << "frame " << frame << " traversal " << int(t) << (one_sided ? " one-sided" : "");
        const double sun[3] = {0.4, -0.3, 1};
        for (bool one_sided : {false, true})
            EXPECT_EQ(disagreements(oracle, sun, p, answer_sun(level, sun, p, one_sided), one_sided, nullptr, true), 0u)
                << "frame " << frame << " sun" << (one_sided ? " one-sided" : "");
        // Next frame: move 8 buildings (sheared or mirrored), remove 2, add 2 towers.
        for (int k = 0; k < 8; ++k) {
            const uint32_t h = city_handles[1 + (frame * 8 + k) % 24];
            if (!level.alive(h)) continue;
            double m[12];
            std::copy(level.transform_of(h), level.transform_of(h) + 12, m);
            m[9] += 7 * u(rng);
            m[10] += 7 * u(rng);
            if (k % 2) m[3] += 0.3 * u(rng);  // shear: y axis leans along x
            if (k % 3 == 0)
                for (int j = 0; j < 3; ++j) m[j] = -m[j];  // mirrored
            EXPECT_TRUE(level.move(h, m));
        }
        EXPECT_TRUE(level.remove(city_handles[2 + frame * 3]));
        EXPECT_FALSE(level.remove(city_handles[2 + frame * 3]));  // gone already
        EXPECT_TRUE(level.alive(city_handles[1]) || frame > 0);
        const double at[12] = {0, 1, 0, -1, 0, 0, 0, 0, 1, 40 - 30.0 * frame, 40, 0};
        EXPECT_NE(level.add_instance(cb_, uint32_t(frame % 3), at), cb::Level::none);
        level.commit();
    }
    EXPECT_EQ(level.add_instance(cb_, 99, lift), cb::Level::none);  // no such mesh
    EXPECT_EQ(level.add_instance(7, 0, lift), cb::Level::none);     // no such asset
}

TEST(Level, MovesAndRemovalsAloneRefitTheHierarchyAsARebuildWould) {
    // Frames of moves and removals only (a refit, no rebuild): buildings thrown beyond the city's edge, some
    // moved twice in a frame. Every box up the hierarchy must hold its instances again, and every tile's
    // pyramid the buildings its points reach, or tiles would pass them by: answers against the oracle, and
    // the root box against a level built afresh from the same placements.
    std::unique_ptr<CityLevel> c = city_level(200, 13);
    cb::Level& level = c->level;
    std::mt19937_64 rng(21);
    std::uniform_real_distribution<double> u(-1, 1);
    const double light[3] = {40, 90, 70};
    for (int frame = 0; frame < 3; ++frame) {
        for (int k = 0; k < 40; ++k) {
            const uint32_t h = uint32_t(rng() % level.handle_limit());
            if (!level.alive(h)) continue;
            double m[12];
            std::copy(level.transform_of(h), level.transform_of(h) + 12, m);
            const double reach = k % 4 == 0 ? 150 : 5;  // a quarter thrown beyond the city's edge
            m[9] += reach * u(rng);
            m[10] += reach * u(rng);
            EXPECT_TRUE(level.move(h, m));
        }
        EXPECT_TRUE(level.remove(uint32_t(1 + frame)));
        level.commit();
        const cb::Scene world = oracle_scene(level, {&c->city});
        const SceneOracle oracle(world, level.shadow_bias());
        const Points p = level_points(world, 800, 31 + frame);
        for (cb::Traversal t : {cb::Traversal::scan, cb::Traversal::top_two})
            EXPECT_EQ(disagreements(oracle, light, p, answer(level, light, p, t, false), false), 0u)
                << "frame " << frame << " traversal " << int(t);
        cb::Level fresh;
        const uint32_t asset = fresh.add_asset(c->baked.view);
        for (uint32_t h = 0; h < level.handle_limit(); ++h)
            if (level.alive(h)) fresh.add_instance(asset, level.mesh_of(h), level.transform_of(h));
        fresh.commit();
        for (int k = 0; k < 3; ++k) {
            EXPECT_EQ(level.world_lo()[k], fresh.world_lo()[k]) << "frame " << frame;
            EXPECT_EQ(level.world_hi()[k], fresh.world_hi()[k]) << "frame " << frame;
        }
    }
}

// An instance's oriented box (orient_box) holds every corner of its mesh box under turned, scaled, mirrored,
// sheared and far transforms, is about half the volume of the world box for a box turned by 45 degrees about
// z, and falls back to the world axes for a shear so strong its axes cannot be made orthonormal in double.
TEST(Level, OrientedBoxesHoldThePlacedMeshBox) {
    cb::level_detail::Box local;
    for (int k = 0; k < 3; ++k) {
        local.lo[k] = -1.0 - k;
        local.hi[k] = 2.0 + 3 * k;
    }
    std::mt19937_64 rng(17);
    std::uniform_real_distribution<double> u(-1, 1);
    auto holds = [&](const cb::level_detail::OrientedBox& b, const double* m) {
        for (int corner = 0; corner < 8; ++corner) {
            const double q[3] = {corner & 1 ? local.hi[0] : local.lo[0], corner & 2 ? local.hi[1] : local.lo[1],
                                 corner & 4 ? local.hi[2] : local.lo[2]};
            double w[3];
            cb::apply_instance(m, q, w);
            for (int a = 0; a < 3; ++a) {
                double along = 0;
                for (int k = 0; k < 3; ++k) along += (w[k] - b.c[k]) * b.axis[a][k];
                if (!(std::fabs(along) <= b.h[a])) return false;
            }
        }
        return true;
    };
    for (int round = 0; round < 2000; ++round) {
        const double angle = 3.2 * u(rng), scale = std::exp2(8 * u(rng)), far = round % 4 == 0 ? 1e7 : 10.0;
        double m[12] = {std::cos(angle) * scale,
                        std::sin(angle) * scale,
                        0,
                        -std::sin(angle),
                        std::cos(angle),
                        0,
                        0,
                        0,
                        1,
                        far * u(rng),
                        far * u(rng),
                        far * u(rng)};
        if (round % 3 == 1) m[6] = -1.5 * m[6] + 0.7 * u(rng);  // mirrored, leaning
        if (round % 5 == 2)
            for (int k = 0; k < 9; ++k) m[k] += 0.4 * u(rng);  // any linear part
        const cb::level_detail::OrientedBox b = cb::level_detail::orient_box(local, m);
        ASSERT_FALSE(b.empty()) << round;
        EXPECT_TRUE(holds(b, m)) << round;
    }
    const double s = std::sqrt(0.5);
    const double turned[12] = {s, s, 0, -s, s, 0, 0, 0, 1, 5, 5, 5};
    const cb::level_detail::OrientedBox b = cb::level_detail::orient_box(local, turned);
    const cb::level_detail::Box world = cb::level_detail::transform_box(local, turned);
    double volume = 1, world_volume = 1;
    for (int k = 0; k < 3; ++k) {
        volume *= b.h[k];
        world_volume *= 0.5 * (world.hi[k] - world.lo[k]);
    }
    EXPECT_LT(volume, 0.55 * world_volume);
    // y axis all but along x: Gram-Schmidt's difference keeps a few bits (its axes 8e-4 from orthogonal)
    const double sheared[12] = {1, 0.3, 0.2, 1 + 1e-13, 0.3 - 2e-13, 0.2 + 3e-13, 0, 0, 1, 0, 0, 0};
    const cb::level_detail::OrientedBox f = cb::level_detail::orient_box(local, sheared);
    for (int a = 0; a < 3; ++a)
        for (int k = 0; k < 3; ++k) EXPECT_EQ(f.axis[a][k], a == k ? 1.0 : 0.0);
    EXPECT_TRUE(holds(f, sheared));
    const double flat[12] = {1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0};
    EXPECT_TRUE(cb::level_detail::orient_box(local, flat).empty());
}

TEST(Level, SingularAndFarInstancesBlockNothingOrAnswerExactly) {
    // A flattened instance blocks nothing, and a level 1e7 from the origin answers as the oracle does.
    cb::Scene towers;
    towers.meshes.push_back(cb::generate::tower("t", 6, 6, 20, 4));
    cb::test::Baked b = cb::test::bake_scene(towers);
    cb::Level level;
    const uint32_t asset = level.add_asset(b.view);
    const double far = 1e7;
    for (int i = 0; i < 10; ++i) {
        const double m[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1, far + 9.0 * i, far, 0};
        level.add_instance(asset, 0, m);
    }
    const double flat[12] = {1, 0, 0, 0, 1, 0, 0, 0, 0, far + 4, far + 4, 0};
    level.add_instance(asset, 0, flat);
    level.commit();
    const cb::Scene world = oracle_scene(level, {&towers});
    const SceneOracle oracle(world, level.shadow_bias());
    const Points p = level_points(world, 500, 3);
    const double light[3] = {far + 100, far + 30, 60};
    for (cb::Traversal t : all_traversals)
        EXPECT_EQ(disagreements(oracle, light, p, answer(level, light, p, t, false), false), 0u) << int(t);
    const double sun[3] = {0.5, 0.2, 0.6};
    EXPECT_EQ(disagreements(oracle, sun, p, answer_sun(level, sun, p, false), false, nullptr, true), 0u);
}

// A flat mesh (a ground, a floor) settles the points whose segments rise off its slab without their entering
// it (LevelShadow's slab test): grounds flat to the last bit and a two-sheet floor 1e-5 thick, placed as is,
// mirrored, sheared and turned, near the origin and 2e5 from it; points on them (as rounded by their
// placement), just above, just below (by less than the bias and by more) and between the sheets; point
// lights overhead, grazing, 1e-7 above the ground, in its plane, under it and between the sheets; suns high,
// low, 1e-9 off the plane, along it and from below. Every answer the exact oracle's, both modes; points on
// the ground under a low light test none of its clusters.
TEST(Level, FlatInstancesSettlePointsRisingOffThemExactly) {
    cb::Scene scene;
    cb::Mesh ground;
    ground.positions = {-50, -50, 0, 50, -50, 0, 50, 50, 0, -50, 50, 0};
    ground.indices = {0, 1, 2, 0, 2, 3};
    ground.primitives.push_back({0, 2, false});
    cb::Mesh floor;  // two sheets 1e-5 apart, facing away from each other
    floor.positions = {-20, -20, 0,     20, -20, 0,     20, 20, 0,     -20, 20, 0,
                       -20, -20, 1e-5f, 20, -20, 1e-5f, 20, 20, 1e-5f, -20, 20, 1e-5f};
    floor.indices = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7};
    floor.primitives.push_back({0, 4, false});
    scene.meshes = {ground, floor, cb::generate::tower("t", 6, 6, 20, 3)};
    cb::test::Baked b = cb::test::bake_scene(scene);
    ASSERT_EQ(b.view.mesh_count, 3u);
    for (const double offset : {0.0, 2e5}) {
        cb::Level level;
        const uint32_t asset = level.add_asset(b.view);
        const double o[3] = {offset, -offset, offset * 1e-3};
        const double c = std::cos(0.4), s = std::sin(0.4);
        const double places[][12] = {
            {1, 0, 0, 0, 1, 0, 0, 0, 1, o[0], o[1], o[2]},                      // ground as is
            {-c, -s, 0, -s, c, 0, 0.3, 0, 1, o[0] + 120, o[1] + 10, o[2] + 5},  // mirrored, sheared
            {1, 0, 0, 0, 1, 0, 0, 0, 1, o[0] - 80, o[1] + 70, o[2]},            // the floor
            {c, s, 0, -s, c, 0, 0, 0, 1, o[0] + 15, o[1] + 10, o[2]}};          // the tower
        const uint32_t meshes[] = {0, 0, 1, 2};
        for (int i = 0; i < 4; ++i) level.add_instance(asset, meshes[i], places[i]);
        level.commit();
        const cb::Scene world = oracle_scene(level, {&scene});
        const SceneOracle oracle(world, level.shadow_bias());
        Points p;
        std::mt19937_64 rng(11);
        std::uniform_real_distribution<double> u(-1, 1);
        const double heights[] = {0, 0, 0, 1e-12, -1e-12, 1e-9, -1e-9, 1e-3, -1e-3, 5e-6, 1e-5, 2e-5, -0.05, -1};
        for (int i = 0; i < 1400; ++i) {
            const int placed = i % 3 == 2 ? 2 : i % 3;  // the two grounds and the floor
            const double extent = placed == 2 ? 20 : 50;
            const double local[3] = {extent * u(rng), extent * u(rng), heights[i / 3 % 14]};
            std::array<double, 3> w;
            cb::apply_instance(places[placed], local, w.data());
            p.push_back(w);
        }
        const double lights[][3] = {{0, 0, 80},    {500, 300, 0.5}, {60, 0, 1e-7}, {60, 0, 0},
                                    {10, -5, -40}, {-80, 70, 5e-6}, {120, 10, 60}};
        for (const auto& l : lights) {
            const double light[3] = {l[0] + o[0], l[1] + o[1], l[2] + o[2]};
            for (bool one_sided : {false, true})
                EXPECT_EQ(
                    disagreements(oracle, light, p, answer(level, light, p, cb::Traversal::scan, one_sided), one_sided),
                    0u)
                    << "offset " << offset << " light " << l[0] << "," << l[1] << "," << l[2]
                    << (one_sided ? " one-sided" : "");
        }
        const double suns[][3] = {{0.3, 0.2, 1}, {-1, 0.2, 0.15}, {1, 0.2, 1e-9}, {1, 0.3, 0}, {0.1, 0, -1}};
        for (const auto& sun : suns)
            for (bool one_sided : {false, true})
                EXPECT_EQ(disagreements(oracle, sun, p, answer_sun(level, sun, p, one_sided), one_sided, nullptr, true),
                          0u)
                    << "offset " << offset << " sun " << sun[0] << "," << sun[1] << "," << sun[2]
                    << (one_sided ? " one-sided" : "");
        // Points beyond what the slab test decides (not finite, beyond 1e300, 1e-300 off the ground) answer as
        // the level's reference does.
        const double huge = 1e300;
        Points odd;
        for (const auto& q : std::vector<std::array<double, 3>>{{NAN, 0, 0},
                                                                {INFINITY, 0, 0},
                                                                {0, 0, -INFINITY},
                                                                {huge, huge, 0},
                                                                {-huge, 5, 0},
                                                                {3, 4, 1e-300},
                                                                {3, 4, -1e-300},
                                                                {-30, 20, -huge}})
            odd.push_back({q[0] + o[0], q[1] + o[1], q[2] + o[2]});
        for (const auto& l : lights) {
            const double light[3] = {l[0] + o[0], l[1] + o[1], l[2] + o[2]};
            const std::vector<uint8_t> got = answer(level, light, odd, cb::Traversal::scan, false);
            for (size_t i = 0; i < odd.size(); ++i)
                EXPECT_EQ(got[i], uint8_t(cb::occluded_reference(level, odd[i].data(), light, level.shadow_bias())))
                    << "offset " << offset << " light " << l[0] << "," << l[1] << "," << l[2] << " point " << i;
        }
        for (const auto& sun : suns) {
            const std::vector<uint8_t> got = answer_sun(level, sun, odd, false);
            for (size_t i = 0; i < odd.size(); ++i)
                EXPECT_EQ(got[i], uint8_t(cb::occluded_sun_reference(level, odd[i].data(), sun, level.shadow_bias())))
                    << "offset " << offset << " sun " << sun[0] << "," << sun[1] << "," << sun[2] << " point " << i;
        }
        // Points on the ground as is, away from the tower, under a low light (their segments within the fine
        // boxes' padding of the ground): the ground's clusters are never tested.
        Points on;
        for (int i = 0; i < 200; ++i) on.push_back({o[0] - 45 + 0.2 * i, o[1] - 40, o[2]});
        const double above[3] = {o[0] + 150, o[1] - 40, o[2] + 2};
        cb::QueryStats stats;
        const std::vector<uint8_t> got = answer(level, above, on, cb::Traversal::scan, false, &stats);
        EXPECT_EQ(disagreements(oracle, above, on, got, false), 0u);
        EXPECT_EQ(stats.clusters_tested, 0u) << "offset " << offset;
    }
}

TEST(Level, ShadowsSettleAsTheLightMovesAway) {
    // The self-shadowing bias is a world distance: a light moved away in one direction, from 100 m to
    // 10,000 km, keeps the walls' and roofs' shadows, and the shadowed share settles to the far limit instead
    // of falling (a bias in proportion to the light's distance would lose them all).
    const std::unique_ptr<CityLevel> c = city_level(40, 5);
    cb::Level& level = c->level;
    const Points p = level_points(c->city, 3000, 21);
    const cb::test::WorldSample w = cb::test::sample_scene(c->city, 1);
    const double centre[3] = {0.5 * (w.lo[0] + w.hi[0]), 0.5 * (w.lo[1] + w.hi[1]), 0.5 * (w.lo[2] + w.hi[2])};
    const double dl = std::sqrt(0.5 * 0.5 + 0.3 * 0.3 + 0.8 * 0.8), dir[3] = {0.5 / dl, 0.3 / dl, 0.8 / dl};
    std::vector<double> share;
    for (double distance : {1e2, 1e3, 1e4, 1e5, 1e6, 1e7}) {
        const double light[3] = {centre[0] + distance * dir[0], centre[1] + distance * dir[1],
                                 centre[2] + distance * dir[2]};
        const std::vector<uint8_t> got = answer(level, light, p, cb::Traversal::scan, false);
        size_t dark = 0;
        for (uint8_t g : got) dark += g;
        share.push_back(double(dark) / double(p.size()));
        std::printf("light at %.0e m: %.2f%% of %zu points in shadow\n", distance, 100 * share.back(), p.size());
        if (distance >= 1e6) {  // exact there too, by every traversal
            const SceneOracle oracle(c->city, level.shadow_bias());
            for (cb::Traversal t : all_traversals)
                EXPECT_EQ(disagreements(oracle, light, p, answer(level, light, p, t, false), false), 0u)
                    << distance << " m, traversal " << int(t);
        }
    }
    // The sun in that direction: its exact reference answers (the ray from each point, the same bias) give
    // the share the far lights settle to.
    size_t sun_dark = 0;
    const double bias = level.shadow_bias();
    for (const auto& q : p) sun_dark += cb::occluded_sun_reference(level, q.data(), dir, bias);
    const double sun_share = double(sun_dark) / double(p.size());
    size_t clustered_dark = 0;
    for (uint8_t g : answer_sun(level, dir, p, false)) clustered_dark += g;
    EXPECT_EQ(clustered_dark, sun_dark);  // the clustered sun's answers count the same
    std::printf("the sun: %.2f%% in shadow\n", 100 * sun_share);
    EXPECT_LT(std::fabs(share[5] - sun_share), 0.002);
    EXPECT_LT(std::fabs(share[3] - sun_share), 0.01);
    EXPECT_GT(share.back(), 0.1);                      // the far light still casts shadows
    EXPECT_LT(std::fabs(share[5] - share[4]), 0.002);  // settled: 1,000 km and 10,000 km agree
    EXPECT_LT(std::fabs(share[5] - share[3]), 0.01);   // and 100 km nearly
    EXPECT_GT(share[3], share[5] - 0.01);              // nothing lost on the way out
}

// A field of 4,096 small towers (one mesh, turned) under a low light from its side and a light inside it:
// a tile meets tens of instances, most entered by a few of its points, which are put off and answered with
// other tiles' points, more of them than are held at once (so some are answered while the tiles go on).
// Every answer equals the level's reference query, in one batch and in ranges of tiles.
TEST(Level, InstancesEnteredByFewPointsAnswerAsTheReference) {
    cb::Scene field;
    field.meshes.push_back(cb::generate::tower("t", 1.0, 1.0, 2.0, 1));
    field.instances.push_back({0, cb::identity_transform(), "t"});
    const cb::test::Baked baked = cb::test::bake_scene(field);
    cb::Level level;
    const uint32_t asset = level.add_asset(baked.view);
    for (int y = 0; y < 64; ++y)
        for (int x = 0; x < 64; ++x) {
            const double turn = 0.1 * ((x * 5 + y * 3) % 16), c = std::cos(turn), s = std::sin(turn);
            const double m[12] = {c, s, 0, -s, c, 0, 0, 0, 1, 3.0 * x, 3.0 * y, 0};
            level.add_instance(asset, 0, m);
        }
    level.commit();
    Points p;  // on the ground and up to the towers' height, in rows as a camera sees them
    for (int y = 0; y < 200; ++y)
        for (int x = 0; x < 200; ++x)
            p.push_back({0.96 * x, 0.96 * y, (x * 7 + y * 3) % 5 == 0 ? 0.0 : 0.2 * ((x * 13 + y * 17) % 11)});
    const double bias = level.shadow_bias();
    for (const std::array<double, 3>& light : {std::array<double, 3>{-40, 70, 1.5}, std::array<double, 3>{97, 95, 3}}) {
        const std::vector<uint8_t> got = answer(level, light.data(), p, cb::Traversal::scan, false);
        size_t wrong = 0, dark = 0;
        for (size_t i = 0; i < p.size(); ++i) {
            const bool expect = cb::occluded_reference(level, p[i].data(), light.data(), bias);
            wrong += got[i] != uint8_t(expect);
            dark += expect;
        }
        EXPECT_EQ(wrong, 0u) << light[0];
        EXPECT_GT(dark, p.size() / 4) << light[0];
        cb::LevelShadow shadow;  // the same in ranges of 3 tiles
        shadow.begin(level, light.data(), p[0].data(), p.size());
        shadow.cull(0, shadow.tile_count());
        shadow.build(0, shadow.gather());
        std::vector<uint32_t> scratch(shadow.scratch_size());
        std::vector<uint8_t> ranged(p.size(), 2);
        for (size_t t = 0; t < shadow.tile_count(); t += 3)
            shadow.occluded(t, std::min(t + 3, shadow.tile_count()), ranged.data(), scratch.data());
        EXPECT_EQ(ranged, got) << light[0];
    }
}

TEST(Level, ConcurrentQueriesFromEightThreadsGiveTheSingleThreadedAnswers) {
    const std::unique_ptr<CityLevel> c = city_level(200, 4);
    const cb::Scene& city = c->city;
    cb::Level& level = c->level;
    const Points p = level_points(city, 20000, 8);
    const double light[3] = {100, -60, 150}, sun[3] = {0.3, -0.4, 1};
    for (int k = 0; k < 4; ++k) {  // three traversals, then the sun
        const cb::Traversal t = k == 1 ? cb::Traversal::top_two
            : k == 2                   ? cb::Traversal::mtsv_one
                                       : cb::Traversal::scan;
        cb::ShadowBuildOptions o;
        o.traversal = t;
        cb::LevelShadow shadow;
        std::vector<uint8_t> one(p.size()), many(p.size(), 2);
        if (k == 3)
            shadow.occluded_sun_batch(level, sun, p[0].data(), p.size(), one.data(), o);
        else
            shadow.occluded_batch(level, light, p[0].data(), p.size(), one.data(), o);
        const size_t met = shadow.instances_met();
        std::vector<uint32_t> set_up;
        for (size_t i = 0; i < shadow.build_count(); ++i) set_up.push_back(shadow.built_handle(i));
        // The same steps in ranges: culling and building on 8 threads, then 8 threads answering interleaved
        // tile ranges of the same const structure.
        if (k == 3)
            shadow.begin_sun(level, sun, p[0].data(), p.size(), o);
        else
            shadow.begin(level, light, p[0].data(), p.size(), o);
        const size_t tiles = shadow.tile_count();
        std::vector<std::thread> pool;
        for (size_t w = 0; w < 8; ++w) pool.emplace_back([&, w] { shadow.cull(tiles * w / 8, tiles * (w + 1) / 8); });
        for (std::thread& th : pool) th.join();
        pool.clear();
        const size_t built = shadow.gather();
        // The same lists whatever the ranges (tiles are culled in groups, and some groups decide for others).
        EXPECT_EQ(shadow.instances_met(), met) << k;
        ASSERT_EQ(built, set_up.size()) << k;
        for (size_t i = 0; i < built; ++i) EXPECT_EQ(shadow.built_handle(i), set_up[i]) << k;
        std::vector<cb::BuildScratch> scratch(8);
        for (size_t w = 0; w < 8; ++w)
            pool.emplace_back([&, w] { shadow.build(built * w / 8, built * (w + 1) / 8, &scratch[w]); });
        for (std::thread& th : pool) th.join();
        pool.clear();
        for (size_t w = 0; w < 8; ++w)
            pool.emplace_back([&, w] {
                std::vector<uint32_t> own(shadow.scratch_size());
                for (size_t first = w; first < tiles; first += 8)
                    shadow.occluded(first, first + 1, many.data(), own.data());
            });
        for (std::thread& th : pool) th.join();
        EXPECT_EQ(one, many) << k;
    }
}

TEST(Level, TilesMeetOnlyTheInstancesNearTheirPointsWhateverTheLevelsSize) {
    // The same corner of the city, seen in levels of 100 and 2,500 buildings: the instances a tile meets
    // (and the instances set up for the light) stay about the same, far below the level's count.
    size_t met[2] = {0, 0}, built[2] = {0, 0}, tiles[2] = {0, 0};
    const uint32_t sizes[2] = {100, 2500};
    for (int s = 0; s < 2; ++s) {
        const std::unique_ptr<CityLevel> c = city_level(sizes[s], 2);
        cb::Level& level = c->level;
        // Points on the ground in a 100 m square at one corner of the grid, the light above it.
        const double corner = -0.5 * 30 * (std::ceil(std::sqrt(double(sizes[s]))) - 1);
        Points p;
        for (int j = 0; j < 100; ++j)
            for (int i = 0; i < 100; ++i) p.push_back({corner + i, corner + j, 0.0});
        const double light[3] = {corner + 50, corner + 50, 80};
        cb::LevelShadow shadow;
        std::vector<uint8_t> out(p.size());
        shadow.occluded_batch(level, light, p[0].data(), p.size(), out.data());
        met[s] = shadow.instances_met();
        built[s] = shadow.build_count();
        tiles[s] = shadow.tile_count();
    }
    std::printf("instances met per tile: %.2f (100 buildings), %.2f (2,500); set up: %zu, %zu\n",
                double(met[0]) / tiles[0], double(met[1]) / tiles[1], built[0], built[1]);
    EXPECT_LE(met[1], met[0] * 3 / 2);
    EXPECT_LT(built[1], 60u);
}

TEST(Level, CameraCullingThroughTheHierarchyListsWhatEachInstanceWould) {
    const std::unique_ptr<CityLevel> c = city_level(300, 6);
    const cb::test::Baked& baked = c->baked;
    cb::Level& level = c->level;
    // A frustum looking along +x from the middle of the city: near, far and four sides.
    cb::Frustum f;
    f.count = 6;
    const double planes[6][4] = {{1, 0, 0, -1},   {-1, 0, 0, 200}, {0.5, 1, 0, 0},
                                 {0.5, -1, 0, 0}, {0.4, 0, 1, 0},  {0.4, 0, -1, 30}};
    for (int k = 0; k < 6; ++k)
        for (int j = 0; j < 4; ++j) f.plane[k][j] = planes[k][j];
    std::vector<cb::VisibleCluster> through(1 << 16), each(1 << 16);
    const size_t n = cb::cull_clusters(level, f, true, through.data(), through.size());
    size_t m = 0;
    for (uint32_t h = 0; h < level.handle_limit(); ++h)
        m = cb::cull_instance(baked.view, level.placement(h), h, f, true, each.data(), each.size(), m);
    ASSERT_LT(n, through.size());
    through.resize(n);
    each.resize(m);
    auto key = [](const cb::VisibleCluster& c) { return uint64_t(c.instance) << 32 | c.fine; };
    auto by_key = [&](const cb::VisibleCluster& x, const cb::VisibleCluster& y) { return key(x) < key(y); };
    std::sort(through.begin(), through.end(), by_key);
    std::sort(each.begin(), each.end(), by_key);
    EXPECT_GT(n, 0u);
    ASSERT_EQ(n, m);
    for (size_t i = 0; i < n; ++i) EXPECT_EQ(key(through[i]), key(each[i]));
}

}  // namespace
