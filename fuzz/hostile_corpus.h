// Small hostile scene files, written on demand: what an attacker would upload to a bake pipeline
// (docs/SECURITY.md). The tests run the tool on each and check a one-line refusal, quickly and in little
// memory; the fuzz smoke run seeds the loaders' fuzzers with them.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace cb::hostile {

struct File {
    std::string name;    // below the corpus folder
    std::string expect;  // a part of the one-line error; empty when the file loads
};

namespace detail {

using json = nlohmann::json;

inline void write(const std::filesystem::path& path, const std::string& bytes) {
    std::filesystem::create_directories(path.parent_path());
    std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
}

// Base64 of bytes, for data URIs.
inline std::string base64(const std::string& bytes) {
    static const char digits[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    for (size_t i = 0; i < bytes.size(); i += 3) {
        uint32_t v = uint32_t(uint8_t(bytes[i])) << 16;
        if (i + 1 < bytes.size()) v |= uint32_t(uint8_t(bytes[i + 1])) << 8;
        if (i + 2 < bytes.size()) v |= uint8_t(bytes[i + 2]);
        out += digits[v >> 18];
        out += digits[(v >> 12) & 63];
        out += i + 1 < bytes.size() ? digits[(v >> 6) & 63] : '=';
        out += i + 2 < bytes.size() ? digits[v & 63] : '=';
    }
    return out;
}

// One triangle's positions as 36 bytes of little-endian floats (0,0,0) (1,0,0) (0,1,0).
inline std::string triangle_bytes() {
    const float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    return std::string(reinterpret_cast<const char*>(xyz), sizeof xyz);
}

inline std::string data_uri(const std::string& bytes) {
    return "data:application/octet-stream;base64," + base64(bytes);
}

// A glTF of one triangle (one node, one mesh) whose buffer is `uri`; callers break one part of it.
inline json triangle_gltf(const std::string& uri) {
    return {{"asset", {{"version", "2.0"}}},
            {"buffers", {{{"byteLength", 36}, {"uri", uri}}}},
            {"bufferViews", {{{"buffer", 0}, {"byteLength", 36}}}},
            {"accessors",
             {{{"bufferView", 0},
               {"componentType", 5126},
               {"count", 3},
               {"type", "VEC3"},
               {"min", {0, 0, 0}},
               {"max", {1, 1, 0}}}}},
            {"meshes", {{{"primitives", {{{"attributes", {{"POSITION", 0}}}}}}}}},
            {"nodes", {{{"mesh", 0}}}},
            {"scenes", {{{"nodes", {0}}}}},
            {"scene", 0}};
}

// A chain of `n` nodes, each the only child of the one before; the last holds the mesh, or, with `cycle`,
// names the first as its child.
inline json chain_gltf(int n, bool cycle) {
    json doc = triangle_gltf(data_uri(triangle_bytes()));
    doc["nodes"] = json::array();
    for (int i = 0; i + 1 < n; ++i) doc["nodes"].push_back({{"children", {i + 1}}});
    doc["nodes"].push_back(cycle ? json{{"children", {0}}} : json{{"mesh", 0}});
    return doc;
}

// A glTF whose only primitive is KHR_draco_mesh_compression over the bytes `stream`.
inline json draco_gltf(const std::string& stream) {
    json doc = triangle_gltf(data_uri(stream));
    doc["buffers"][0]["byteLength"] = stream.size();
    doc["bufferViews"][0]["byteLength"] = stream.size();
    doc["accessors"][0].erase("bufferView");
    doc["extensionsUsed"] = {"KHR_draco_mesh_compression"};
    doc["meshes"][0]["primitives"][0]["extensions"] = {
        {"KHR_draco_mesh_compression", {{"bufferView", 0}, {"attributes", {{"POSITION", 0}}}}}};
    return doc;
}

// Draco's varUI32.
inline std::string varint(uint64_t v) {
    std::string out;
    do {
        out += char((v & 0x7f) | (v > 0x7f ? 0x80 : 0));
        v >>= 7;
    } while (v);
    return out;
}

// A GLB container around `json_text` with a BIN chunk header that declares `bin_length` bytes.
inline std::string glb(const std::string& json_text, uint32_t bin_length, const std::string& bin) {
    std::string text = json_text;
    while (text.size() % 4) text += ' ';
    auto u32 = [](uint32_t v) { return std::string{char(v), char(v >> 8), char(v >> 16), char(v >> 24)}; };
    std::string body = u32(uint32_t(text.size())) + "JSON" + text + u32(bin_length) + std::string("BIN\0", 4) + bin;
    return "glTF" + u32(2) + u32(uint32_t(12 + body.size())) + body;
}

}  // namespace detail

// Writes the corpus into `dir` (the folder a batch would take as its root) and `outside` (a folder beside
// it holding secret.bin, a valid triangle buffer the escapes aim at, and a scene a symbolic link leads to).
// Every file is a few kilobytes at most.
inline std::vector<File> write_corpus(const std::filesystem::path& dir, const std::filesystem::path& outside) {
    using namespace detail;
    std::vector<File> files;
    auto add = [&](const std::string& name, const std::string& bytes, const std::string& expect) {
        write(dir / name, bytes);
        files.push_back({name, expect});
    };
    auto gltf = [&](const std::string& name, const json& doc, const std::string& expect) {
        add(name, doc.dump(), expect);
    };
    write(outside / "secret.bin", triangle_bytes());
    const std::string tri = data_uri(triangle_bytes());

    // Declared sizes far beyond the bytes that hold them.
    json doc = triangle_gltf(tri);
    doc["accessors"][0]["count"] = uint64_t(1) << 29;
    doc["accessors"][0].erase("min");
    doc["accessors"][0].erase("max");
    gltf("gltf/huge_accessor.gltf", doc, "needs 6442450944 bytes of bufferView 0 which has 36");
    doc = triangle_gltf(tri);
    doc["accessors"][0] = {{"componentType", 5126}, {"count", uint64_t(1) << 31}, {"type", "VEC3"}};
    gltf("gltf/huge_zero_filled.gltf", doc, "without a bufferView (zero-filled)");
    doc = triangle_gltf(tri);
    doc["accessors"][0]["sparse"] = {{"count", 3},
                                     {"indices", {{"bufferView", 0}, {"byteOffset", 30}, {"componentType", 5125}}},
                                     {"values", {{"bufferView", 0}}}};
    gltf("gltf/sparse_past_view.gltf", doc, "sparse indices: needs 42 bytes of bufferView 0 which has 36");
    doc = triangle_gltf(tri);
    doc["bufferViews"][0] = {{"buffer", 0}, {"byteOffset", 24}, {"byteLength", 36}};
    gltf("gltf/view_past_buffer.gltf", doc, "past the end of buffer 0");
    doc = triangle_gltf(tri);
    doc["accessors"][0]["byteOffset"] = 12;
    gltf("gltf/accessor_past_view.gltf", doc, "needs 48 bytes of bufferView 0 which has 36");
    add("gltf/bin_chunk_past_end.glb", glb(triangle_gltf(tri).dump(), 0x7fffffff, "xx"), "GLB BIN chunk runs past");

    // Draco streams declaring a billion faces, or cut short after their header.
    std::string header = std::string("DRACO\x02\x02\x01", 8);
    gltf("gltf/draco_huge_counts.gltf",
         draco_gltf(header + std::string("\x01\x00\x00\x00", 4) + varint(3'000'000'000u) + varint(1'000'000'000) +
                    std::string(24, '\0')),
         "Draco: declares 1000000000 faces");
    gltf("gltf/draco_truncated.gltf", draco_gltf(header + std::string("\x00\x00\x00", 3) + varint(50) + varint(36)),
         "Draco: ");

    // EXT_meshopt_compression: a view declaring a billion 12-byte vertices from a stream of 40 bytes, and
    // a stream cut short.
    auto meshopt_gltf = [&](uint64_t count, size_t stream_bytes) {
        json d = triangle_gltf(data_uri(std::string("\xa0", 1) + std::string(stream_bytes - 1, '\0')));
        d["buffers"][0]["byteLength"] = stream_bytes;
        d["bufferViews"][0] = {{"buffer", 0},
                               {"byteLength", count * 12},
                               {"byteStride", 12},
                               {"extensions",
                                {{"EXT_meshopt_compression",
                                  {{"buffer", 0},
                                   {"byteLength", stream_bytes},
                                   {"byteStride", 12},
                                   {"count", count},
                                   {"mode", "ATTRIBUTES"}}}}}};
        d["accessors"][0]["count"] = count;
        d["extensionsUsed"] = {"EXT_meshopt_compression"};
        d["extensionsRequired"] = {"EXT_meshopt_compression"};
        return d;
    };
    gltf("gltf/meshopt_huge_count.gltf", meshopt_gltf(1'000'000'000, 40),
         "EXT_meshopt_compression: count 1000000000, byteStride 12 declare 12000000000 bytes from a stream of 40");
    gltf("gltf/meshopt_truncated.gltf", meshopt_gltf(3, 8), "EXT_meshopt_compression: bad compressed data");

    // Parts the loader never reads, in bulk: a million empty arrays in "extras", a million empty objects
    // in an extension. Both load, without holding them.
    doc = triangle_gltf(tri);
    doc["extras"] = json::array();
    for (int i = 0; i < 1'000'000; ++i) doc["extras"].push_back(json::array());
    gltf("gltf/bulky_extras.gltf", doc, "");
    doc = triangle_gltf(tri);
    doc["extensions"]["EXT_bulk"] = json::object();
    for (int i = 0; i < 300'000; ++i) doc["extensions"]["EXT_bulk"][std::to_string(i)] = json::object();
    gltf("gltf/bulky_extension.gltf", doc, "");

    // Node hierarchies: a chain 20,000 deep loads; a cycle through all of it and a DAG that doubles the
    // paths at each of 40 levels are refused.
    gltf("gltf/deep_chain.gltf", chain_gltf(20000, false), "");
    gltf("gltf/long_cycle.gltf", chain_gltf(20000, true), "node cycle");
    doc = triangle_gltf(tri);
    doc["nodes"] = json::array({{{"mesh", 0}}});
    for (int level = 1; level <= 40; ++level) {
        int below = level == 1 ? 0 : 2 * level - 3;
        doc["nodes"].push_back({{"children", {below, level == 1 ? 0 : below + 1}}});
        doc["nodes"].push_back({{"children", {below, level == 1 ? 0 : below + 1}}});
    }
    doc["scenes"] = json::array({{{"nodes", {int(doc["nodes"].size()) - 1}}}});
    gltf("gltf/exponential_dag.gltf", doc, "node visits");

    // External files that lead out of the folder, every way.
    gltf("gltf/escape_dotdot.gltf", triangle_gltf("../../" + outside.filename().string() + "/secret.bin"),
         "refused: a '..' leads out");
    gltf("gltf/escape_percent.gltf", triangle_gltf("..%2F..%2F" + outside.filename().string() + "%2Fsecret.bin"),
         "refused: a '..' leads out");
    gltf("gltf/escape_absolute.gltf", triangle_gltf(std::filesystem::absolute(outside / "secret.bin").string()),
         "refused: an absolute path");
    gltf("gltf/escape_file_uri.gltf",
         triangle_gltf("file://" + std::filesystem::absolute(outside / "secret.bin").string()),
         "refused: a URI with a scheme ('file:')");
    std::error_code ec;
    std::filesystem::remove(dir / "gltf/link.bin", ec);
    std::filesystem::create_symlink(std::filesystem::absolute(outside / "secret.bin"), dir / "gltf/link.bin", ec);
    if (!ec) gltf("gltf/escape_symlink.gltf", triangle_gltf("link.bin"), "refused: a symbolic link leads out");

    // Text and binary mesh formats: counts no file of that size can hold.
    add("mesh/huge_counts.off", "OFF\n1000000000 1000000000 0\n0 0 0\n", "exceed what the file can hold");
    add("mesh/huge_vertex_count.ply",
        "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\n"
        "property float z\nend_header\n" +
            std::string(24, '\0'),
        "count 4000000000 exceeds the data");
    add("mesh/huge_list.ply",
        "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n" +
            std::string(36, '\0') + std::string("\xff\xff\xff\x7f", 4),
        "list length");
    add("mesh/short_vertices.ply",
        "ply\nformat ascii 1.0\nelement vertex 1000\nproperty float x\nproperty float y\nproperty float z\n"
        "end_header\n" +
            std::string(2000, ' ') + "0 0 0\n",
        "unexpected end of data");
    add("mesh/huge_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 1099511627776\n", "out of range");
    add("mesh/huge_facets.stl", std::string(80, 'x') + std::string("\xff\xff\xff\xff", 4) + std::string(50, '\0'),
        "not an STL file");
    add("mesh/truncated_facet.stl", "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n",
        "truncated");
    return files;
}

}  // namespace cb::hostile
