// glTF loading on generated files: every feature the loader claims, and every way a file can be broken.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "gltf_writer.h"
#include "load.h"
#include "scene_info.h"

using cb::data::GltfWriter;
using cb::data::json;
using cb::data::MeshData;

namespace {

cb::Scene load_text(const std::string& text, const std::string& name = "t.gltf", const std::string& dir = "") {
    return cb::load_gltf_memory(reinterpret_cast<const uint8_t*>(text.data()), text.size(), name, dir);
}

cb::Scene load_bytes(const std::vector<uint8_t>& bytes, const std::string& name = "t.glb") {
    return cb::load_gltf_memory(bytes.data(), bytes.size(), name, "");
}

// The error message a broken document produces; fails the test if it loads.
std::string error_of(const std::string& text) {
    try {
        load_text(text);
    } catch (const cb::LoadError& e) {
        std::string what = e.what();
        EXPECT_EQ(what.find('\n'), std::string::npos) << "one line: " << what;
        EXPECT_EQ(what.rfind("t.gltf: ", 0), 0u) << "names the file: " << what;
        return what;
    }
    ADD_FAILURE() << "loaded a broken file";
    return "";
}

MeshData triangle() { return {{0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2}}; }

GltfWriter one_mesh_scene(const MeshData& m, int material = -1) {
    GltfWriter w;
    w.mesh("m", m, material);
    w.node({{"mesh", 0}});
    w.doc["scenes"] = json::array({{{"nodes", {0}}}});
    w.doc["scene"] = 0;
    return w;
}

std::array<double, 3> world_of(const cb::Scene& s, size_t instance, size_t vertex) {
    const cb::Instance& inst = s.instances[instance];
    const float* p = &s.meshes[inst.mesh].positions[vertex * 3];
    return cb::transform_point(inst.world, p[0], p[1], p[2]);
}

}  // namespace

TEST(Gltf, PrimitiveModesSparseQuantizedAndStride) {
    std::ifstream in(std::string(CB_SOURCE_DIR) + "/data/small/primitive_modes.gltf");
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    cb::Scene s = load_text(text);
    ASSERT_EQ(s.meshes.size(), 1u);
    const cb::Mesh& m = s.meshes[0];
    EXPECT_EQ(s.report.skipped_primitives, 1u);  // the LINES primitive
    ASSERT_EQ(m.primitives.size(), 3u);
    // Strip of 6 vertices: 4 triangles, odd ones with their first two vertices swapped.
    EXPECT_EQ(m.primitives[0].triangle_count, 4u);
    std::vector<uint32_t> strip(m.indices.begin(), m.indices.begin() + 12);
    EXPECT_EQ(strip, (std::vector<uint32_t>{0, 1, 2, 2, 1, 3, 2, 3, 4, 4, 3, 5}));
    // Fan of 4 vertices (after the 6 strip vertices): 2 triangles around the first.
    EXPECT_EQ(m.primitives[1].triangle_count, 2u);
    std::vector<uint32_t> fan(m.indices.begin() + 12, m.indices.begin() + 18);
    EXPECT_EQ(fan, (std::vector<uint32_t>{6, 7, 8, 6, 8, 9}));
    // Normalized int16 with an 8-byte stride (the padding short is skipped): 32767 is exactly 1.
    EXPECT_EQ(m.positions[7 * 3 + 0], 1.0f);
    EXPECT_EQ(m.positions[8 * 3 + 0], 1.0f);
    EXPECT_EQ(m.positions[8 * 3 + 1], 1.0f);
    EXPECT_EQ(m.positions[9 * 3 + 0], 0.0f);
    EXPECT_EQ(m.positions[9 * 3 + 1], 1.0f);
    EXPECT_EQ(m.positions[9 * 3 + 2], 0.0f);
    // Sparse: vertex 1 of the third primitive replaced by (0.5, 0.25, 0.125), the rest as the base view.
    const float* v1 = &m.positions[(10 + 1) * 3];
    EXPECT_EQ(v1[0], 0.5f);
    EXPECT_EQ(v1[1], 0.25f);
    EXPECT_EQ(v1[2], 0.125f);
    EXPECT_EQ(m.positions[(10 + 2) * 3 + 1], 1.0f);
}

