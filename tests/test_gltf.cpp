// glTF loading on generated files: every feature the loader claims, and every way a file can be broken.
#include <gtest/gtest.h>

#include <meshoptimizer.h>

#include <algorithm>
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
    w.doc["extensionsUsed"] = {"KHR_meshopt_compression"};
    w.doc["extensionsRequired"] = {"KHR_meshopt_compression"};
    EXPECT_EQ(error_of(w.gltf_embedded()), "t.gltf: unsupported required extension KHR_meshopt_compression");
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
        below[0] = a;
        below[1] = b;
    }
    w.doc["scenes"] = json::array({{{"nodes", {int(w.doc["nodes"].size()) - 1}}}});
    EXPECT_NE(error_of(w.gltf_embedded()).find("node visits: nodes shared by several parents multiply the paths"),
              std::string::npos);
}

// EXT_meshopt_compression and EXT_mesh_gpu_instancing, as gltfpack and glTF-Transform write them: compressed
// streams in buffer 0 (the BIN chunk), the bufferViews' own buffer a fallback of no data, as buffer 1.
namespace {

struct MeshoptGlb {
    GltfWriter w;
    uint64_t fallback_bytes = 0;

    // A bufferView decoding to count x stride bytes from `stream`, with the extension's fields; returns its
    // index. `view_stride` also gives the bufferView the stride (vertex attributes have it).
    int view(const std::vector<uint8_t>& stream, size_t count, size_t stride, const std::string& mode,
             const std::string& filter = "NONE", bool view_stride = true) {
        while (w.bin.size() % 4) w.bin.push_back(0);
        const size_t offset = w.bin.size();
        w.bin.insert(w.bin.end(), stream.begin(), stream.end());
        json ext = {{"buffer", 0},          {"byteOffset", offset}, {"byteLength", stream.size()},
                    {"byteStride", stride}, {"count", count},       {"mode", mode}};
        if (filter != "NONE") ext["filter"] = filter;
        json v = {{"buffer", 1}, {"byteOffset", fallback_bytes}, {"byteLength", count * stride}};
        if (view_stride) v["byteStride"] = stride;
        v["extensions"] = {{"EXT_meshopt_compression", ext}};
        w.doc["bufferViews"].push_back(v);
        fallback_bytes += (count * stride + 3) / 4 * 4;
        return int(w.doc["bufferViews"].size() - 1);
    }

