// clusterbake render and its library (render/): primary visibility against a brute-force ray cast, the area
// light's samples, and the command on the default scene (a picture that is not blank, shadows that agree
// with clusterbake query on the same points, Embree's answers beside the runtime's), its option errors, and
// a shared scene.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <detail/cb_math.h>

#include <algorithm>
#include <array>
#include <fstream>
#include <cmath>
#include <filesystem>
#include <set>
#include <sstream>
#include <string>

#include "area_light.h"
#include "asset_file.h"
#include "asset_writer.h"
#include "baked_scene.h"
#include "stats_helpers.h"
#include "visibility.h"

namespace {

namespace fs = std::filesystem;
using cb::test::CliRun;
using cb::test::read_png;
using cb::test::Rgb;
using cb::test::run_cli;

// The default scene as the build bakes it (tests/CMakeLists.txt, runtime_bake_default_scene).
const std::string default_asset = CB_DEFAULT_ASSET;

// A folder of this test's own under the build's test-artifacts/render (kept for looking at the pictures).
fs::path output_dir(const std::string& name) {
    fs::path dir = fs::path(CB_TEST_OUTPUT) / name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

// Pixels whose colour is not the background's (which has equal columns, changing only down the picture).
size_t scene_pixels(const Rgb& img) {
    size_t n = 0;
    for (uint32_t y = 0; y < img.height; ++y)
        for (uint32_t x = 0; x < img.width; ++x) {
            const uint8_t* p = &img.pixels[(size_t(y) * img.width + x) * 3];
            const uint8_t* first = &img.pixels[size_t(y) * img.width * 3];
            n += !std::equal(p, p + 3, first);
        }
    return n;
}

size_t line_count(const std::string& text) { return size_t(std::count(text.begin(), text.end(), '\n')); }

std::string light_text(const nlohmann::json& xyz) {
    char text[128];
    std::snprintf(text, sizeof text, "%.17g,%.17g,%.17g", xyz[0].get<double>(), xyz[1].get<double>(),
                  xyz[2].get<double>());
    return text;
}

// How many points `query` puts in shadow of `light`, over the default asset or another asset or level.
uint64_t query_shadowed(const std::string& points, const std::string& light, const std::string& extra = "",
                        const std::string& asset = default_asset) {
    CliRun q = run_cli("query " + asset + " --light " + light + " --points " + points + " --json " + extra);
    EXPECT_EQ(q.code, 0) << q.err;
    return q.code == 0 ? nlohmann::json::parse(q.out)["shadowed"].get<uint64_t>() : 0;
}

// The ray o + t d (t > 0) against triangle a, b, c in double: t, or INFINITY.
double ray_triangle(const double* o, const double* d, const double* a, const double* b, const double* c) {
    double e1[3], e2[3], s[3], p[3], q[3];
    for (int k = 0; k < 3; ++k) {
        e1[k] = b[k] - a[k];
        e2[k] = c[k] - a[k];
        s[k] = o[k] - a[k];
    }
    cb::math::cross3(d, e2, p);
    const double det = cb::math::dot3(e1, p);
    if (det == 0) return INFINITY;
    const double u = cb::math::dot3(s, p) / det;
    cb::math::cross3(s, e1, q);
    const double v = cb::math::dot3(d, q) / det, t = cb::math::dot3(e2, q) / det;
    return u >= 0 && v >= 0 && u + v <= 1 && t > 0 ? t : INFINITY;
}

}  // namespace

TEST(RenderVisibility, MatchesABruteForceRayCast) {
    // Two unit cubes, the second turned and moved, seen from a generic eye: each pixel's visible point is
    // where a brute-force ray cast over every triangle first hits.
    cb::Scene scene = cb::test::scene_of(cb::test::unit_cube());
    cb::Transform moved = cb::identity_transform();
    moved[0] = 0;
    moved[2] = -1;
    moved[8] = 1;
    moved[10] = 0;  // a quarter turn about y
    moved[12] = 1.7;
    moved[13] = 0.2;
    moved[14] = -0.4;
    scene.instances.push_back({0, moved, "moved"});
    cb::ClusterOptions clustering;
    clustering.fine_size = 4;
    cb::BoundsOptions bounds;
    bounds.mask = cb::bounds_auto;
    cb::BakedScene baked = cb::bake_in_memory(scene, clustering, bounds);
    cb::LoadedAsset asset;
    ASSERT_EQ(cb::open_asset_copy(cb::encode_asset(baked.meshes, baked.instances), asset), cb::AssetError::ok);

    const double eye[3] = {-2.3, 2.9, 4.1}, target[3] = {1.1, 0.4, 0.2}, up[3] = {0, 1, 0};
    const cb::Camera cam = cb::camera_looking_at(eye, target, up, 30, 96, 64);
    const cb::VisibleSurface s = cb::primary_visibility(cb::baked_level(asset.view), cam, 2);
    ASSERT_GT(s.pixel.size(), 1000u);

    std::vector<std::array<double, 9>> world;  // every triangle of both instances
    for (const cb::Instance& inst : scene.instances) {
        const cb::Mesh& m = scene.meshes[0];
        for (size_t t = 0; t < m.indices.size(); t += 3) {
            std::array<double, 9> tri;
            for (int c = 0; c < 3; ++c) {
                const float* p = &m.positions[size_t(m.indices[t + c]) * 3];
                auto w = cb::transform_point(inst.world, p[0], p[1], p[2]);
                for (int k = 0; k < 3; ++k) tri[size_t(c * 3 + k)] = w[size_t(k)];
            }
            world.push_back(tri);
        }
    }
    const double aspect = 96.0 / 64.0;
    size_t next = 0, covered = 0;
    for (uint32_t y = 0; y < cam.height; ++y)
        for (uint32_t x = 0; x < cam.width; ++x) {
            double dir[3], sx = ((x + 0.5) / cam.width * 2 - 1) * aspect, sy = 1 - (y + 0.5) / cam.height * 2;
            for (int k = 0; k < 3; ++k)
                dir[k] = cam.forward[k] + cam.half_extent * (sx * cam.right[k] + sy * cam.up[k]);
            double best = INFINITY;
            for (const auto& t : world) best = std::min(best, ray_triangle(cam.eye, dir, &t[0], &t[3], &t[6]));
            const bool drawn = next < s.pixel.size() && s.pixel[next] == y * cam.width + x;
            ASSERT_EQ(drawn, best < INFINITY) << "pixel " << x << ", " << y;
            if (!drawn) continue;
            ++covered;
            const double* p = &s.points[next * 3];
            const double* n = &s.normals[next * 3];
            for (int k = 0; k < 3; ++k) EXPECT_NEAR(p[k], cam.eye[k] + best * dir[k], 1e-12) << x << ", " << y;
            EXPECT_NEAR(cb::math::dot3(n, n), 1.0, 1e-12);
            EXPECT_LT(cb::math::dot3(n, dir), 0) << "the normal faces the eye";
            EXPECT_EQ(s.meshes[next], 0u);
            ++next;
        }
    EXPECT_EQ(covered, s.pixel.size());
    EXPECT_EQ(s.triangles_drawn, 24u);
}

TEST(RenderAreaLight, StratifiedJitteredAndRepeatable) {
    const double facing[3] = {0, 0, 0};
    for (cb::AreaShape shape : {cb::AreaShape::square, cb::AreaShape::disc})
        for (uint32_t n : {1u, 5u, 16u, 17u, 64u}) {
            cb::AreaLight light;
            light.centre[0] = 3;
            light.centre[1] = 10;
            light.centre[2] = -2;
            light.size = 2;
            light.samples = n;
            light.shape = shape;
            const std::vector<double> a = cb::area_light_samples(light, facing),
                                      b = cb::area_light_samples(light, facing);
            ASSERT_EQ(a.size(), size_t(n) * 3);
            EXPECT_EQ(a, b) << "a fixed seed";
            const double axis[3] = {-3, -10, 2};
            double mean[3] = {0, 0, 0};
            std::set<std::array<double, 3>> distinct;
            for (uint32_t i = 0; i < n; ++i) {
                double off[3];
                for (int k = 0; k < 3; ++k) {
                    off[k] = a[i * 3 + k] - light.centre[k];
                    mean[k] += off[k] / n;
                }
                EXPECT_NEAR(cb::math::dot3(off, axis), 0, 1e-12) << "in the plane facing the scene";
                const double r = std::sqrt(cb::math::dot3(off, off));
                EXPECT_LE(r, shape == cb::AreaShape::disc ? 1 + 1e-12 : std::sqrt(2.0) + 1e-12);
                distinct.insert({a[i * 3], a[i * 3 + 1], a[i * 3 + 2]});
            }
            EXPECT_EQ(distinct.size(), size_t(n));
            if (n == 16 && shape == cb::AreaShape::square) {  // one point a cell of 0.5 x 0.5: the mean stays near
                EXPECT_LT(std::sqrt(cb::math::dot3(mean, mean)), 0.25 * std::sqrt(2.0));
            }
        }
}

TEST(Render, DefaultSceneShadowsAgreeWithQuery) {
    const fs::path dir = output_dir("default");
    const std::string png = (dir / "default.png").string(), points = (dir / "points.txt").string();
    CliRun r =
        run_cli("render " + default_asset + " -o " + png + " --size 320x240 --write-points " + points + " --json");
    ASSERT_EQ(r.code, 0) << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["tool"].get<std::string>().rfind("clusterbake ", 0), 0u);
    EXPECT_EQ(j["width"], 320);
    EXPECT_EQ(j["lights"], 1);