TEST(Gltf, InterleavedStrideUnsignedByteIndicesAndNonIndexed) {
    GltfWriter w;
    // Two vertices' worth of interleaved position + 4 bytes of something else (stride 16).
    float inter[] = {0, 0, 0, 99, 1, 0, 0, 99, 0, 1, 0, 99};
    int v = w.view(inter, sizeof inter, 34962);
    w.doc["bufferViews"][v]["byteStride"] = 16;
    int pa = w.accessor({{"bufferView", v}, {"componentType", 5126}, {"count", 3}, {"type", "VEC3"}});
    uint8_t idx[] = {2, 1, 0, 0};
    int iv = w.view(idx, 3, 34963);
    int ia = w.accessor({{"bufferView", iv}, {"componentType", 5121}, {"count", 3}, {"type", "SCALAR"}});
    // KHR_mesh_quantization: unnormalized uint16 positions are plain integers.
    uint16_t q[] = {0, 0, 0, 7, 0, 0, 0, 9, 0};
    int qv = w.view(q, sizeof q, 34962);
    int qa = w.accessor({{"bufferView", qv}, {"componentType", 5123}, {"count", 3}, {"type", "VEC3"}});
    w.doc["meshes"] = json::array({{{"primitives",
                                     json::array({{{"attributes", {{"POSITION", pa}}}, {"indices", ia}},
                                                  {{"attributes", {{"POSITION", qa}}}}})}}});
    w.node({{"mesh", 0}});
    cb::Scene s = load_text(w.gltf_embedded());
    const cb::Mesh& m = s.meshes[0];
    ASSERT_EQ(m.triangle_count(), 2u);
    EXPECT_EQ(std::vector<uint32_t>(m.indices.begin(), m.indices.end()), (std::vector<uint32_t>{2, 1, 0, 3, 4, 5}));
    EXPECT_EQ(m.positions[3 * 1 + 0], 1.0f);
    EXPECT_EQ(m.positions[3 * 2 + 1], 1.0f);
    EXPECT_EQ(m.positions[3 * 4 + 0], 7.0f);
    EXPECT_EQ(m.positions[3 * 5 + 1], 9.0f);
    // No "scene": every root node is used.
    EXPECT_EQ(s.instances.size(), 1u);
}

