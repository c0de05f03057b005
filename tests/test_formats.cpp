// OBJ, OFF, PLY and STL loading: features, the generated cubes in data/small, and broken input.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <limits>
#include <fstream>

#include "load.h"
#include "scene_info.h"

namespace {

cb::Scene load(const std::string& text, cb::FileFormat format) {
    return cb::load_mesh_memory(reinterpret_cast<const uint8_t*>(text.data()), text.size(), format, "t");
}

std::string error_of(const std::string& text, cb::FileFormat format) {
    try {
        load(text, format);
    } catch (const cb::LoadError& e) {
        std::string what = e.what();
        EXPECT_EQ(what.find('\n'), std::string::npos) << what;
        EXPECT_EQ(what.rfind("t: ", 0), 0u) << what;
        return what;
    }
    ADD_FAILURE() << "loaded a broken file";
    return "";
}

std::string read_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

}  // namespace

TEST(Formats, GeneratedCubesAgreeAcrossFormats) {
    const char* files[] = {"cube.obj",        "cube.off",       "cube_ascii.ply",
                           "cube_binary.ply", "cube_ascii.stl", "cube_binary.stl"};
    for (const char* f : files) {
        SCOPED_TRACE(f);
        cb::Scene s = cb::load_scene(std::string(CB_SOURCE_DIR) + "/data/small/" + f);
        cb::SceneInfo info = cb::describe(s);
        EXPECT_EQ(info.unique_triangles, 12u);
        EXPECT_EQ(info.degenerate_triangles, 0u);
        EXPECT_EQ(info.world_min, (std::array<double, 3>{-1, -1, -1}));
        EXPECT_EQ(info.world_max, (std::array<double, 3>{1, 1, 1}));
        // Every face is wound outward: the signed volume of the closed cube is +8.
        const cb::Mesh& m = s.meshes[0];
        double volume = 0;
        for (size_t t = 0; t < m.triangle_count(); ++t) {
            const float* a = &m.positions[m.indices[t * 3] * 3];
            const float* b = &m.positions[m.indices[t * 3 + 1] * 3];
            const float* c = &m.positions[m.indices[t * 3 + 2] * 3];
            volume += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
                       a[2] * (b[0] * c[1] - b[1] * c[0])) /
                6.0;
        }
        EXPECT_NEAR(volume, 8.0, 1e-9);
    }
}

TEST(Formats, ObjFeatures) {
    // Polygons, v/vt/vn references, negative indices, line continuations, comments, a repeated index.
    cb::Scene s = load(
        "# c\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 \\\n 0\nvt 0 0\nvn 0 0 1\n"
        "f 1/1/1 2/1/1 3/1/1 4/1/1\nf -4//1 -3//1 -2//1\nf 1 1 3\n",
        cb::FileFormat::obj);
    const cb::Mesh& m = s.meshes[0];
    EXPECT_EQ(m.vertex_count(), 4u);
    EXPECT_EQ(std::vector<uint32_t>(m.indices.begin(), m.indices.end()),
              (std::vector<uint32_t>{0, 1, 2, 0, 2, 3, 0, 1, 2, 0, 0, 2}));
    EXPECT_EQ(s.report.degenerate_triangles, 1u);
}

TEST(Formats, ObjErrorsNameTheLine) {
    EXPECT_EQ(error_of("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", cb::FileFormat::obj),
              "t: line 4: face index 9 out of range (3 vertices)");
    EXPECT_EQ(error_of("v 0 0 0\nv nan 0 0\n", cb::FileFormat::obj),
              "t: line 2: vertex 2: position is not a finite float (nan)");
    EXPECT_EQ(error_of("v 0 0 1e39\n", cb::FileFormat::obj).find("t: line 1: vertex 1: position is not a finite float"),
              0u);
    EXPECT_EQ(error_of("v 0 0 x\n", cb::FileFormat::obj), "t: line 1: bad coordinate 'x'");
    EXPECT_EQ(error_of("v 0 0 0\nf 1 0 1\n", cb::FileFormat::obj), "t: line 2: face index 0 out of range (1 vertices)");
    EXPECT_EQ(error_of("v 0 0 0\nf 1 1\n", cb::FileFormat::obj), "t: line 2: face with 2 vertices");
    EXPECT_EQ(error_of("", cb::FileFormat::obj), "t: empty file");
    EXPECT_EQ(error_of("hello\n", cb::FileFormat::obj), "t: no vertices or faces (not an OBJ file?)");
}