    // `marked`: the fallback buffer says it is one; else it is a placeholder that only compressed views name.
    std::vector<uint8_t> glb(bool marked = true) {
        w.doc["extensionsUsed"] = {"EXT_meshopt_compression"};
        w.doc["extensionsRequired"] = {"EXT_meshopt_compression"};
        json fallback = {{"byteLength", fallback_bytes}};
        if (marked) fallback["extensions"] = {{"EXT_meshopt_compression", {{"fallback", true}}}};
        return w.glb(json::array({fallback}));
    }
};

std::vector<uint8_t> encode_vertices(const void* data, size_t count, size_t stride) {
    std::vector<uint8_t> out(meshopt_encodeVertexBufferBound(count, stride));
    out.resize(meshopt_encodeVertexBuffer(out.data(), out.size(), data, count, stride));
    return out;
}

// A 5 x 5 grid of float positions away from the origin, and its 32 triangles.
MeshData grid() {
    MeshData m;
    for (int j = 0; j < 5; ++j)
        for (int i = 0; i < 5; ++i)
            m.positions.insert(m.positions.end(), {1000.25f + i * 0.5f, 3.0f + 0.1f * i * j, -7.0f - j});
    for (uint32_t j = 0; j < 4; ++j)
        for (uint32_t i = 0; i < 4; ++i) {
            const uint32_t a = j * 5 + i;
            m.indices.insert(m.indices.end(), {a, a + 1, a + 6, a, a + 6, a + 5});
        }
    return m;
}

// The triangles of instance 0's mesh as world-position triples, each starting at its least corner (the
// triangle codec may rotate a triangle's corners, never its winding), sorted.
std::vector<std::array<double, 9>> world_triangles(const cb::Scene& s, size_t instance = 0) {
    const cb::Mesh& m = s.meshes[s.instances[instance].mesh];
    std::vector<std::array<double, 9>> out;
    for (size_t t = 0; t < m.triangle_count(); ++t) {
        std::array<std::array<double, 3>, 3> c;
        for (int k = 0; k < 3; ++k) {
            const float* p = &m.positions[size_t(m.indices[t * 3 + k]) * 3];
            c[k] = cb::transform_point(s.instances[instance].world, p[0], p[1], p[2]);
        }
        const int first = int(std::min_element(c.begin(), c.end()) - c.begin());
        std::array<double, 9> tri;
        for (int k = 0; k < 3; ++k)
            for (int a = 0; a < 3; ++a) tri[k * 3 + a] = c[(first + k) % 3][a];
        out.push_back(tri);
    }
    std::sort(out.begin(), out.end());
    return out;
}

std::vector<std::array<double, 9>> world_triangles(const MeshData& m) {
    cb::Mesh mesh;
    mesh.positions = m.positions;
    mesh.indices = m.indices;
    cb::Scene s;
    s.meshes.push_back(mesh);
    s.instances.push_back({});
    return world_triangles(s);
}

// The grid compressed: positions (12-byte stride), triangle list indices (32-bit, triangle codec) for one
// primitive, the same triangles as an index sequence (16-bit, index codec) for a second one.
MeshoptGlb compressed_grid() {
    MeshoptGlb g;
    const MeshData m = grid();
    const int pv = g.view(encode_vertices(m.positions.data(), 25, 12), 25, 12, "ATTRIBUTES");
    std::vector<uint8_t> tri(meshopt_encodeIndexBufferBound(m.indices.size(), 25));
    tri.resize(meshopt_encodeIndexBuffer(tri.data(), tri.size(), m.indices.data(), m.indices.size()));
    const int tv = g.view(tri, m.indices.size(), 4, "TRIANGLES", "NONE", false);
    std::vector<uint8_t> seq(meshopt_encodeIndexSequenceBound(m.indices.size(), 25));
    seq.resize(meshopt_encodeIndexSequence(seq.data(), seq.size(), m.indices.data(), m.indices.size()));
    const int sv = g.view(seq, m.indices.size(), 2, "INDICES", "NONE", false);
    const int pa = g.w.accessor({{"bufferView", pv}, {"componentType", 5126}, {"count", 25}, {"type", "VEC3"}});
    const int ta = g.w.accessor({{"bufferView", tv}, {"componentType", 5125}, {"count", 96}, {"type", "SCALAR"}});
    const int sa = g.w.accessor({{"bufferView", sv}, {"componentType", 5123}, {"count", 96}, {"type", "SCALAR"}});
    g.w.doc["meshes"] = json::array({{{"primitives",
                                       {{{"attributes", {{"POSITION", pa}}}, {"indices", ta}},
                                        {{"attributes", {{"POSITION", pa}}}, {"indices", sa}}}}}});
    g.w.node({{"mesh", 0}});
    return g;
}

std::string glb_error(const std::vector<uint8_t>& bytes) {
    try {
        load_bytes(bytes);
    } catch (const cb::LoadError& e) {
        std::string what = e.what();
        EXPECT_EQ(what.find('\n'), std::string::npos) << "one line: " << what;
        EXPECT_EQ(what.rfind("t.glb: ", 0), 0u) << "names the file: " << what;
        return what;
    }
    ADD_FAILURE() << "loaded a broken file";
    return "";
}

}  // namespace

TEST(GltfMeshopt, CompressedViewsDecodeToTheFilesFloatsAndTriangles) {
    const cb::Scene s = load_bytes(compressed_grid().glb());
    ASSERT_EQ(s.meshes.size(), 1u);
    ASSERT_EQ(s.meshes[0].primitives.size(), 2u);
    EXPECT_EQ(s.report.meshopt_views, 3u);  // positions once for both primitives, two index views
    const cb::Scene both = [] {
        MeshData twice = grid();
        const MeshData g = grid();
        twice.indices.insert(twice.indices.end(), g.indices.begin(), g.indices.end());
        cb::Mesh m;
        m.positions = twice.positions;
        m.indices = twice.indices;
        cb::Scene r;
        r.meshes.push_back(m);
        r.instances.push_back({});
        return r;
    }();
    EXPECT_EQ(world_triangles(s), world_triangles(both));  // exactly: the codec is lossless
    EXPECT_EQ(world_triangles(load_bytes(compressed_grid().glb(false))), world_triangles(both));  // unmarked
    ASSERT_FALSE(s.report.extensions.empty());
    EXPECT_EQ(cb::extension_text(s.report.extensions[0]), "EXT_meshopt_compression (required, applied)");
}