    // A picture that is not blank: the scene covers a good part of it, in many shades.
    const Rgb img = read_png(png);
    ASSERT_EQ(img.width, 320u);
    ASSERT_EQ(img.height, 240u);
    const uint64_t covered = j["pixels_covered"], asked = j["points"];
    EXPECT_GT(covered, 320u * 240u / 8);
    EXPECT_GE(scene_pixels(img), covered * 9 / 10);
    EXPECT_EQ(j["aa"], 2) << "2 x 2 samples a pixel by default";
    EXPECT_GT(asked, 3 * covered);
    EXPECT_LE(asked, 4 * covered);
    EXPECT_GT(cb::test::grey_variance(img), 50);
    std::set<uint32_t> shades;
    for (size_t i = 0; i < img.pixels.size(); i += 3)
        shades.insert(uint32_t(img.pixels[i]) << 16 | uint32_t(img.pixels[i + 1]) << 8 | img.pixels[i + 2]);
    EXPECT_GT(shades.size(), 100u);

    // The same points asked of clusterbake query: the same number in shadow, one-sided too.
    const std::string text = cb::test::slurp(points);
    EXPECT_EQ(line_count(text), asked);
    EXPECT_EQ(j["queries"], asked);
    const uint64_t shadowed = j["shadowed"];
    EXPECT_GT(shadowed, 0u);
    EXPECT_LT(shadowed, asked);
    EXPECT_EQ(query_shadowed(points, light_text(j["light"])), shadowed);
    EXPECT_DOUBLE_EQ(j["shadowed_fraction"].get<double>(), double(shadowed) / double(asked));