TEST(Formats, OffVariants) {
    // Counts on the header line, comments everywhere, face colours after the indices.
    cb::Scene s = load("OFF 4 2 0 # counts\n0 0 0\n1 0 0 # a vertex\n1 1 0\n0 1 0\n3 0 1 2 1.0 0.0 0.0\n3 0 2 3\n",
                       cb::FileFormat::off);
    EXPECT_EQ(s.meshes[0].triangle_count(), 2u);
    EXPECT_EQ(
        load("COFF\n3 1 0\n0 0 0 255 0 0 255\n1 0 0 255 0 0 255\n0 1 0 255 0 0 255\n3 0 1 2\n", cb::FileFormat::off)
            .meshes[0]
            .triangle_count(),
        1u);
}

TEST(Formats, OffErrors) {
    EXPECT_EQ(error_of("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", cb::FileFormat::off),
              "t: line 6: face 0: index '3' out of range (3 vertices)");
    EXPECT_EQ(error_of("OFF\n3 1 0\n0 0 0\n1 0 0\n", cb::FileFormat::off), "t: truncated: 2 of 3 vertices");
    EXPECT_EQ(error_of("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", cb::FileFormat::off),
              "t: truncated: 1 of 2 faces");
    EXPECT_EQ(error_of("OFF\n1000000000 1 0\n", cb::FileFormat::off).find("t: counts 1000000000 vertices"), 0u);
    EXPECT_EQ(error_of("PLY\n", cb::FileFormat::off), "t: line 1: not an OFF header 'PLY'");
    EXPECT_EQ(error_of("OFF\n1 0 0\ninf 0 0\n", cb::FileFormat::off),
              "t: line 3: vertex 0: position is not a finite float (inf)");
}

TEST(Formats, PlyAndStlErrors) {
    std::string ply = read_file(std::string(CB_SOURCE_DIR) + "/data/small/cube_binary.ply");
    for (size_t cut : {size_t(0), size_t(10), ply.size() / 2, ply.size() - 3}) {
        SCOPED_TRACE(cut);
        try {
            cb::Scene s = load(ply.substr(0, cut), cb::FileFormat::ply);
            // OpenMesh may accept a cut file as long as what it produced is consistent; it never may
            // produce more than the file holds.
            EXPECT_LE(s.meshes[0].triangle_count(), 12u);
        } catch (const cb::LoadError&) {}
    }
    EXPECT_THROW(load("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n3 0 1 2\n",
                      cb::FileFormat::ply),
                 cb::LoadError);
    EXPECT_THROW(load("solid x\n facet normal 0 0 0\n outer loop\n vertex 0 0 nan\n vertex 1 0 0\n vertex 0 1 0\n"
                      " endloop\n endfacet\nendsolid x\n",
                      cb::FileFormat::stl),
                 cb::LoadError);
    EXPECT_THROW(load("", cb::FileFormat::stl), cb::LoadError);
}