TEST(GltfMeshopt, FiltersOctahedralQuaternionExponential) {
    // Positions on the unit sphere through the octahedral filter (8-byte stride: normalized shorts), and an
    // instanced node whose translations go through the exponential filter and rotations through the
    // quaternion one.
    MeshoptGlb g;
    const float dirs[4][4] = {{0.6f, 0.8f, 0, 0}, {0, 0.6f, 0.8f, 0}, {-0.48f, 0.6f, 0.64f, 0}, {0, 0, 1, 0}};
    std::vector<uint8_t> oct(4 * 8);
    meshopt_encodeFilterOct(oct.data(), 4, 8, 16, &dirs[0][0]);
    const int pv = g.view(encode_vertices(oct.data(), 4, 8), 4, 8, "ATTRIBUTES", "OCTAHEDRAL");
    const int pa = g.w.accessor(
        {{"bufferView", pv}, {"componentType", 5122}, {"normalized", true}, {"count", 4}, {"type", "VEC3"}});
    const uint32_t indices[6] = {0, 1, 2, 0, 2, 3};
    const int iv = g.view(encode_vertices(indices, 6, 4), 6, 4, "ATTRIBUTES", "NONE", false);
    const int ia = g.w.accessor({{"bufferView", iv}, {"componentType", 5125}, {"count", 6}, {"type", "SCALAR"}});
    g.w.doc["meshes"] = json::array({{{"primitives", {{{"attributes", {{"POSITION", pa}}}, {"indices", ia}}}}}});

    const float translations[3][3] = {{1.5f, -2.25f, 3}, {100, 0.5f, -0.125f}, {-6, 7, 8}};
    std::vector<uint8_t> exp(3 * 12);
    meshopt_encodeFilterExp(exp.data(), 3, 12, 24, &translations[0][0]);
    const int tv = g.view(encode_vertices(exp.data(), 3, 12), 3, 12, "ATTRIBUTES", "EXPONENTIAL");
    const double half = std::sqrt(0.5);
    const float rotations[3][4] = {{0, 0, 0, 1}, {0, float(half), 0, float(half)}, {1, 0, 0, 0}};
    std::vector<uint8_t> quat(3 * 8);
    meshopt_encodeFilterQuat(quat.data(), 3, 8, 16, &rotations[0][0]);
    const int rv = g.view(encode_vertices(quat.data(), 3, 8), 3, 8, "ATTRIBUTES", "QUATERNION");
    const int ta = g.w.accessor({{"bufferView", tv}, {"componentType", 5126}, {"count", 3}, {"type", "VEC3"}});
    const int ra = g.w.accessor(
        {{"bufferView", rv}, {"componentType", 5122}, {"normalized", true}, {"count", 3}, {"type", "VEC4"}});
    g.w.node(
        {{"mesh", 0},
         {"translation", {0.0, 10.0, 0.0}},
         {"extensions", {{"EXT_mesh_gpu_instancing", {{"attributes", {{"TRANSLATION", ta}, {"ROTATION", ra}}}}}}}});
    g.w.doc["extensionsUsed"] = {"EXT_meshopt_compression", "EXT_mesh_gpu_instancing"};
    const cb::Scene s = load_bytes(g.glb());
    ASSERT_EQ(s.instances.size(), 3u);
    EXPECT_EQ(s.report.gpu_instances, 3u);
    // Instance 1: turned a quarter about y (x -> -z), then moved by (100, 0.5, -0.125) and the node's
    // (0, 10, 0). Translations are exact through the exponential filter (24-bit mantissas); rotations and
    // directions to their 16 bits (a few 1e-5).
    for (int v = 0; v < 4; ++v) {
        const auto p0 = world_of(s, 0, size_t(v)), p1 = world_of(s, 1, size_t(v)), p2 = world_of(s, 2, size_t(v));
        const double x = dirs[v][0], y = dirs[v][1], z = dirs[v][2];
        EXPECT_NEAR(p0[0], 1.5 + x, 5e-4);
        EXPECT_NEAR(p0[1], 10 - 2.25 + y, 5e-4);
        EXPECT_NEAR(p0[2], 3 + z, 5e-4);
        EXPECT_NEAR(p1[0], 100 + z, 5e-4);
        EXPECT_NEAR(p1[1], 10.5 + y, 5e-4);
        EXPECT_NEAR(p1[2], -0.125 - x, 5e-4);
        EXPECT_NEAR(p2[0], -6 + x, 5e-4);  // a half turn about x
        EXPECT_NEAR(p2[1], 17 - y, 5e-4);
        EXPECT_NEAR(p2[2], 8 - z, 5e-4);
    }
    EXPECT_EQ(s.instances[1].world[12] - s.instances[0].world[12], 100 - 1.5);  // exact translations
}

