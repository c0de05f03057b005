// Meshes far from the world origin: every loader stores a mesh relative to an origin of its own
// (mesh_frame.h) and its instances carry it, so world positions keep float precision relative to the
// mesh's size, degenerate counts do not depend on where the mesh lies, and shadow answers stay exact.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "baked.h"
#include "gltf_writer.h"
#include "load.h"
#include "scene_oracle.h"
#include "scene_query.h"

namespace {

namespace fs = std::filesystem;

// A triangle mesh in double, as the tests write it out.
struct Source {
    std::vector<double> xyz;
    std::vector<uint32_t> tri;

    double size() const {
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (size_t i = 0; i < xyz.size(); ++i) {
            lo[i % 3] = std::min(lo[i % 3], xyz[i]);
            hi[i % 3] = std::max(hi[i % 3], xyz[i]);
        }
        return std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
    }
    std::array<double, 3> centre() const {
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (size_t i = 0; i < xyz.size(); ++i) {
            lo[i % 3] = std::min(lo[i % 3], xyz[i]);
            hi[i % 3] = std::max(hi[i % 3], xyz[i]);
        }
        return {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
    }
};

const double offsets[] = {1e3, 1e5, 1e7};

// The v and f lines of a triangle OBJ (indices before any '/').
bool read_obj(const fs::path& path, Source& s) {
    std::ifstream in(path);
    if (!in) return false;
    std::string line;
    while (std::getline(in, line)) {
        if (line.rfind("v ", 0) == 0) {
            double v[3];
            if (std::sscanf(line.c_str() + 2, "%lf %lf %lf", &v[0], &v[1], &v[2]) == 3)
                s.xyz.insert(s.xyz.end(), v, v + 3);
        } else if (line.rfind("f ", 0) == 0) {
            unsigned a, b, c;
            if (std::sscanf(line.c_str() + 2, "%u%*[^ ] %u%*[^ ] %u", &a, &b, &c) == 3 ||
                std::sscanf(line.c_str() + 2, "%u %u %u", &a, &b, &c) == 3)
                s.tri.insert(s.tri.end(), {a - 1, b - 1, c - 1});
        }
    }
    return !s.tri.empty();
}

// A bumpy terrain of 40 x 40 cells, 100 units across, on coordinates that are not floats (steps of 0.1).
Source terrain() {
    Source s;
    const int n = 40;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
            double x = i * 2.5 + 0.1, y = j * 2.5 - 0.3;
            double z =
                std::round(40 * (std::sin(x * 0.21) * std::cos(y * 0.17) + 0.3 * std::sin(x * 0.05 + y * 0.07))) / 10;
            s.xyz.insert(s.xyz.end(), {x, y, z});
        }
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            uint32_t a = uint32_t(j * (n + 1) + i), b = a + 1, c = a + n + 1, d = c + 1;
            s.tri.insert(s.tri.end(), {a, b, d, a, d, c});
        }
    return s;
}

// Every coordinate plus `offset` (each axis), in double.
Source moved(const Source& s, const std::array<double, 3>& offset) {
    Source m = s;
    for (size_t i = 0; i < m.xyz.size(); ++i) m.xyz[i] += offset[i % 3];
    return m;
}
Source moved(const Source& s, double offset) { return moved(s, {offset, offset, offset}); }

std::string obj_text(const Source& s) {
    std::string out;
    char buf[128];
    for (size_t v = 0; v < s.xyz.size(); v += 3) {
        std::snprintf(buf, sizeof buf, "v %.17g %.17g %.17g\n", s.xyz[v], s.xyz[v + 1], s.xyz[v + 2]);
        out += buf;
    }
    for (size_t t = 0; t < s.tri.size(); t += 3) {
        std::snprintf(buf, sizeof buf, "f %u %u %u\n", s.tri[t] + 1, s.tri[t + 1] + 1, s.tri[t + 2] + 1);
        out += buf;
    }
    return out;
}