TEST(Formats, StlThatIsNeitherKindIsNotAnEmptyMesh) {
    EXPECT_EQ(error_of("hello world\n", cb::FileFormat::stl),
              "t: not an STL file: neither binary STL (at least 84 bytes) nor ASCII STL (starts with 'solid')");
    std::string binary(84 + 50, '\0');
    binary[80] = 2;  // two facets in the header, one in the file
    EXPECT_EQ(error_of(binary, cb::FileFormat::stl),
              "t: not an STL file: neither binary STL (its header's 2 facets need 184 bytes, it has 134) nor ASCII STL "
              "(starts with 'solid')");
    binary[80] = 1;
    const float corners[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    std::memcpy(&binary[84 + 12], corners, sizeof corners);
    EXPECT_EQ(load(binary, cb::FileFormat::stl).meshes[0].triangle_count(), 1u);
    EXPECT_EQ(load("  solid empty\nendsolid empty\n", cb::FileFormat::stl).meshes[0].triangle_count(), 0u);
}

TEST(Formats, PlyFeatures) {
    // Big-endian binary with a double coordinate, an extra property, and tristrips with a restart.
    std::string ply =
        "ply\nformat binary_big_endian 1.0\ncomment made by hand\nelement vertex 4\nproperty double x\n"
        "property float y\nproperty float z\nproperty uchar red\nelement tristrips 1\n"
        "property list int int vertex_indices\nend_header\n";
    auto be32 = [&](uint32_t v) {
        for (int i = 3; i >= 0; --i) ply.push_back(char(v >> (8 * i)));
    };
    auto bef = [&](float f) {
        uint32_t v;
        std::memcpy(&v, &f, 4);
        be32(v);
    };
    auto bed = [&](double d) {
        uint64_t v;
        std::memcpy(&v, &d, 8);
        for (int i = 7; i >= 0; --i) ply.push_back(char(v >> (8 * i)));
    };
    float xyz[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
    for (auto& p : xyz) {
        bed(p[0]);
        bef(p[1]);
        bef(p[2]);
        ply.push_back(7);
    }
    int strip[] = {0, 1, 2, 3, -1, 0, 1, 2};
    be32(8);
    for (int i : strip) be32(uint32_t(i));
    cb::Scene s = load(ply, cb::FileFormat::ply);
    const cb::Mesh& m = s.meshes[0];
    // A double coordinate: the mesh is centred on its box, and its instance puts it back.
    auto world = cb::transform_point(s.instances[0].world, m.positions[9], m.positions[10], m.positions[11]);
    EXPECT_EQ(world, (std::array<double, 3>{1, 1, 0}));
    EXPECT_EQ(m.positions[3 * 3 + 0], 0.5f);
    // 0 1 2 3 gives (0,1,2) and (2,1,3); after the restart 0 1 2 gives (0,1,2).
    EXPECT_EQ(std::vector<uint32_t>(m.indices.begin(), m.indices.end()),
              (std::vector<uint32_t>{0, 1, 2, 2, 1, 3, 0, 1, 2}));
}

TEST(Formats, PlyErrors) {
    const std::string head =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    EXPECT_EQ(error_of(head + "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", cb::FileFormat::ply),
              "t: face 0: index 3.000000 out of range (3 vertices)");
    EXPECT_EQ(error_of(head + "0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n", cb::FileFormat::ply),
              "t: vertex 1: position is not a finite float (nan)");
    EXPECT_EQ(error_of(head + "0 0 0\n1 0 0\n", cb::FileFormat::ply), "t: vertex 2: unexpected end of data");
    EXPECT_EQ(error_of("ply\nformat ascii 1.0\nelement vertex 3\n", cb::FileFormat::ply),
              "t: header has no end_header (truncated?)");
    EXPECT_EQ(error_of("ply\nproperty float x\nend_header\n", cb::FileFormat::ply),
              "t: line 2: property before any element");
    EXPECT_EQ(error_of("ply\nformat ascii 1.0\nelement vertex 99999999\nproperty float x\nproperty float y\nproperty "
                       "float z\nend_header\n0 0 0\n",
                       cb::FileFormat::ply),
              "t: element vertex: count 99999999 exceeds the data (truncated?)");
    // Found by fuzz_ply: an element without properties but a count near 2^63 must not spin for ever.
    cb::Scene s = load(
        "ply\nformat ascii 1.0\nelement junk 6148914691236517209\nelement vertex 3\nproperty float x\n"
        "property float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n",
        cb::FileFormat::ply);
    EXPECT_EQ(s.meshes[0].vertex_count(), 3u);
    // Binary garbage in an error message is made printable.
    std::string bad = head + std::string("0 0 0\n1 0 \x01\x02zz\n0 1 0\n3 0 1 2\n");
    EXPECT_EQ(error_of(bad, cb::FileFormat::ply), "t: vertex 1: '??zz' is not a number");
}

namespace {

// A binary PLY of float vertices (with a normal and a colour beside x, y, z) and faces of the given sizes,
// with an element of no interest between them: little-endian, which the fast reader takes, and the same
// values big-endian, which only the general reader reads.
struct PlyPair {
    std::string little, big;
};

PlyPair ply_pair(const std::vector<float>& xyz, const std::vector<std::vector<int32_t>>& faces,
                 const char* index_type = "int") {
    auto head = [&](const char* format) {
        return std::string("ply\nformat ") + format + " 1.0\nelement vertex " + std::to_string(xyz.size() / 3) +
            "\nproperty float nx\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\n"
            "element note 2\nproperty short a\nelement face " +
            std::to_string(faces.size()) + "\nproperty list uchar " + index_type + " vertex_indices\nend_header\n";
    };
    PlyPair p{head("binary_little_endian"), head("binary_big_endian")};
    auto put = [&](const void* v, size_t n) {
        const char* c = static_cast<const char*>(v);
        p.little.append(c, n);
        for (size_t i = n; i-- > 0;) p.big.push_back(c[i]);
    };
    for (size_t v = 0; v < xyz.size() / 3; ++v) {
        float nx = 0.5f;
        uint8_t red = 200;
        put(&nx, 4);
        put(&xyz[v * 3], 4);
        put(&xyz[v * 3 + 1], 4);
        put(&xyz[v * 3 + 2], 4);
        put(&red, 1);
    }
    for (int16_t a : {int16_t(1), int16_t(-2)}) put(&a, 2);
    for (const auto& f : faces) {
        uint8_t n = uint8_t(f.size());
        put(&n, 1);
        for (int32_t i : f) put(&i, 4);
    }
    return p;
}

}  // namespace

TEST(Formats, BinaryPlyOfTrianglesReadsAsTheGeneralReaderDoes) {
    // Far from the origin, so that the exact shift of float input is exercised too.
    std::vector<float> xyz;
    std::vector<std::vector<int32_t>> tris;
    for (int i = 0; i < 40; ++i) xyz.insert(xyz.end(), {4e5f + float(i % 7), -3.25f * float(i), 1e-3f * float(i * i)});
    for (int i = 0; i + 2 < 40; ++i) tris.push_back({i, i + 1, i + 2});
    for (const char* index_type : {"int", "uint"}) {
        PlyPair p = ply_pair(xyz, tris, index_type);
        cb::Scene fast = load(p.little, cb::FileFormat::ply), general = load(p.big, cb::FileFormat::ply);
        ASSERT_EQ(fast.meshes.size(), 1u);
        EXPECT_EQ(fast.meshes[0].positions, general.meshes[0].positions) << index_type;
        EXPECT_EQ(fast.meshes[0].indices, general.meshes[0].indices) << index_type;
        EXPECT_EQ(fast.instances[0].world, general.instances[0].world) << index_type;
        EXPECT_EQ(fast.meshes[0].triangle_count(), tris.size());
        EXPECT_NE(fast.instances[0].world[12], 0) << "the exact shift of far float input";
    }
    // A polygon among the triangles: the general reader takes the file and triangulates it.
    std::vector<std::vector<int32_t>> mixed = tris;
    mixed[5] = {0, 1, 2, 3};
    cb::Scene quads = load(ply_pair(xyz, mixed).little, cb::FileFormat::ply);
    EXPECT_EQ(quads.report.polygons.total, 1u);
    EXPECT_EQ(quads.meshes[0].triangle_count(), tris.size() + 1);
    // Records the fast reader refuses get the general reader's errors, naming the element.
    std::vector<std::vector<int32_t>> out_of_range = tris, negative = tris;
    out_of_range[3][1] = 40;
    negative[7][2] = -1;
    EXPECT_EQ(error_of(ply_pair(xyz, out_of_range).little, cb::FileFormat::ply),
              "t: face 3: index 40.000000 out of range (40 vertices)");
    EXPECT_EQ(error_of(ply_pair(xyz, negative).little, cb::FileFormat::ply),
              "t: face 7: index -1.000000 out of range (40 vertices)");
    std::vector<float> nan_xyz = xyz;
    nan_xyz[4] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_EQ(error_of(ply_pair(nan_xyz, tris).little, cb::FileFormat::ply),
              "t: vertex 1: position is not a finite float (nan)");
    std::string cut = ply_pair(xyz, tris).little;
    cut.resize(cut.size() - 5);
    EXPECT_EQ(error_of(cut, cb::FileFormat::ply), "t: face 37: unexpected end of data");
}

// A binary PLY of more records than one thread's part reads on two threads as on one, and validation on
// two threads names the first bad element, not the first a thread happened to meet.
TEST(Formats, LargeBinaryPlyReadsAndValidatesTheSameOnTwoThreads) {
    const int side = 400;  // a grid of 160,000 vertices and 318,402 triangles: parts of 2^18 records
    std::vector<float> xyz;
    for (int y = 0; y < side; ++y)
        for (int x = 0; x < side; ++x) xyz.insert(xyz.end(), {float(x), float(y), float((x * y) % 5)});
    std::vector<std::vector<int32_t>> tris;
    for (int y = 0; y + 1 < side; ++y)
        for (int x = 0; x + 1 < side; ++x) {
            const int v = y * side + x;
            tris.push_back({v, v + 1, v + side});
            tris.push_back({v + 1, v + side + 1, v + side});
        }
    tris[5] = {7, 7, 8};  // degenerate, counted by the validation
    const std::string text = ply_pair(xyz, tris).little;
    auto bytes = reinterpret_cast<const uint8_t*>(text.data());
    const cb::Scene one = cb::load_mesh_memory(bytes, text.size(), cb::FileFormat::ply, "t", 1);
    const cb::Scene two = cb::load_mesh_memory(bytes, text.size(), cb::FileFormat::ply, "t", 2);
    EXPECT_EQ(one.meshes[0].positions, two.meshes[0].positions);
    EXPECT_EQ(one.meshes[0].indices, two.meshes[0].indices);
    EXPECT_EQ(one.report.degenerate_triangles, 1u);
    EXPECT_EQ(two.report.degenerate_triangles, one.report.degenerate_triangles);

    // Two bad indices in different parts of the index array, and two non-finite coordinates: the error names
    // the first of each, on any thread count.
    auto validation_error = [](cb::Scene s, unsigned threads) {
        try {
            cb::validate_scene(s, "t", threads);
        } catch (const cb::LoadError& e) {
            return std::string(e.what());
        }
        return std::string("validated");
    };
    cb::Scene bad = one;
    bad.meshes[0].indices[size_t(300000) * 3 + 1] = uint32_t(side * side);
    bad.meshes[0].indices[size_t(90000) * 3 + 2] = uint32_t(side * side + 5);
    for (unsigned threads : {1u, 2u})
        EXPECT_EQ(validation_error(bad, threads),
                  "t: mesh 0: triangle 90000: index 160005 out of range (160000 vertices)");
    bad = one;
    bad.meshes[0].positions[size_t(150000) * 3] = std::numeric_limits<float>::infinity();
    bad.meshes[0].positions[size_t(20) * 3 + 2] = std::numeric_limits<float>::quiet_NaN();
    for (unsigned threads : {1u, 2u})
        EXPECT_EQ(validation_error(bad, threads), "t: mesh 0: vertex 20: position is not finite");
}