TEST(GltfMeshopt, BadDataIsOneLineNamingTheBufferView) {
    // A stream cut short.
    MeshoptGlb g = compressed_grid();
    json& ext = g.w.doc["bufferViews"][0]["extensions"]["EXT_meshopt_compression"];
    ext["byteLength"] = ext["byteLength"].get<size_t>() - 20;
    EXPECT_EQ(glb_error(g.glb()).rfind("t.glb: mesh 0 primitive 0: accessor 0: bufferView 0: EXT_meshopt_compression: "
                                       "bad compressed data: ATTRIBUTES stream of ",
                                       0),
              0u);
    // Bytes that are not a stream: the header of a later codec version, and garbage.
    g = compressed_grid();
    g.w.bin[g.w.doc["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]["byteOffset"].get<size_t>()] = 0xa1;
    EXPECT_NE(glb_error(g.glb()).find("bufferView 0: EXT_meshopt_compression: attribute stream header 0xa1"),
              std::string::npos);
    g = compressed_grid();
    g.w.doc["bufferViews"][1]["extensions"]["EXT_meshopt_compression"]["byteLength"] = 40;  // 32 triangles need more
    EXPECT_NE(glb_error(g.glb()).find("bufferView 1: EXT_meshopt_compression: bad compressed data: TRIANGLES"),
              std::string::npos);
    // A declared count the stream cannot hold is refused before anything is allocated for it.
    g = compressed_grid();
    g.w.doc["bufferViews"][0]["byteLength"] = 12000000000ull;
    g.w.doc["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]["count"] = 1000000000;
    g.w.doc["accessors"][0]["count"] = 1000000000;
    EXPECT_NE(glb_error(g.glb()).find("bufferView 0: EXT_meshopt_compression: count 1000000000, byteStride 12 "
                                      "declare 12000000000 bytes from a stream of "),
              std::string::npos);
    // The extension's rules: count x byteStride is the view's length, strides by mode and filter.
    g = compressed_grid();
    g.w.doc["bufferViews"][0]["byteLength"] = 12 * 24;
    EXPECT_NE(glb_error(g.glb()).find("count 25, byteStride 12 make 300 bytes, but the bufferView's byteLength is 288"),
              std::string::npos);
    g = compressed_grid();
    g.w.doc["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]["filter"] = "QUATERNION";
    EXPECT_NE(glb_error(g.glb()).find("filter QUATERNION with byteStride 12"), std::string::npos);
    g = compressed_grid();
    g.w.doc["bufferViews"][1]["extensions"]["EXT_meshopt_compression"]["mode"] = "STRIPS";
    EXPECT_NE(glb_error(g.glb()).find("mode 'STRIPS' is none of ATTRIBUTES, TRIANGLES, INDICES"), std::string::npos);
    // A plain view into the fallback buffer has no bytes to read.
    g = compressed_grid();
    g.w.doc["bufferViews"][1].erase("extensions");
    EXPECT_NE(glb_error(g.glb()).find("bufferView 1: reads buffer 1, an EXT_meshopt_compression fallback buffer"),
              std::string::npos);
}

TEST(GltfInstancing, EveryElementIsAnInstanceComposedWithTheNodeMirroredToo) {
    GltfWriter w;
    w.mesh("m", triangle(), -1);
    const float t[9] = {1, 0, 0, 0, 2, 0, 0, 0, 3};
    const float s[9] = {1, 1, 1, -1, 1, 1, 2, 2, 2};  // the second instance mirrored in x
    const int tv = w.view(t, sizeof(t), 34962), sv = w.view(s, sizeof(s), 34962);
    const int ta = w.accessor({{"bufferView", tv}, {"componentType", 5126}, {"count", 3}, {"type", "VEC3"}});
    const int sa = w.accessor({{"bufferView", sv}, {"componentType", 5126}, {"count", 3}, {"type", "VEC3"}});
    const double yaw = std::sqrt(0.5);  // the node: a quarter turn about z, then (100, 0, 0); a plain child
    w.node({{"mesh", 0},
            {"translation", {100.0, 0.0, 0.0}},
            {"rotation", {0.0, 0.0, yaw, yaw}},
            {"children", {1}},
            {"extensions", {{"EXT_mesh_gpu_instancing", {{"attributes", {{"TRANSLATION", ta}, {"SCALE", sa}}}}}}}});
    w.node({{"mesh", 0}, {"translation", {0.0, 0.0, 5.0}}});
    w.doc["scenes"] = json::array({{{"nodes", {0}}}});
    w.doc["extensionsUsed"] = {"EXT_mesh_gpu_instancing"};
    const cb::Scene sc = load_text(w.gltf_embedded());
    ASSERT_EQ(sc.instances.size(), 4u);  // three from the extension, the child once
    EXPECT_EQ(sc.meshes.size(), 1u);     // instanced, never flattened
    EXPECT_EQ(sc.report.instanced_nodes, 1u);
    EXPECT_EQ(sc.report.gpu_instances, 3u);
    // Vertex (1, 0, 0) of each: scaled, moved by the instance's translation, turned (x -> y), moved by 100.
    auto near = [](std::array<double, 3> a, std::array<double, 3> b) {
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(a[k], b[k], 1e-12) << k;
    };
    near(world_of(sc, 0, 1), {100, 2, 0});
    near(world_of(sc, 1, 1), {98, -1, 0});  // mirrored: x -> -1, then +2 in y, turned
    near(world_of(sc, 2, 1), {100, 2, 3});
    near(world_of(sc, 3, 1), {100, 1, 5});  // the child: the node's transform only
    auto det = [](const cb::Transform& m) {
        return m[0] * (m[5] * m[10] - m[6] * m[9]) - m[4] * (m[1] * m[10] - m[2] * m[9]) +
            m[8] * (m[1] * m[6] - m[2] * m[5]);
    };
    EXPECT_GT(det(sc.instances[0].world), 0);
    EXPECT_LT(det(sc.instances[1].world), 0);  // as a mirrored node's: the runtime turns its winding over
    // Accessors of different lengths, and none of the three attributes: errors naming the node.
    w.doc["accessors"][sa]["count"] = 2;
    EXPECT_EQ(error_of(w.gltf_embedded()),
              "t.gltf: node 0: EXT_mesh_gpu_instancing SCALE: has 2 elements, the other attributes 3");
    w.doc["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"] = {{"_ID", ta}};
    EXPECT_EQ(error_of(w.gltf_embedded()),
              "t.gltf: node 0: EXT_mesh_gpu_instancing: names none of TRANSLATION, "
              "ROTATION, SCALE: how many instances is unknown");
}

TEST(GltfExtensions, UnknownGeometryExtensionsWarnWhenOptionalFailWhenRequired) {
    GltfWriter w = one_mesh_scene(triangle());
    w.doc["nodes"][0]["extensions"] = {{"MSFT_lod", {{"ids", {0}}}}};
    w.doc["materials"] = json::array({{{"extensions", {{"EXT_fancy_paint", json::object()}}}}});
    w.doc["meshes"][0]["primitives"][0]["material"] = 0;
    w.doc["extensionsUsed"] = {"MSFT_lod", "EXT_fancy_paint", "KHR_texture_transform"};
    w.doc["extensionsRequired"] = {"EXT_fancy_paint"};
    const cb::Scene s = load_text(w.gltf_embedded());
    ASSERT_EQ(s.report.extensions.size(), 3u);
    EXPECT_EQ(cb::extension_text(s.report.extensions[0]), "MSFT_lod (unsupported)");
    EXPECT_EQ(s.report.extensions[0].where, "nodes");
    EXPECT_EQ(cb::extension_text(s.report.extensions[1]), "EXT_fancy_paint (required, no geometry)");
    EXPECT_EQ(cb::extension_text(s.report.extensions[2]), "KHR_texture_transform (no geometry)");
    ASSERT_EQ(s.report.warnings.size(), 1u);
    EXPECT_EQ(s.report.warnings[0],
              "t.gltf: optional extension MSFT_lod (on nodes) is not supported and could change "
              "the geometry: loaded without it");
    // Required, it is an error; so is a required unknown extension on no object at all.
    w.doc["extensionsRequired"] = {"MSFT_lod"};
    EXPECT_EQ(error_of(w.gltf_embedded()), "t.gltf: unsupported required extension MSFT_lod (on nodes)");
    w.doc["extensionsUsed"] = {"KHR_mesh_sculpting"};
    w.doc["extensionsRequired"] = {"KHR_mesh_sculpting"};
    EXPECT_EQ(error_of(w.gltf_embedded()), "t.gltf: unsupported required extension KHR_mesh_sculpting");
    // An unknown extension named nowhere but in an extras object is not one the file uses.
    GltfWriter x = one_mesh_scene(triangle());
    x.doc["asset"]["extensions"] = {{"EXT_asset_note", json::object()}};
    x.doc["nodes"][0]["extras"] = {{"extensions", {{"EXT_in_extras", 1}}}};
    const cb::Scene e = load_text(x.gltf_embedded());
    ASSERT_EQ(e.report.extensions.size(), 1u);
    EXPECT_EQ(cb::extension_text(e.report.extensions[0]), "EXT_asset_note (no geometry)");
    EXPECT_TRUE(e.report.warnings.empty());
}