// Binary little-endian PLY with float32 x, y, z: float(coordinate) is what the file holds.
std::string ply_float_binary(const Source& s) {
    std::string out = "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(s.xyz.size() / 3) +
        "\nproperty float x\nproperty float y\nproperty float z\nelement face " + std::to_string(s.tri.size() / 3) +
        "\nproperty list uchar int vertex_indices\nend_header\n";
    for (double v : s.xyz) {
        float f = float(v);
        out.append(reinterpret_cast<const char*>(&f), 4);
    }
    for (size_t t = 0; t < s.tri.size(); t += 3) {
        out.push_back(3);
        out.append(reinterpret_cast<const char*>(&s.tri[t]), 12);
    }
    return out;
}

cb::Scene load(const std::string& bytes, cb::FileFormat format) {
    return cb::load_mesh_memory(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), format, "t");
}

// World positions of a one-instance scene, as the runtime places them (double).
std::vector<double> world_positions(const cb::Scene& s) {
    std::vector<double> out;
    const cb::Instance& inst = s.instances.at(0);
    const cb::Mesh& m = s.meshes[inst.mesh];
    for (size_t v = 0; v < m.vertex_count(); ++v) {
        auto w = cb::transform_point(inst.world, m.positions[v * 3], m.positions[v * 3 + 1], m.positions[v * 3 + 2]);
        out.insert(out.end(), w.begin(), w.end());
    }
    return out;
}

double max_error(const std::vector<double>& a, const std::vector<double>& b) {
    double e = 0;
    for (size_t i = 0; i < a.size(); ++i) e = std::max(e, std::fabs(a[i] - b[i]));
    return e;
}

double max_magnitude(const std::vector<float>& v) {
    double m = 0;
    for (float x : v) m = std::max(m, double(std::fabs(x)));
    return m;
}

fs::path shared(const char* file) { return fs::path(CB_SHARED_DATA) / file; }

// The real mesh for the tests that move one: the bunny, or nothing when ../shared/data is absent.
bool bunny(Source& s) { return read_obj(shared("scanned/bunny_npm.obj"), s); }

// Text keeps float precision relative to the mesh's size, and the mesh's degenerate count.
void check_text(const Source& base, const char* what) {
    SCOPED_TRACE(what);
    const double size = base.size();
    const cb::Scene near = load(obj_text(base), cb::FileFormat::obj);
    for (double offset : offsets) {
        SCOPED_TRACE(offset);
        Source far = moved(base, offset);
        cb::Scene s = load(obj_text(far), cb::FileFormat::obj);
        ASSERT_EQ(s.meshes[0].vertex_count() * 3, far.xyz.size());
        // float(x - centre): half a float step of the mesh's half size, plus the double sums.
        double error = max_error(world_positions(s), far.xyz);
        EXPECT_LE(error, size * std::ldexp(1.0, -24)) << "max world error " << error;
        EXPECT_LE(max_magnitude(s.meshes[0].positions), size);  // stored relative to the mesh
        EXPECT_EQ(s.report.degenerate_triangles, near.report.degenerate_triangles);
        std::printf("[ origin ] %s at %g: max world error %.3g (size %.4g), degenerate %llu\n", what, offset, error,
                    size, (unsigned long long)s.report.degenerate_triangles);
    }
}

}  // namespace

TEST(Origin, TextKeepsPrecisionFarAway) {
    check_text(terrain(), "terrain");
    Source b;
    if (!bunny(b)) GTEST_SKIP() << "../shared/data is absent: the bunny was not moved";
    check_text(b, "bunny_npm");
}

TEST(Origin, FloatInputsAreStoredExactly) {
    Source base = terrain();
    const double size = base.size();
    for (double offset : {0.0, 1e3, 1e5, 1e7}) {
        SCOPED_TRACE(offset);
        Source far = moved(base, offset);
        cb::Scene s = load(ply_float_binary(far), cb::FileFormat::ply);
        // The file's floats, exactly, in world space.
        std::vector<double> file(far.xyz.size());
        for (size_t i = 0; i < file.size(); ++i) file[i] = double(float(far.xyz[i]));
        EXPECT_EQ(world_positions(s), file);
        if (offset >= 1e5) {
            EXPECT_LE(max_magnitude(s.meshes[0].positions), size);
        }
    }
}