TEST(Gltf, NodeTransformsComposeAndMeshesInstanceOnce) {
    GltfWriter w = one_mesh_scene(triangle());
    w.doc["nodes"] = json::array();
    // parent: translate (10,0,0); child A: rotate 90 degrees about +y, scale 2; child B: a matrix that
    // translates by (0,5,0); child C: the mesh again, untransformed.
    double h = std::sqrt(0.5);
    w.node({{"children", {1, 2, 3}}, {"translation", {10.0, 0.0, 0.0}}});
    w.node({{"mesh", 0}, {"rotation", {0.0, h, 0.0, h}}, {"scale", {2.0, 2.0, 2.0}}, {"name", "A"}});
    w.node({{"mesh", 0}, {"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 5, 0, 1}}, {"name", "B"}});
    w.node({{"mesh", 0}, {"name", "C"}});
    w.doc["scenes"] = json::array({{{"nodes", {0}}}});
    cb::Scene s = load_text(w.gltf_embedded());
    ASSERT_EQ(s.meshes.size(), 1u);
    ASSERT_EQ(s.instances.size(), 3u);
    // Vertex 1 is (1,0,0): rotated +90 about y gives (0,0,-1), scaled (0,0,-2), translated (10,0,-2).
    auto a = world_of(s, 0, 1);
    EXPECT_NEAR(a[0], 10, 1e-12);
    EXPECT_NEAR(a[1], 0, 1e-12);
    EXPECT_NEAR(a[2], -2, 1e-12);
    auto b = world_of(s, 1, 2);  // (0,1,0) + (0,5,0) + (10,0,0)
    EXPECT_EQ(b, (std::array<double, 3>{10, 6, 0}));
    EXPECT_EQ(s.instances[2].node_name, "C");
    cb::SceneInfo info = cb::describe(s);
    EXPECT_EQ(info.unique_triangles, 1u);
    EXPECT_EQ(info.scene_triangles, 3u);
}

TEST(Gltf, SharedChildNodeIsInstancedPerPath) {
    GltfWriter w = one_mesh_scene(triangle());
    w.doc["nodes"] = json::array();
    w.node({{"mesh", 0}});
    w.node({{"children", {0}}, {"translation", {1.0, 0.0, 0.0}}});
    w.node({{"children", {0}}, {"translation", {2.0, 0.0, 0.0}}});
    w.doc["scenes"] = json::array({{{"nodes", {1, 2}}}});
    cb::Scene s = load_text(w.gltf_embedded());
    ASSERT_EQ(s.instances.size(), 2u);
    EXPECT_EQ(world_of(s, 0, 0)[0], 1.0);
    EXPECT_EQ(world_of(s, 1, 0)[0], 2.0);
}

TEST(Gltf, DoubleSidedIsKeptPerPrimitive) {
    GltfWriter w;
    w.doc["materials"] = json::array({{{"doubleSided", true}}, json::object()});
    w.mesh("a", triangle(), 0);
    w.mesh("b", triangle(), 1);
    w.mesh("c", triangle(), -1);
    for (int i = 0; i < 3; ++i) w.node({{"mesh", i}});
    cb::Scene s = load_text(w.gltf_embedded());
    ASSERT_EQ(s.meshes.size(), 3u);
    EXPECT_TRUE(s.meshes[0].primitives[0].double_sided);
    EXPECT_FALSE(s.meshes[1].primitives[0].double_sided);
    EXPECT_FALSE(s.meshes[2].primitives[0].double_sided);
}

TEST(Gltf, ImagesAreNeverRead) {
    GltfWriter w = one_mesh_scene(triangle());
    w.doc["images"] = json::array({{{"uri", "does_not_exist.png"}}});
    w.doc["textures"] = json::array({{{"source", 0}}});
    EXPECT_EQ(load_text(w.gltf_embedded()).meshes.size(), 1u);
}

TEST(Gltf, ExternalBufferNextToTheFile) {
    auto dir = std::filesystem::temp_directory_path() / "cb_gltf_external";
    std::filesystem::create_directories(dir);
    GltfWriter w = one_mesh_scene(triangle());
    w.doc["buffers"] = json::array({{{"byteLength", w.bin.size()}, {"uri", "tri.bin"}}});
    std::ofstream(dir / "tri.bin", std::ios::binary)
        .write(reinterpret_cast<const char*>(w.bin.data()), std::streamsize(w.bin.size()));
    std::ofstream(dir / "tri.gltf") << w.doc.dump();
    EXPECT_EQ(cb::load_scene((dir / "tri.gltf").string()).meshes[0].triangle_count(), 1u);
    // A buffer file of another size, and a missing one: errors naming the buffer, its file and where it was
    // looked for.
    auto error = [&] {
        try {
            cb::load_scene((dir / "tri.gltf").string());
            ADD_FAILURE();
        } catch (const cb::LoadError& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    std::ofstream(dir / "tri.bin", std::ios::binary) << "short";
    EXPECT_EQ(error(),
              (dir / "tri.gltf").string() + ": buffer 0: 'tri.bin': 5 bytes, but its byteLength is " +
                  std::to_string(w.bin.size()));
    std::filesystem::remove(dir / "tri.bin");
    EXPECT_EQ(error(),
              (dir / "tri.gltf").string() + ": buffer 0: 'tri.bin': no such file (looked for " +
                  (dir / "tri.bin").string() + ")");
}

TEST(Gltf, GlbRoundTripAndTruncation) {
    GltfWriter w = one_mesh_scene(triangle());
    std::vector<uint8_t> glb = w.glb();
    EXPECT_EQ(load_bytes(glb).meshes[0].triangle_count(), 1u);
    // Every truncation either loads nothing wrong or fails cleanly; most fail.
    size_t failures = 0;
    for (size_t cut = 0; cut < glb.size(); ++cut) {
        std::vector<uint8_t> part(glb.begin(), glb.begin() + cut);
        try {
            load_bytes(part);
        } catch (const cb::LoadError& e) {
            ++failures;
            EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
        }
    }
    EXPECT_EQ(failures, glb.size());
}

TEST(Gltf, IndexOutOfRange) {
    GltfWriter w = one_mesh_scene({{0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 70000}});
    EXPECT_EQ(error_of(w.gltf_embedded()), "t.gltf: mesh 0 primitive 0: index 70000 out of range (3 vertices)");
}

TEST(Gltf, NonFinitePosition) {
    float inf = INFINITY;
    GltfWriter w = one_mesh_scene({{0, 0, 0, inf, 0, 0, 0, 1, 0}, {0, 1, 2}});
    w.doc["accessors"][0].erase("min");
    w.doc["accessors"][0].erase("max");
    EXPECT_NE(error_of(w.gltf_embedded()).find("mesh 0 primitive 0: vertex 1: position is not a finite float"),
              std::string::npos);
}

TEST(Gltf, AccessorPastItsBufferView) {
    GltfWriter w = one_mesh_scene(triangle());
    w.doc["accessors"][0]["count"] = 4;
    EXPECT_NE(error_of(w.gltf_embedded()).find("accessor 0: needs 48 bytes of bufferView 0 which has 36"),
              std::string::npos);
}

TEST(Gltf, BufferViewPastItsBuffer) {
    GltfWriter w = one_mesh_scene(triangle());
    w.doc["bufferViews"][1]["byteLength"] = 400;
    EXPECT_NE(error_of(w.gltf_embedded()).find("past the end of buffer 0"), std::string::npos);
}

TEST(Gltf, ShortBuffer) {
    GltfWriter w = one_mesh_scene(triangle());
    std::string text = w.gltf_embedded();
    json doc = json::parse(text);
    doc["buffers"][0]["byteLength"] = 1000;  // the data URI holds fewer bytes
    error_of(doc.dump());
}

TEST(Gltf, StrideSmallerThanElement) {
    GltfWriter w = one_mesh_scene(triangle());
    w.doc["bufferViews"][0]["byteStride"] = 4;
    EXPECT_NE(error_of(w.gltf_embedded()).find("byteStride 4 smaller than an element"), std::string::npos);
}

TEST(Gltf, SparseIndexOutOfRange) {
    std::ifstream in(std::string(CB_SOURCE_DIR) + "/data/small/primitive_modes.gltf");
    json doc = json::parse(in);
    doc["accessors"][2]["count"] = 1;  // the sparse accessor now has one element; its sparse index is 1
    doc["accessors"][2]["sparse"]["count"] = 1;
    EXPECT_NE(error_of(doc.dump()).find("sparse index 1 out of range (1 elements)"), std::string::npos);
}

TEST(Gltf, NodeCycleIsAnErrorNotAHang) {
    GltfWriter w = one_mesh_scene(triangle());
    w.doc["nodes"] = json::array();
    w.node({{"children", {1}}});
    w.node({{"children", {0}}, {"mesh", 0}});
    w.doc["scenes"] = json::array({{{"nodes", {0}}}});
    EXPECT_NE(error_of(w.gltf_embedded()).find("node 0: node cycle"), std::string::npos);
}

TEST(Gltf, MissingMeshAndNode) {
    GltfWriter w = one_mesh_scene(triangle());
    w.doc["nodes"][0]["mesh"] = 5;
    EXPECT_NE(error_of(w.gltf_embedded()).find("node 0: mesh 5 does not exist"), std::string::npos);
    GltfWriter v = one_mesh_scene(triangle());
    v.doc["scenes"][0]["nodes"] = {3};
    error_of(v.gltf_embedded());
}

TEST(Gltf, UnsupportedRequiredExtension) {
    GltfWriter w = one_mesh_scene(triangle());
    w.doc["extensionsUsed"] = {"EXT_meshopt_compression"};
    w.doc["extensionsRequired"] = {"EXT_meshopt_compression"};
    EXPECT_EQ(error_of(w.gltf_embedded()), "t.gltf: unsupported required extension EXT_meshopt_compression");
}

TEST(Gltf, TrianglesNotAMultipleOfThree) {
    GltfWriter w = one_mesh_scene({{0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2, 0}});
    EXPECT_NE(error_of(w.gltf_embedded()).find("TRIANGLES with 4 indices"), std::string::npos);
}

TEST(Gltf, SignedIndicesRejected) {
    GltfWriter w = one_mesh_scene(triangle());
    w.doc["accessors"][1]["componentType"] = 5124;
    EXPECT_NE(error_of(w.gltf_embedded()).find("not an unsigned integer type"), std::string::npos);
}

TEST(Gltf, EmptyAndGarbageFiles) {
    EXPECT_THROW(load_text(""), cb::LoadError);
    // Not JSON, or JSON but not glTF: said in those words, never as the JSON library's exception text.
    const std::string neither = "t.gltf: not a glTF file: neither binary glTF (magic 'glTF') nor JSON text";
    EXPECT_EQ(error_of("{"), neither + " (parse error at byte 2)");
    EXPECT_EQ(error_of("hello"), neither + " (parse error at byte 1)");
    EXPECT_EQ(error_of("{\"asset\": {\"version\": \"2.0\"}} trailing"), neither + " (parse error at byte 33)");
    const std::string no_asset = "t.gltf: not a glTF file: JSON without an \"asset\" object naming its \"version\"";
    EXPECT_EQ(error_of("[1,2,3]"), no_asset);
    EXPECT_EQ(error_of("{}"), no_asset);
    EXPECT_EQ(error_of("{\"asset\": {}}"), no_asset);
    EXPECT_EQ(error_of("{\"asset\": {\"version\": \"2.0\"}, \"x\": 1e999}"),
              "t.gltf: JSON: number overflow parsing '1e999'");
    EXPECT_THROW(load_bytes({'g', 'l', 'T', 'F', 2, 0, 0, 0}), cb::LoadError);
}

TEST(Gltf, GlbWhoseJsonChunkIsNotJson) {
    GltfWriter w = one_mesh_scene(triangle());
    std::vector<uint8_t> glb = w.glb();
    glb[20] = '[';  // the chunk's opening brace
    try {
        load_bytes(glb);
        ADD_FAILURE();
    } catch (const cb::LoadError& e) {
        EXPECT_EQ(std::string(e.what()).rfind("t.glb: GLB JSON chunk is not JSON text (parse error at byte ", 0), 0u)
            << e.what();
    }
}

TEST(Gltf, DracoPrimitiveDecodesThroughTheExtension) {
    // A real Draco stream (written by Draco's own tools) from ../shared/data.
    std::string path = std::string(CB_SHARED_DATA) + "/gltf/Box_Draco.glb";
    if (!std::filesystem::exists(path)) GTEST_SKIP() << "../shared/data is absent";
    cb::Scene s = cb::load_scene(path);
    EXPECT_EQ(s.report.draco_primitives, 1u);
    EXPECT_EQ(s.meshes[0].triangle_count(), 12u);
    EXPECT_EQ(s.meshes[0].vertex_count(), 24u);
    for (float p : s.meshes[0].positions) EXPECT_LE(std::fabs(p), 0.5f + 1e-3f);
}

TEST(Gltf, DracoCountsMustAgreeWithTheAccessors) {
    std::string dir = std::string(CB_SHARED_DATA) + "/gltf/BoxDraco";
    if (!std::filesystem::exists(dir)) GTEST_SKIP() << "../shared/data is absent";
    std::ifstream in(dir + "/BoxDraco.gltf");
    json doc = json::parse(in);
    int indices = doc["meshes"][0]["primitives"][0]["indices"];
    doc["accessors"][indices]["count"] = 35;
    std::string text = doc.dump();
    try {
        load_text(text, "t.gltf", dir);
        ADD_FAILURE();
    } catch (const cb::LoadError& e) {
        EXPECT_NE(std::string(e.what()).find("Draco decoded 12 triangles but indices accessor"), std::string::npos)
            << e.what();
    }
    // A corrupted Draco stream is a clean error too.
    doc["accessors"][indices]["count"] = 36;
    doc["bufferViews"][doc["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["bufferView"]
                           .get<int>()]["byteLength"] = 20;
    EXPECT_THROW(load_text(doc.dump(), "t.gltf", dir), cb::LoadError);
}

TEST(Gltf, HugeZeroFilledAccessorIsRefused) {
    // Three vertices' worth of file asking for four billion zero positions: an error, not an allocation.
    GltfWriter w = one_mesh_scene(triangle());
    w.doc["accessors"].push_back({{"componentType", 5126}, {"count", 4000000000u}, {"type", "VEC3"}});
    w.doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = w.doc["accessors"].size() - 1;
    EXPECT_NE(
        error_of(w.gltf_embedded())
            .find("without a bufferView (zero-filled) needs 48000000000 bytes, more than the file's buffers hold"),
        std::string::npos);
}

TEST(Gltf, ExponentialNodeDagIsCapped) {
    // 30 levels, each node the child of two parents: 2^30 paths to the mesh node.
    GltfWriter w = one_mesh_scene(triangle());
    w.doc["nodes"] = json::array();
    w.node({{"mesh", 0}});
    int below[2] = {0, 0};  // the two nodes of the level beneath (level 0: the mesh node, twice)
    for (int level = 1; level <= 30; ++level) {
        int a = w.node({{"children", {below[0], below[1]}}});
        int b = w.node({{"children", {below[0], below[1]}}});
        below[0] = a, below[1] = b;
    }
    w.doc["scenes"] = json::array({{{"nodes", {int(w.doc["nodes"].size()) - 1}}}});
    EXPECT_NE(error_of(w.gltf_embedded()).find("node visits: nodes shared by several parents multiply the paths"),
              std::string::npos);
}