    // --up turns the default camera, and the light placed from it, about the framed box's centre: a quarter
    // turn about x takes +y to +z. An object alone (the default scene's ground is flat along y, not z).
    const std::string cube = (dir / "cube.cbk").string();
    ASSERT_EQ(run_cli("bake " + std::string(CB_SOURCE_DIR) + "/data/small/cube.obj -o " + cube + " -q").code, 0);
    CliRun y_up = run_cli("render " + cube + " -o " + (dir / "cube.png").string() + " --size 64 --json -q");
    CliRun z_up =
        run_cli("render " + cube + " -o " + (dir / "cube_z_up.png").string() + " --size 64 --up 0,0,1 --json -q");
    ASSERT_EQ(y_up.code, 0) << y_up.err;
    ASSERT_EQ(z_up.code, 0) << z_up.err;
    const nlohmann::json a = nlohmann::json::parse(y_up.out), b = nlohmann::json::parse(z_up.out);
    EXPECT_EQ(a["framed_box"], b["framed_box"]);
    const std::vector<double> l = a["light"], turned = b["light"], lo = a["framed_box"]["lo"],
                              hi = a["framed_box"]["hi"];
    const double centre[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
    EXPECT_NEAR(turned[0], l[0], 1e-9);
    EXPECT_NEAR(turned[1] - centre[1], -(l[2] - centre[2]), 1e-6);
    EXPECT_NEAR(turned[2] - centre[2], l[1] - centre[1], 1e-6);

    CliRun one = run_cli("render " + default_asset + " -o " + (dir / "one_sided.png").string() +
                         " --size 320x240 --one-sided --light -4,30,2 --json -q");
    ASSERT_EQ(one.code, 0) << one.err;
    const nlohmann::json o = nlohmann::json::parse(one.out);
    EXPECT_EQ(o["pixels_covered"], covered) << "the same camera";
    EXPECT_EQ(query_shadowed(points, "-4,30,2", "--one-sided"), o["shadowed"].get<uint64_t>());
}

// A level file: the asset alone draws the same picture as the asset; placed three times (one copy turned
// and mirrored), every copy is drawn and lit, and query over the level agrees with the picture's shadows.
TEST(Render, LevelFilePlacesEveryAsset) {
    const fs::path dir = output_dir("level");
    fs::copy_file(default_asset, dir / "scene.cbk");
    std::ofstream(dir / "alone.json") << R"({"instances": [{"asset": "scene.cbk"}]})";
    std::ofstream(dir / "three.json") << R"({"instances": [{"asset": "scene.cbk"},
        {"asset": "scene.cbk", "translation": [40, 0, 0], "rotation": [0, 1, 0, 0], "scale": [1, 1, -1]},
        {"asset": "scene.cbk", "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 40, 1]}]})";
    const std::string common = " --size 160x120 --light -4,30,2 -q --json";
    CliRun asset = run_cli("render " + default_asset + " -o " + (dir / "asset.png").string() + common);
    CliRun alone = run_cli("render " + (dir / "alone.json").string() + " -o " + (dir / "alone.png").string() + common);
    ASSERT_EQ(asset.code, 0) << asset.err;
    ASSERT_EQ(alone.code, 0) << alone.err;
    EXPECT_EQ(read_png((dir / "alone.png").string()).pixels, read_png((dir / "asset.png").string()).pixels);

    const std::string points = (dir / "points.txt").string(), level = (dir / "three.json").string();
    CliRun three = run_cli("render " + level + " -o " + (dir / "three.png").string() +
                           " --size 320x240 --aa 1 --light 16,30,20 --json -q --write-points " + points);
    ASSERT_EQ(three.code, 0) << three.err;
    const nlohmann::json j = nlohmann::json::parse(three.out), a = nlohmann::json::parse(asset.out);
    EXPECT_GT(j["triangles_drawn"].get<uint64_t>(), 2 * a["triangles_drawn"].get<uint64_t>()) << "every copy in view";
    const uint64_t shadowed = j["shadowed"];
    EXPECT_GT(shadowed, 0u);
    EXPECT_EQ(query_shadowed(points, "16,30,20", "", level), shadowed);
    EXPECT_EQ(query_shadowed(points, "16,30,20", "--reference", level), shadowed);
}

TEST(Render, AreaLightIsSoftAndEachSampleAgreesWithQuery) {
    const fs::path dir = output_dir("area");
    const std::string points = (dir / "points.txt").string();
    // One sample a pixel: the soft shadow's shades, not the edges', are counted below.
    const std::string common =
        " --size 200x150 --aa 1 --eye 6,5,12 --target -1,0.5,0 --fov 40 --area-light -4,12,2,5,9";
    CliRun r = run_cli("render " + default_asset + " -o " + (dir / "soft.png").string() + common + " --write-points " +
                       points + " --threads 1 --json");
    ASSERT_EQ(r.code, 0) << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    ASSERT_EQ(j["lights"], 9);
    EXPECT_EQ(j["area_light"]["samples"], 9);
    EXPECT_EQ(j["build_seconds"].size(), 9u);
    EXPECT_EQ(j["query_seconds"].size(), 9u);
    EXPECT_GE(j["bounds_seconds"].get<double>(), 0.0);

    // Every sample's share of the shadows is what query says for that light alone.
    uint64_t total = 0;
    const std::vector<double> lights = j["light_positions"];
    ASSERT_EQ(lights.size(), 27u);
    for (size_t l = 0; l < lights.size(); l += 3)
        total += query_shadowed(points, light_text(nlohmann::json{lights[l], lights[l + 1], lights[l + 2]}));
    EXPECT_EQ(total, j["shadowed"].get<uint64_t>());
    EXPECT_EQ(j["queries"].get<uint64_t>(), 9 * j["points"].get<uint64_t>());

    // Soft: some points are reached by some samples and not others. The picture does not depend on threads.
    CliRun again = run_cli("render " + default_asset + " -o " + (dir / "soft2.png").string() + common +
                           " --area-shape square --threads 2 -q");
    ASSERT_EQ(again.code, 0) << again.err;
    EXPECT_EQ(cb::test::slurp((dir / "soft.png").string()), cb::test::slurp((dir / "soft2.png").string()));
    CliRun hard = run_cli("render " + default_asset + " -o " + (dir / "hard.png").string() +
                          " --size 200x150 --aa 1 --eye 6,5,12 --target -1,0.5,0 --fov 40 --light -4,12,2 --json -q");
    ASSERT_EQ(hard.code, 0) << hard.err;
    const Rgb soft = read_png((dir / "soft.png").string()), sharp = read_png((dir / "hard.png").string());
    std::set<uint8_t> soft_greys, sharp_greys;  // shades of the ground's pale grey between lit and shadowed
    for (size_t i = 0; i < soft.pixels.size(); i += 3) soft_greys.insert(soft.pixels[i]);
    for (size_t i = 0; i < sharp.pixels.size(); i += 3) sharp_greys.insert(sharp.pixels[i]);
    EXPECT_GT(soft_greys.size(), sharp_greys.size());

    CliRun disc = run_cli("render " + default_asset + " -o " + (dir / "disc.png").string() + common +
                          " --area-shape disc --json -q");
    ASSERT_EQ(disc.code, 0) << disc.err;
    EXPECT_EQ(nlohmann::json::parse(disc.out)["area_light"]["shape"], "disc");
}

TEST(Render, CompareWithEmbreeDiffersOnlyInTiesAndNearTies) {
    const fs::path dir = output_dir("compare");
    const std::string png = (dir / "default.png").string();
    CliRun r = run_cli("render " + default_asset + " -o " + png + " --size 320x240 --compare --json");
    ASSERT_EQ(r.code, 0) << r.err;
    const nlohmann::json c = nlohmann::json::parse(r.out)["compare"];
    EXPECT_EQ(c["output"], (dir / "default.compare.png").string());
    EXPECT_EQ(c["pairs"], nlohmann::json::parse(r.out)["points"]);
    EXPECT_EQ(c["pixels_other"], 0) << c.dump();
    EXPECT_EQ(c["differing"].get<uint64_t>(), c["runtime_only"].get<uint64_t>() + c["embree_only"].get<uint64_t>());
    const Rgb diff = read_png(c["output"].get<std::string>());
    EXPECT_EQ(diff.width, 320u);
    // The difference picture is grey wherever nothing differs.
    size_t coloured = 0;
    for (size_t i = 0; i < diff.pixels.size(); i += 3)
        coloured += diff.pixels[i] != diff.pixels[i + 1] || diff.pixels[i + 1] != diff.pixels[i + 2];
    EXPECT_EQ(coloured == 0, c["pixels"] == 0);

    // The counts are printed.
    CliRun text = run_cli("render " + default_asset + " -o " + png + " --size 320x240 --compare -q");
    ASSERT_EQ(text.code, 0) << text.err;
    EXPECT_NE(text.out.find("compare -> " + c["output"].get<std::string>() + ": " +
                            std::to_string(c["pairs"].get<uint64_t>()) + " pairs, " +
                            std::to_string(c["differing"].get<uint64_t>()) + " differ"),
              std::string::npos)
        << text.out;
    EXPECT_NE(text.out.find(std::to_string(c["pixels"].get<uint64_t>()) + " pixels differ, " +
                            std::to_string(c["pixels_other"].get<uint64_t>()) + " other than by a tie or near tie"),
              std::string::npos);

    // An area light's samples graze the blobs: pairs may differ there, each a tie or a near tie.
    CliRun soft = run_cli("render " + default_asset + " -o " + (dir / "soft.png").string() +
                          " --size 320x240 --eye 6,5,12 --target -1,0.5,0 --fov 40 --area-light -4,30,2,6,16 --compare "
                          "--json -q");
    ASSERT_EQ(soft.code, 0) << soft.err;
    const nlohmann::json s = nlohmann::json::parse(soft.out)["compare"];
    EXPECT_EQ(s["pixels_other"], 0) << s.dump();
    EXPECT_EQ(s["ties"].get<uint64_t>() + s["near_ties"].get<uint64_t>(), s["differing"].get<uint64_t>()) << s.dump();
}

TEST(Render, SunShadowsAgreeWithQueryAndEmbree) {
    // --sun: the picture's shadows are those clusterbake query --sun gives its points, the JSON names the
    // sun, and Embree's rays along the same direction differ only in ties and near ties.
    const fs::path dir = output_dir("sun");
    const std::string png = (dir / "sun.png").string(), points = (dir / "points.txt").string();
    for (const char* sun : {"0.8,0.5,0.3", "-1,0.2,0.5"}) {  // 1.1% and 6% of the points in shadow
        SCOPED_TRACE(sun);
        CliRun r = run_cli("render " + default_asset + " -o " + png + " --size 240x180 --sun " + sun +
                           " --write-points " + points + " --compare --json -q");
        ASSERT_EQ(r.code, 0) << r.err;
        const nlohmann::json j = nlohmann::json::parse(r.out);
        ASSERT_TRUE(j.contains("sun")) << r.out;
        EXPECT_FALSE(j.contains("light"));
        const uint64_t shadowed = j["shadowed"], covered = j["pixels_covered"];
        EXPECT_GT(shadowed, covered / 200);
        EXPECT_LT(shadowed, covered);
        CliRun q = run_cli("query " + default_asset + " --sun " + sun + " --points " + points + " --json");
        ASSERT_EQ(q.code, 0) << q.err;
        EXPECT_EQ(nlohmann::json::parse(q.out)["shadowed"].get<uint64_t>(), shadowed);
        const nlohmann::json c = j["compare"];
        EXPECT_EQ(c["pixels_other"], 0) << c.dump();
        EXPECT_EQ(c["ties"].get<uint64_t>() + c["near_ties"].get<uint64_t>(), c["differing"].get<uint64_t>())
            << c.dump();
    }
    for (const char* bad : {" --sun 0,0,0", " --sun 0,1,0 --light 0,5,0", " --sun 0,1,0 --area-light 0,9,0,1,4"}) {
        CliRun r = run_cli("render " + default_asset + " -o " + png + bad);
        EXPECT_EQ(r.code, 2) << bad;
    }
}

TEST(Render, OptionsAreCheckedBeforeAnyWork) {
    const fs::path dir = output_dir("errors");
    const std::string out = (dir / "out.png").string();
    auto refused = [&](const std::string& args, const std::string& says) {
        CliRun r = run_cli("render " + args);
        EXPECT_EQ(r.code, 2) << args;
        EXPECT_EQ(line_count(r.err), 1u) << args << ": " << r.err;
        EXPECT_NE(r.err.find(says), std::string::npos) << args << ": " << r.err;
        EXPECT_TRUE(r.out.empty()) << args;
        EXPECT_FALSE(fs::exists(out)) << args << " wrote the picture";
    };
    const std::string a = default_asset + " -o " + out;
    refused(a + " --light 1,2", "--light takes X,Y,Z");
    refused(a + " --light 1,2,3 --area-light 1,2,3,1,4", "give one");
    refused(a + " --area-shape disc", "--area-shape does nothing here");
    refused(a + " --area-light 1,2,3,0,4", "--area-light takes X,Y,Z,SIZE,N");
    refused(a + " --area-light 1,2,3,1,0", "--area-light takes X,Y,Z,SIZE,N");
    refused(a + " --area-light 1,2,3,1,5000", "--area-light takes X,Y,Z,SIZE,N");
    refused(a + " --area-light 1,2,3,1,4 --area-shape circle", "--area-shape");
    refused(a + " --size 8", "--size takes W or WxH");
    refused(a + " --size 100x", "--size takes W or WxH");
    refused(a + " --size 5000x100", "--size takes W or WxH");
    refused(a + " --fov 170", "--fov takes degrees");
    refused(a + " --aa 0", "--aa takes 1 to 4");
    refused(a + " --aa 5", "--aa takes 1 to 4");
    refused(a + " --size 4096x2048 --aa 2", "over 4096 x 4096 samples");
    refused(a + " --eye 1,2,3 --target 1,2,3", "no direction");
    refused(a + " --up 0,0,0", "--up must not be zero");
    refused(a + " --eye 1,nan,3", "--eye takes X,Y,Z");
    refused(a + " --threads x", "--threads");
    refused(a + " --frobnicate", "frobnicate");
    refused(default_asset + " -o " + (dir / "out.jpg").string(), "name it .png");
    refused(default_asset + " -o " + (dir / "no/such/folder/out.png").string(), "does not exist");
    refused(a + " --write-points " + default_asset, "--write-points would replace it");
    refused("/no/such/asset.cbk -o " + out, "/no/such/asset.cbk: cannot open");
    refused(std::string(CB_SOURCE_DIR) + "/README.md -o " + out, "README.md");

    // An existing file that is not a PNG is kept unless --force; a failed run leaves an old picture as it was.
    const std::string notes = (dir / "notes.png").string();
    std::ofstream(notes) << "not a picture\n";
    CliRun kept = run_cli("render " + default_asset + " -o " + notes + " -q");
    EXPECT_EQ(kept.code, 2);
    EXPECT_NE(kept.err.find("exists and is not a PNG"), std::string::npos) << kept.err;
    EXPECT_EQ(cb::test::slurp(notes), "not a picture\n");
    CliRun forced = run_cli("render " + default_asset + " -o " + notes + " --size 32 --force -q");
    EXPECT_EQ(forced.code, 0) << forced.err;
    EXPECT_EQ(read_png(notes).width, 32u);
    const std::string before = cb::test::slurp(notes);
    CliRun failed = run_cli("render /no/such/asset.cbk -o " + notes);
    EXPECT_EQ(failed.code, 2);
    EXPECT_EQ(cb::test::slurp(notes), before);
}

TEST(Render, SharedDragonHardAndSoft) {
    const fs::path dragon = fs::path(CB_SHARED_DATA) / "scanned/dragon_vrip_res3.ply";
    if (!fs::exists(dragon)) GTEST_SKIP() << "shared data absent: " << dragon;
    const fs::path dir = output_dir("dragon");
    const std::string asset = (dir / "dragon.cbk").string();
    ASSERT_EQ(run_cli("bake " + dragon.string() + " -o " + asset + " -q").code, 0);
    for (const std::string light : {"--light -0.17,0.43,0.057", "--area-light -0.17,0.43,0.057,0.1,16"}) {
        const std::string png = (dir / (light[2] == 'l' ? "hard.png" : "soft.png")).string();
        CliRun r = run_cli("render " + asset + " -o " + png + " --size 256x192 --compare --json -q " + light);
        ASSERT_EQ(r.code, 0) << r.err;
        const nlohmann::json j = nlohmann::json::parse(r.out);
        EXPECT_GT(j["pixels_covered"].get<uint64_t>(), 256u * 192u / 10);
        EXPECT_GT(j["shadowed"].get<uint64_t>(), 0u);
        EXPECT_GT(cb::test::grey_variance(read_png(png)), 50);
        // Embree's float rays part from the exact answers only in ties and near ties.
        EXPECT_EQ(j["compare"]["pixels_other"], 0) << j["compare"].dump();
    }
}

// The default scene's first picture: the 40 m ground is left out of the framing, so its objects fill the
// view; the default light is above the camera's side, so the sides seen are lit and the shadows fall on the
// ground in view.
TEST(Render, DefaultViewFramesTheObjectsAndLightsTheSideSeen) {
    const fs::path dir = output_dir("default_view");
    const std::string png = (dir / "default.png").string();
    CliRun r = run_cli("render " + default_asset + " -o " + png + " --json -q");
    ASSERT_EQ(r.code, 0) << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    std::printf("artefact: %s\n", png.c_str());
    EXPECT_EQ(j["ground_instances"], 1);
    const std::vector<double> lo = j["framed_box"]["lo"], hi = j["framed_box"]["hi"], light = j["light"],
                              eye = j["camera"]["eye"];
    EXPECT_LT(hi[0] - lo[0], 30) << "not the whole 40 m ground";
    EXPECT_LT(hi[2] - lo[2], 30);
    EXPECT_GT(hi[0] - lo[0], 17) << "every object: the fence and the colonnade span 17 m";
    EXPECT_GT(j["pixels_covered"].get<uint64_t>(), 640u * 480u / 2) << "the ground fills most of the view";
    double to_light[3], to_eye[3];
    for (int k = 0; k < 3; ++k) {
        to_light[k] = light[k] - 0.5 * (lo[k] + hi[k]);
        to_eye[k] = eye[k] - 0.5 * (lo[k] + hi[k]);
    }
    EXPECT_GT(cb::math::dot3(to_light, to_eye), 0) << "the light is on the camera's side";
    EXPECT_GT(light[1], hi[1]);
    const double fraction = j["shadowed_fraction"];
    EXPECT_GT(fraction, 0.005) << "shadows on the ground";
    EXPECT_LT(fraction, 0.05);
}

// --aa N: each pixel is the mean, in linear light, of the N x N samples a picture N times as wide and high
// has at its pixels' centres; the same picture on any number of threads.
TEST(Render, AntiAliasingAveragesTheSamplesOfAFinerPicture) {
    const fs::path dir = output_dir("aa");
    const std::string view = " --eye 6,5,12 --target -1,0.5,0 --fov 40 --light -4,12,2 -q";
    ASSERT_EQ(run_cli("render " + default_asset + " -o " + (dir / "aa2.png").string() + " --size 160x120" + view +
                      " --threads 1")
                  .code,
              0);
    ASSERT_EQ(run_cli("render " + default_asset + " -o " + (dir / "aa2_threads.png").string() +
                      " --size 160x120 --aa 2" + view + " --threads 2")
                  .code,
              0);
    ASSERT_EQ(
        run_cli("render " + default_asset + " -o " + (dir / "aa1.png").string() + " --size 160x120 --aa 1" + view).code,
        0);
    ASSERT_EQ(
        run_cli("render " + default_asset + " -o " + (dir / "fine.png").string() + " --size 320x240 --aa 1" + view)
            .code,
        0);
    std::printf("artefacts: %s/{aa1,aa2,fine}.png\n", dir.c_str());
    EXPECT_EQ(cb::test::slurp((dir / "aa2.png").string()), cb::test::slurp((dir / "aa2_threads.png").string()));
    const Rgb aa2 = read_png((dir / "aa2.png").string()), aa1 = read_png((dir / "aa1.png").string()),
              fine = read_png((dir / "fine.png").string());
    ASSERT_EQ(fine.width, 2 * aa2.width);
    auto linear = [](uint8_t c) { return std::pow(c / 255.0, 2.2); };
    int worst = 0;
    size_t blended = 0;  // pixels whose samples differ by more than a few levels: edges, smoothed
    for (uint32_t y = 0; y < aa2.height; ++y)
        for (uint32_t x = 0; x < aa2.width; ++x)
            for (int k = 0; k < 3; ++k) {
                double mean = 0;
                int lo = 255, hi = 0;
                for (uint32_t s = 0; s < 4; ++s) {
                    const uint8_t c = fine.pixels[(size_t(2 * y + s / 2) * fine.width + 2 * x + s % 2) * 3 + k];
                    mean += linear(c) / 4;
                    lo = std::min<int>(lo, c);
                    hi = std::max<int>(hi, c);
                }
                const int expected = int(std::lround(255 * std::pow(mean, 1 / 2.2)));
                // The background's rows are those of the coarse picture: a level apart at most.
                worst = std::max(worst, std::abs(int(aa2.pixels[(size_t(y) * aa2.width + x) * 3 + k]) - expected));
                blended += k == 0 && hi - lo > 16;
            }
    EXPECT_LE(worst, 2);
    EXPECT_GT(blended, 200u);
    EXPECT_NE(aa1.pixels, aa2.pixels);
}

// --ground: a plane under an object alone takes its shadow. The ground is drawn and asked as part of the
// level: the picture's answers are clusterbake query's on the asset alone (a ground under every point does
// not block a light above it), and Embree's over the same level.
TEST(Render, GroundPlaneTakesTheObjectsShadow) {
    const fs::path dir = output_dir("ground");
    const std::string cube = (dir / "cube.cbk").string(), points = (dir / "points.txt").string();
    ASSERT_EQ(run_cli("bake " + std::string(CB_SOURCE_DIR) + "/data/small/cube.obj -o " + cube + " -q").code, 0);
    CliRun bare = run_cli("render " + cube + " -o " + (dir / "bare.png").string() + " --size 200x150 --json -q");
    CliRun r = run_cli("render " + cube + " -o " + (dir / "ground.png").string() +
                       " --size 200x150 --ground --compare --json -q --write-points " + points);
    ASSERT_EQ(bare.code, 0) << bare.err;
    ASSERT_EQ(r.code, 0) << r.err;
    std::printf("artefacts: %s/{bare,ground,ground.compare}.png\n", dir.c_str());
    const nlohmann::json j = nlohmann::json::parse(r.out), b = nlohmann::json::parse(bare.out);
    EXPECT_EQ(j["ground"], true);
    EXPECT_EQ(j["light"], b["light"]) << "the ground changes neither the camera nor the light";
    EXPECT_EQ(j["bias"], b["bias"]) << "nor the bias";
    EXPECT_GT(j["points"].get<uint64_t>(), 2 * b["points"].get<uint64_t>());
    EXPECT_EQ(j["compare"]["pixels_other"], 0) << j["compare"].dump();

    CliRun q = run_cli("query " + cube + " --light " + light_text(j["light"]) + " --points " + points);
    ASSERT_EQ(q.code, 0) << q.err;
    const std::vector<double> lo = j["framed_box"]["lo"];
    std::istringstream answers(q.out), xyz(cb::test::slurp(points));
    uint64_t shadowed = 0, ground_shadowed = 0, ground_lit = 0;
    double p[3];
    for (int answer; answers >> answer && xyz >> p[0] >> p[1] >> p[2];) {
        shadowed += answer;
        if (p[1] < lo[1]) (answer ? ground_shadowed : ground_lit) += 1;
    }
    EXPECT_EQ(shadowed, j["shadowed"].get<uint64_t>());
    EXPECT_GT(ground_shadowed, 500u) << "the cube's shadow on the ground";
    EXPECT_GT(ground_lit, 2 * ground_shadowed);
}

// A scanned statue as a new user first renders it: the default light lights what the camera sees; with
// --ground and its own up, its shadow lies on the ground.
TEST(Render, SharedStatueIsLitAndCastsAShadow) {
    const fs::path horse = fs::path(CB_SHARED_DATA) / "scanned/horse.ply";
    if (!fs::exists(horse)) GTEST_SKIP() << "shared data absent: " << horse;
    const fs::path dir = output_dir("statue");
    const std::string asset = (dir / "horse.cbk").string();
    ASSERT_EQ(run_cli("bake " + horse.string() + " -o " + asset + " -q").code, 0);
    CliRun plain = run_cli("render " + asset + " -o " + (dir / "horse.png").string() + " --json -q");
    CliRun ground = run_cli("render " + asset + " -o " + (dir / "horse_ground.png").string() +
                            " --up 0,0,1 --ground --compare --json -q");
    ASSERT_EQ(plain.code, 0) << plain.err;
    ASSERT_EQ(ground.code, 0) << ground.err;
    std::printf("artefacts: %s/{horse,horse_ground}.png\n", dir.c_str());
    const nlohmann::json p = nlohmann::json::parse(plain.out), g = nlohmann::json::parse(ground.out);
    EXPECT_LT(p["shadowed_fraction"].get<double>(), 0.4) << "not a dark silhouette";
    EXPECT_GT(p["shadowed_fraction"].get<double>(), 0.02) << "the legs shadow the body";
    EXPECT_GT(g["shadowed_fraction"].get<double>(), 0.03);
    EXPECT_EQ(g["compare"]["pixels_other"], 0) << g["compare"].dump();
    EXPECT_GT(cb::test::grey_variance(read_png((dir / "horse_ground.png").string())), 50);
}