TEST(Origin, GltfInstancesShareOneOffsetPerMesh) {
    cb::data::MeshData m;
    Source base = terrain();
    for (double v : moved(base, {1e7, -2.5e6, 3e5}).xyz) m.positions.push_back(float(v));
    m.indices = base.tri;
    cb::data::GltfWriter w;
    w.mesh("far", m, -1);
    w.node({{"mesh", 0}, {"translation", {5, 0, 0}}});
    w.node({{"mesh", 0}, {"rotation", {0, 0, std::sqrt(0.5), std::sqrt(0.5)}}, {"scale", {2, 2, 2}}});
    w.doc["scenes"] = cb::data::json::array({{{"nodes", {0, 1}}}});
    w.doc["scene"] = 0;
    std::vector<uint8_t> glb = w.glb();
    cb::Scene s = cb::load_gltf_memory(glb.data(), glb.size(), "t.glb", "");
    ASSERT_EQ(s.meshes.size(), 1u);
    ASSERT_EQ(s.instances.size(), 2u);
    EXPECT_LE(max_magnitude(s.meshes[0].positions), base.size());
    const cb::Transform nodes[2] = {{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 5, 0, 0, 1},
                                    {0, 2, 0, 0, -2, 0, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1}};
    for (size_t i = 0; i < 2; ++i) {
        SCOPED_TRACE(i);
        const cb::Transform& world = s.instances[i].world;
        for (int k = 0; k < 12; ++k) EXPECT_NEAR(world[k], nodes[i][k], 1e-15);  // the node's axes
        // The node's transform of the file's floats, to double rounding of 2e7.
        double error = 0;
        for (size_t v = 0; v < s.meshes[0].vertex_count(); ++v) {
            const float* p = &s.meshes[0].positions[v * 3];
            auto got = cb::transform_point(world, p[0], p[1], p[2]);
            auto want =
                cb::transform_point(nodes[i], m.positions[v * 3], m.positions[v * 3 + 1], m.positions[v * 3 + 2]);
            for (int k = 0; k < 3; ++k) error = std::max(error, std::fabs(got[k] - want[k]));
        }
        EXPECT_LE(error, 1e-8);
    }
}

// Float inputs near the origin load as before: world positions, as floats, are the same bits (FNV-1a over
// every instance's vertices), and so are the degenerate counts. The hashes were taken with the loader that
// stored every mesh in its file's frame.
TEST(Origin, FloatInputsNearTheOriginAreUnchanged) {
    struct Golden {
        const char* file;
        uint64_t hash;
        bool shared;
    };
    const Golden golden[] = {
        {"data/default_scene.glb", 0xceed10c18c020212ULL, false},
        {"data/small/cube_binary.ply", 0x18e54acb0a83d843ULL, false},
        {"data/small/cube_binary.stl", 0xc2c72570f09b8643ULL, false},
        {"data/small/primitive_modes.gltf", 0xf7ac28d55262d383ULL, false},
        {"gltf/CesiumMilkTruck_draco.glb", 0xf73e3b01b7b8ec1bULL, true},
        {"gltf/CesiumMilkTruck/CesiumMilkTruck.gltf", 0x80b4e73f6b637f75ULL, true},
        {"gltf/CubeScaledInstances/cube_att.gltf", 0xb544ec2e34c1fe93ULL, true},
        {"gltf/SpheresScaledInstances/spheres_scaled_instances.gltf", 0xa02baa153840e82fULL, true},
        {"gltf/TestScene/TestScene.gltf", 0xc224f4e7dddabe91ULL, true},
        {"gltf/many-cubes/many-cubes.gltf", 0x1346d860a9b4013fULL, true},
        {"gltf/Duck.glb", 0x221080066ab74cbaULL, true},
        {"scanned/horse.ply", 0xeb2e967264d0ad21ULL, true},
        {"scanned/dragon_vrip_res2_binary.ply", 0x0c9811854f80159fULL, true},
        {"scanned/bunny.stl", 0x7e97d33380dc6c03ULL, true},
        {"hard/featuretype.STL", 0x7e0b68d944f7cbfdULL, true},
        {"hard/large_block.STL", 0x01933b1731248075ULL, true},
        {"hard/mode5.gltf", 0x62a92fbabbe76152ULL, true},
    };
    size_t skipped = 0;
    for (const Golden& g : golden) {
        SCOPED_TRACE(g.file);
        fs::path path = g.shared ? shared(g.file) : fs::path(CB_SOURCE_DIR) / g.file;
        if (g.shared && !fs::exists(path)) {
            ++skipped;
            continue;
        }
        cb::Scene s = cb::load_scene(path.string());
        uint64_t h = 1469598103934665603ULL;
        for (const cb::Instance& inst : s.instances) {
            const cb::Mesh& m = s.meshes[inst.mesh];
            for (size_t v = 0; v < m.vertex_count(); ++v)
                for (double x : cb::transform_point(inst.world, m.positions[v * 3], m.positions[v * 3 + 1],
                                                    m.positions[v * 3 + 2])) {
                    float f = float(x);
                    uint32_t b;
                    std::memcpy(&b, &f, 4);
                    for (int i = 0; i < 4; ++i) h = (h ^ ((b >> (8 * i)) & 0xff)) * 1099511628211ULL;
                }
        }
        EXPECT_EQ(h, g.hash);
        EXPECT_EQ(s.report.degenerate_triangles, 0u);
    }
    if (skipped) GTEST_SKIP() << "../shared/data is absent: " << skipped << " shared files not checked";
}

