// Cluster statistics on shapes whose figures are known by hand, on real scans, and through the CLI (text,
// JSON, asset input, determinism, bad input).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>

#include "cluster_stats.h"
#include "load.h"
#include "stats_helpers.h"
#include "baked_scene.h"

namespace fs = std::filesystem;
using namespace cb::test;

namespace {

cb::SceneStats stats_of(const cb::Scene& scene, uint32_t fine = 16, cb::StatsOptions so = {}) {
    cb::ClusterOptions c;
    c.fine_size = fine;
    cb::BoundsOptions b;
    b.mask = cb::bounds_all;
    cb::BakedScene baked = cb::bake_in_memory(scene, c, b);
    return cb::cluster_statistics(baked.meshes, baked.instances, so);
}

std::string data(const std::string& f) { return std::string(CB_SOURCE_DIR) + "/data/" + f; }

fs::path scratch(const std::string& name) {
    fs::path p = fs::path(CB_TEST_OUTPUT) / name;
    fs::create_directories(p.parent_path());
    return p;
}

}  // namespace

TEST(Stats, SingleClusterCube) {
    cb::SceneStats s = stats_of(scene_of(unit_cube()));
    for (const cb::LevelStats* l : {&s.coarse, &s.fine}) {
        EXPECT_EQ(l->clusters, 1u);
        EXPECT_EQ(l->triangles.min, 12);
        EXPECT_EQ(l->triangles.max, 12);
        EXPECT_EQ(l->vertices.mean, 8);
        EXPECT_EQ(l->components.max, 1);
        EXPECT_EQ(l->split_clusters, 0u);
        EXPECT_NEAR(l->vertices_per_triangle, 8.0 / 12.0, 1e-12);
        // The box is the cube itself, rounded outward by a few ulps.
        EXPECT_NEAR(l->obb_volume_sum, 1.0, 1e-5);
        EXPECT_NEAR(l->obb_area_sum, 6.0, 1e-5);
        EXPECT_NEAR(l->obb_volume_relative, 1.0, 1e-5);
        EXPECT_NEAR(l->obb_area_relative, 1.0, 1e-5);
        EXPECT_NEAR(l->fill, 1.0, 1e-5);
        // Minimal sphere: radius sqrt(3) / 2.
        EXPECT_NEAR(l->sphere_over_obb, 4.0 / 3.0 * M_PI * std::pow(std::sqrt(3.0) / 2, 3), 1e-4);
        EXPECT_NEAR(l->capsule_over_obb, l->sphere_over_obb, 1e-9);  // a cube is not elongated: its sphere
        // Normals in every direction: no cone, and so no light ever skips it.
        EXPECT_EQ(l->no_cone_share, 1.0);
        EXPECT_EQ(l->normal_cone_degrees.count, 0u);
        EXPECT_EQ(l->light_skip_share, 0.0);
        // Sampled points inside the box behind the cube, seen from outside: the cube shadows nearly all of
        // them (only points within the self-shadowing distance of a face escape).
        EXPECT_GT(l->volume_samples, 100u);
        EXPECT_LT(l->useless_share, 0.02);
        // The same for suns: no cone to skip by, and every ray from the cube's prism passes through it.
        EXPECT_EQ(l->sun_skip_share, 0.0);
        EXPECT_GT(l->sun_prism_samples, 100u);
        EXPECT_LT(l->sun_useless_share, 0.02);
    }
    EXPECT_EQ(s.triangles, 12u);
}

TEST(Stats, OneTriangle) {
    cb::StatsOptions so;
    so.lights = 200;
    so.suns = 200;
    cb::SceneStats s = stats_of(scene_of(mesh_of({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2})), 16, so);
    const cb::LevelStats& f = s.fine;
    EXPECT_EQ(f.clusters, 1u);
    EXPECT_EQ(f.vertices.max, 3);
    EXPECT_EQ(f.components.max, 1);
    // The smallest rectangle around a right triangle has twice its area: the flat box's two faces hold 4x.
    EXPECT_NEAR(f.fill, 0.25, 1e-4);
    EXPECT_EQ(f.no_cone_share, 0.0);
    EXPECT_NEAR(f.normal_cone_degrees.max, 0.0, 1e-3);
    // Lights all around a flat triangle: about half are on its front side, and those skip it.
    EXPECT_NEAR(f.light_skip_share, 0.5, 0.1);
    EXPECT_NEAR(f.sun_skip_share, 0.5, 0.1);  // suns from every direction: half see its front
    // A flat scene has no volume: relative volume cannot be computed (NaN, null in JSON).
    EXPECT_TRUE(std::isnan(f.obb_volume_relative));
    EXPECT_TRUE(cb::to_json(s)["fine"]["obb"]["volume_relative_to_scene"].is_null());
}

