// A minimal glTF 2.0 writer for generated inputs: the data/ generator and the loader tests build files with
// it. Every mesh gets float positions and uint32 indices in one binary buffer.
#pragma once

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

namespace cb::data {

using json = nlohmann::json;

struct MeshData {
    std::vector<float> positions;
    std::vector<uint32_t> indices;
};

struct GltfWriter {
    json doc = {{"asset", {{"version", "2.0"}, {"generator", "clusterbake data/generate/make_data"}}}};
    std::vector<uint8_t> bin;

    int view(const void* data, size_t size, int target) {
        while (bin.size() % 4) bin.push_back(0);
        size_t offset = bin.size();
        bin.insert(bin.end(), (const uint8_t*)data, (const uint8_t*)data + size);
        doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", size}, {"target", target}});
        return int(doc["bufferViews"].size() - 1);
    }

    int mesh(const std::string& name, const MeshData& m, int material) {
        float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
        for (size_t i = 0; i < m.positions.size(); ++i) {
            lo[i % 3] = std::min(lo[i % 3], m.positions[i]);
            hi[i % 3] = std::max(hi[i % 3], m.positions[i]);
        }
        int pv = view(m.positions.data(), m.positions.size() * 4, 34962);
        doc["accessors"].push_back({{"bufferView", pv},
                                    {"componentType", 5126},
                                    {"count", m.positions.size() / 3},
                                    {"type", "VEC3"},
                                    {"min", {lo[0], lo[1], lo[2]}},
                                    {"max", {hi[0], hi[1], hi[2]}}});
        int pa = int(doc["accessors"].size() - 1);
        int iv = view(m.indices.data(), m.indices.size() * 4, 34963);
        doc["accessors"].push_back(
            {{"bufferView", iv}, {"componentType", 5125}, {"count", m.indices.size()}, {"type", "SCALAR"}});
        int ia = int(doc["accessors"].size() - 1);
        json prim = {{"attributes", {{"POSITION", pa}}}, {"indices", ia}, {"mode", 4}};
        if (material >= 0) prim["material"] = material;
        doc["meshes"].push_back({{"name", name}, {"primitives", json::array({prim})}});
        return int(doc["meshes"].size() - 1);
    }

    int node(json n) {
        doc["nodes"].push_back(std::move(n));
        return int(doc["nodes"].size() - 1);
    }

    // Appends an accessor over a view and returns its index.
    int accessor(json a) {
        doc["accessors"].push_back(std::move(a));
        return int(doc["accessors"].size() - 1);
    }

    // The document with its buffer embedded as a base64 data URI.
    std::string gltf_embedded() {
        static const char* b64 = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        std::string enc;
        for (size_t i = 0; i < bin.size(); i += 3) {
            uint32_t v = uint32_t(bin[i]) << 16 | (i + 1 < bin.size() ? uint32_t(bin[i + 1]) << 8 : 0) |
                (i + 2 < bin.size() ? bin[i + 2] : 0);
            enc += b64[v >> 18 & 63];
            enc += b64[v >> 12 & 63];
            enc += i + 1 < bin.size() ? b64[v >> 6 & 63] : '=';
            enc += i + 2 < bin.size() ? b64[v & 63] : '=';
        }
        json d = doc;
        d["buffers"] =
            json::array({{{"byteLength", bin.size()}, {"uri", "data:application/octet-stream;base64," + enc}}});
        return d.dump(1);
    }

    // The GLB: buffer 0 is its BIN chunk, `more_buffers` (such as fallback buffers without data) follow it.
    std::vector<uint8_t> glb(const json& more_buffers = json::array()) {
        while (bin.size() % 4) bin.push_back(0);
        doc["buffers"] = json::array({{{"byteLength", bin.size()}}});
        for (const json& b : more_buffers) doc["buffers"].push_back(b);
        std::string text = doc.dump();
        while (text.size() % 4) text.push_back(' ');
        std::vector<uint8_t> out;
        auto u32 = [&](uint32_t v) {
            for (int i = 0; i < 4; ++i) out.push_back(uint8_t(v >> (8 * i)));
        };
        out.insert(out.end(), {'g', 'l', 'T', 'F'});
        u32(2);
        u32(uint32_t(12 + 8 + text.size() + 8 + bin.size()));
        u32(uint32_t(text.size()));
        u32(0x4E4F534A);
        out.insert(out.end(), text.begin(), text.end());
        u32(uint32_t(bin.size()));
        u32(0x004E4942);
        out.insert(out.end(), bin.begin(), bin.end());
        return out;
    }
};

}  // namespace cb::data