// The default scene's asset places every vertex where the scene does: its instances and positions give the
// same world vertices as the loaded scene, whose bits FloatInputsNearTheOriginAreUnchanged checks.
TEST(Origin, DefaultSceneAssetKeepsWorldGeometry) {
    cb::test::Baked b = cb::test::bake(std::string(CB_SOURCE_DIR) + "/data/default_scene.glb");
    ASSERT_GT(b.view.mesh_count, 0u);
    std::vector<std::array<double, 3>> from_asset, from_scene;
    for (uint32_t i = 0; i < b.view.instance_count; ++i) {
        const cb::InstanceRecord& inst = b.view.instances[i];
        const cb::MeshRecord& m = b.view.meshes[inst.mesh];
        for (uint32_t v = 0; v < m.vertex_count; ++v) {
            const float* p = b.view.positions + size_t(m.first_vertex + v) * 3;
            double local[3] = {p[0], p[1], p[2]}, w[3];
            cb::apply_instance(inst.transform, local, w);
            from_asset.push_back({w[0], w[1], w[2]});
        }
    }
    for (const cb::Instance& inst : b.scene.instances) {
        const cb::Mesh& m = b.scene.meshes[inst.mesh];
        for (size_t v = 0; v < m.vertex_count(); ++v)
            from_scene.push_back(
                cb::transform_point(inst.world, m.positions[v * 3], m.positions[v * 3 + 1], m.positions[v * 3 + 2]));
    }
    std::sort(from_asset.begin(), from_asset.end());
    std::sort(from_scene.begin(), from_scene.end());
    from_asset.erase(std::unique(from_asset.begin(), from_asset.end()), from_asset.end());
    from_scene.erase(std::unique(from_scene.begin(), from_scene.end()), from_scene.end());
    EXPECT_EQ(from_asset, from_scene);
}

// The real terrain sits at x ~ 85,000, y ~ 447,000. Stored in its file's frame, float rounding there made
// 123 of its triangles degenerate; centred in double, it has 2 (the shared data's README counts 3 in double
// on the decimal coordinates: one exactly collinear triple is not collinear after rounding to float), and
// keeps that count wherever it is moved.
TEST(Origin, TerrainKeepsItsDegenerateCount) {
    Source real;
    if (!read_obj(shared("hard/3dfier_testarea/testarea.obj"), real))
        GTEST_SKIP() << "../shared/data is absent: the 3dfier terrain was not moved";
    cb::Scene as_is = cb::load_scene(shared("hard/3dfier_testarea/testarea.obj").string());
    EXPECT_EQ(as_is.report.degenerate_triangles, 2u);
    std::array<double, 3> c = real.centre();
    Source centred = moved(real, {-c[0], -c[1], -c[2]});
    for (double offset : {0.0, 1e3, 1e5, 1e7}) {
        SCOPED_TRACE(offset);
        Source far = moved(centred, offset);
        cb::Scene s = load(obj_text(far), cb::FileFormat::obj);
        EXPECT_EQ(s.report.degenerate_triangles, as_is.report.degenerate_triangles);
        double error = max_error(world_positions(s), far.xyz);
        EXPECT_LE(error, real.size() * std::ldexp(1.0, -24));
        std::printf("[ origin ] 3dfier at %g: max world error %.3g, degenerate %llu\n", offset, error,
                    (unsigned long long)s.report.degenerate_triangles);
    }
}