TEST(Stats, TwoDisjointPartsInOneCluster) {
    // Two triangles far apart, then two that share an edge by position only (an unwelded soup).
    cb::SceneStats apart =
        stats_of(scene_of(mesh_of({0, 0, 0, 1, 0, 0, 0, 1, 0, 5, 5, 5, 6, 5, 5, 5, 6, 5}, {0, 1, 2, 3, 4, 5})));
    EXPECT_EQ(apart.fine.clusters, 1u);
    EXPECT_EQ(apart.fine.components.max, 2);
    EXPECT_EQ(apart.fine.split_clusters, 1u);
    EXPECT_EQ(apart.fine.vertices.max, 6);
    cb::SceneStats soup =
        stats_of(scene_of(mesh_of({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, {0, 1, 2, 3, 4, 5})));
    EXPECT_EQ(soup.fine.components.max, 1);
    EXPECT_EQ(soup.fine.vertices.max, 6);  // distinct stored vertices, as the asset stores them
}

TEST(Stats, InstancesScaleWorldVolumes) {
    cb::Scene s = scene_of(unit_cube());
    cb::Transform t = cb::identity_transform();
    t[0] = t[5] = t[10] = 2;
    t[12] = 3;  // scaled by 2, moved to x = 3
    s.instances.push_back({0, t, "big"});
    cb::SceneStats st = stats_of(s);
    EXPECT_EQ(st.fine.clusters, 1u);  // the mesh is stored once
    EXPECT_EQ(st.scene_triangles, 24u);
    // World boxes 1 + 8 in a scene box of 5 x 2 x 2; areas 6 + 24 over 2 (10 + 4 + 10).
    EXPECT_NEAR(st.fine.obb_volume_relative, 9.0 / 20.0, 1e-5);
    EXPECT_NEAR(st.fine.obb_area_relative, 30.0 / 48.0, 1e-5);
}

TEST(Stats, HistogramsCoverEveryCluster) {
    cb::Scene scene = cb::load_scene(data("default_scene.glb"));
    cb::SceneStats s = stats_of(scene);
    for (const cb::LevelStats* l : {&s.coarse, &s.fine}) {
        for (const cb::Distribution* d : {&l->triangles, &l->vertices, &l->components}) {
            uint64_t sum = 0;
            for (uint64_t c : d->counts) sum += c;
            EXPECT_EQ(sum, l->clusters);
            EXPECT_LE(d->counts.size(), 16u);
            EXPECT_LE(d->min, d->mean);
            EXPECT_LE(d->mean, d->max);
        }
        EXPECT_GT(l->useless_share, 0.0);
        EXPECT_LT(l->useless_share, 1.0);
        EXPECT_GT(l->fill, 0.0);
        EXPECT_LE(l->fill, 1.0 + 1e-6);
        EXPECT_GE(l->sphere_over_obb, 0.5);
    }
    EXPECT_LE(s.fine.triangles.max, 16);
    EXPECT_GT(s.acmr, 0.4);
    EXPECT_LT(s.acmr, 3.0);
}

TEST(Stats, ScannedMeshesFinerIsTighter) {
    fs::path bunny = fs::path(CB_SHARED_DATA) / "scanned/bunny_npm.obj";
    if (!fs::exists(bunny)) GTEST_SKIP() << "no shared data at " << bunny;
    cb::Scene scene = cb::load_scene(bunny.string());
    cb::SceneStats s8 = stats_of(scene, 8), s32 = stats_of(scene, 32);
    EXPECT_LT(s8.fine.obb_volume_relative, s32.fine.obb_volume_relative);
    EXPECT_LT(s8.fine.useless_share, s32.fine.useless_share);
    EXPECT_GT(s8.fine.light_skip_share, s32.fine.light_skip_share);  // narrower cones skip more often
    EXPECT_LT(s8.fine.sun_useless_share, s32.fine.sun_useless_share);
    EXPECT_GT(s8.fine.sun_skip_share, s32.fine.sun_skip_share);
}

TEST(StatsCli, JsonIsWellFormedAndDeterministic) {
    std::string file = data("default_scene.glb");
    CliRun one = run_cli("stats --json --threads 1 " + file), two = run_cli("stats --json --threads 2 " + file);
    ASSERT_EQ(one.code, 0) << one.err;
    ASSERT_EQ(two.code, 0) << two.err;
    EXPECT_EQ(one.out, two.out);
    nlohmann::json j = nlohmann::json::parse(one.out);
    for (const char* level : {"coarse", "fine"}) {
        ASSERT_TRUE(j.contains(level));
        for (const char* key : {"clusters", "triangles", "vertices", "components", "obb", "fill", "normal_cone_degrees",
                                "no_cone_share", "light_skip_share", "shadow_volume", "sun_skip_share", "sun_prism"})
            EXPECT_TRUE(j[level].contains(key)) << level << "." << key;
    }
    EXPECT_EQ(j["input"], "scene");
    EXPECT_EQ(j["instances"], 12);
    CliRun text = run_cli("stats " + file);
    ASSERT_EQ(text.code, 0);
    EXPECT_NE(text.out.find("fine: "), std::string::npos);
    EXPECT_NE(text.out.find("shadow volumes:"), std::string::npos);
    EXPECT_NE(text.out.find("sun prisms:"), std::string::npos);
}

// Equal JSON, except that numbers may differ in their last digits: the asset stores its vertices in
// another order (first use by the clusters), so sums over them round differently.
void expect_near_json(const nlohmann::json& a, const nlohmann::json& b, const std::string& path) {
    if (a.is_number() && b.is_number()) {
        double x = a.get<double>(), y = b.get<double>();
        EXPECT_LE(std::fabs(x - y), 1e-9 * std::max(std::fabs(x), std::fabs(y))) << path;
        return;
    }
    ASSERT_EQ(a.type(), b.type()) << path;
    if (a.is_object()) {
        ASSERT_EQ(a.size(), b.size()) << path;
        for (auto it = a.begin(); it != a.end(); ++it) {
            ASSERT_TRUE(b.contains(it.key())) << path << "." << it.key();
            expect_near_json(it.value(), b[it.key()], path + "." + it.key());
        }
    } else if (a.is_array()) {
        ASSERT_EQ(a.size(), b.size()) << path;
        for (size_t i = 0; i < a.size(); ++i) expect_near_json(a[i], b[i], path + "[" + std::to_string(i) + "]");
    } else {
        EXPECT_EQ(a, b) << path;
    }
}

TEST(StatsCli, AnAssetGivesTheSameFiguresAsItsScene) {
    std::string file = data("default_scene.glb"), asset = scratch("stats_default.cbk").string();
    ASSERT_EQ(run_cli("bake " + file + " -o " + asset + " --fine 24").code, 0);
    CliRun from_asset = run_cli("stats --json " + asset), from_scene = run_cli("stats --json --fine 24 " + file);
    ASSERT_EQ(from_asset.code, 0) << from_asset.err;
    nlohmann::json a = nlohmann::json::parse(from_asset.out), s = nlohmann::json::parse(from_scene.out);
    EXPECT_EQ(a["input"], "asset");
    EXPECT_NE(a["note"].get<std::string>().find("sphere"), std::string::npos);  // bake auto stores boxes and cones
    expect_near_json(a["fine"], s["fine"], "fine");
    expect_near_json(a["coarse"], s["coarse"], "coarse");
}

TEST(StatsCli, BadInputIsOneLineNamingTheFile) {
    CliRun missing = run_cli("stats " + scratch("no_such_file.obj").string());
    EXPECT_EQ(missing.code, 2);
    EXPECT_NE(missing.err.find("no_such_file.obj"), std::string::npos) << missing.err;
    EXPECT_EQ(std::count(missing.err.begin(), missing.err.end(), '\n'), 1);
    // A corrupted asset: a byte flipped after the header fails the checksum.
    std::string asset = scratch("stats_corrupt.cbk").string();
    ASSERT_EQ(run_cli("bake " + data("small/cube.obj") + " -o " + asset).code, 0);
    std::string bytes = slurp(asset);
    bytes[bytes.size() - 20] ^= 0x55;
    std::ofstream(asset, std::ios::binary) << bytes;
    CliRun corrupt = run_cli("stats " + asset);
    EXPECT_EQ(corrupt.code, 2);
    EXPECT_NE(corrupt.err.find("stats_corrupt.cbk: checksum"), std::string::npos) << corrupt.err;
    EXPECT_EQ(run_cli("stats --method nope " + data("small/cube.obj")).code, 2);
}