namespace {

// Points whose segment to the light crosses a triangle of the source well inside it (at the centroid of a
// triangle whose inradius is at least 0.2% of the mesh size), just behind or far behind, and as many points
// half way from such a centroid to the light.
std::vector<double> probe_points(const Source& s, const double* light, size_t n) {
    std::vector<double> out;
    const double size = s.size();
    for (size_t t = 0; t < s.tri.size() / 3 && out.size() < n * 3; t += 7) {
        const double* v[3];
        double c[3] = {0, 0, 0};
        for (int k = 0; k < 3; ++k) {
            v[k] = &s.xyz[size_t(s.tri[t * 3 + k]) * 3];
            for (int j = 0; j < 3; ++j) c[j] += v[k][j] / 3;
        }
        double u[3], w[3], perimeter = 0;
        for (int j = 0; j < 3; ++j) {
            u[j] = v[1][j] - v[0][j];
            w[j] = v[2][j] - v[0][j];
        }
        double area2 = std::hypot(u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]);
        for (int k = 0; k < 3; ++k) {
            const double *a = v[k], *b = v[(k + 1) % 3];
            perimeter += std::hypot(b[0] - a[0], b[1] - a[1], b[2] - a[2]);
        }
        if (!(area2 / perimeter > 0.002 * size)) continue;
        for (double f : {1.0 / 64, 1.0, -0.5})
            for (int j = 0; j < 3; ++j) out.push_back(c[j] + f * (c[j] - light[j]));
    }
    return out;
}

// Shadow answers on a baked asset of the mesh moved by each offset: the runtime's (through query_scene,
// as `clusterbake query` asks) against the exact oracle on the loaded scene, every point behind a
// triangle's centroid in shadow, and the same answers wherever the mesh is.
// A float file holds float(coordinate), which at 1e7 is a coarser mesh: its answers are checked against
// the oracle only, with points made from the floats.
void check_shadows(const Source& base, const char* what, cb::FileFormat format) {
    SCOPED_TRACE(what);
    std::vector<uint8_t> first;
    for (double offset : {0.0, 1e3, 1e5, 1e7}) {
        SCOPED_TRACE(offset);
        Source far = moved(base, offset);
        if (format != cb::FileFormat::obj)
            for (double& x : far.xyz) x = double(float(x));
        std::array<double, 3> c = far.centre();
        const double size = base.size();
        double light[3] = {c[0] + 0.3 * size, c[1] + 0.2 * size, c[2] + 2 * size};
        std::vector<double> points = probe_points(far, light, 300);
        cb::Scene scene = load(format == cb::FileFormat::obj ? obj_text(far) : ply_float_binary(far), format);
        cb::test::Baked baked = cb::test::bake_scene(scene);
        ASSERT_GT(baked.view.mesh_count, 0u);
        cb::SceneQueryResult r = cb::query_scene(baked.view, light, points.data(), points.size() / 3);
        cb::test::SceneOracle oracle(scene, r.bias);
        size_t differ = 0, behind_lit = 0;
        for (size_t i = 0; i < points.size() / 3; ++i) {
            differ += r.shadowed[i] != oracle.occluded(&points[i * 3], light, false).blocked;
            behind_lit += i % 3 != 2 && !r.shadowed[i];
        }
        EXPECT_EQ(differ, 0u);
        EXPECT_EQ(behind_lit, 0u);
        if (format != cb::FileFormat::obj) continue;
        if (first.empty())
            first = r.shadowed;
        else
            EXPECT_EQ(r.shadowed, first);
    }
}

}  // namespace

TEST(Origin, ShadowAnswersFarAway) {
    check_shadows(terrain(), "terrain obj", cb::FileFormat::obj);
    check_shadows(terrain(), "terrain float ply", cb::FileFormat::ply);
    Source b;
    if (!bunny(b)) GTEST_SKIP() << "../shared/data is absent: the bunny was not moved";
    check_shadows(b, "bunny_npm obj", cb::FileFormat::obj);
}
