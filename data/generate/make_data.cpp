// Writes every file in data/: the default scene and the small per-format inputs the tests and fuzzers
// start from. Run: make_data OUTDIR. Deterministic: the same binary writes the same bytes.
#include "gltf_writer.h"

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

namespace {

using json = nlohmann::json;
using cb::data::GltfWriter;
using cb::data::MeshData;

// ---------------------------------------------------------------- shapes

MeshData grid_plane(int n, float size) {
    MeshData m;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i)
            m.positions.insert(m.positions.end(), {size * (float(i) / n - 0.5f), 0.0f, size * (float(j) / n - 0.5f)});
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            uint32_t a = j * (n + 1) + i, b = a + 1, c = a + (n + 1), d = c + 1;
            m.indices.insert(m.indices.end(), {a, c, b, b, c, d});  // counter-clockwise seen from +y
        }
    return m;
}

// Integer hash noise, so the shapes do not depend on a random library's implementation.
float hash_noise(uint32_t x) {
    x ^= x >> 16;
    x *= 0x7feb352dU;
    x ^= x >> 15;
    x *= 0x846ca68bU;
    x ^= x >> 16;
    return float(x & 0xffffff) / float(0xffffff) * 2.0f - 1.0f;
}

// An icosphere subdivided `levels` times, displaced along its normals by a few octaves of smooth bumps:
// a closed, scanned-looking blob.
MeshData blob(int levels, uint32_t seed) {
    const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
    MeshData m;
    m.positions = {-1, t,  0,  1, t, 0,  -1, -t, 0,  1, -t, 0, 0,  -1, t,  0,  1, t,
                   0,  -1, -t, 0, 1, -t, t,  0,  -1, t, 0,  1, -t, 0,  -1, -t, 0, 1};
    m.indices = {0, 11, 5, 0, 5, 1, 0, 1, 7, 0, 7, 10, 0, 10, 11, 1, 5, 9, 5, 11, 4,  11, 10, 2,  10, 7, 6, 7, 1, 8,
                 3, 9,  4, 3, 4, 2, 3, 2, 6, 3, 6, 8,  3, 8,  9,  4, 9, 5, 2, 4,  11, 6,  2,  10, 8,  6, 7, 9, 8, 1};
    auto normalize = [&](uint32_t v) {
        float* p = &m.positions[v * 3];
        float l = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        p[0] /= l;
        p[1] /= l;
        p[2] /= l;
    };
    for (uint32_t v = 0; v < 12; ++v) normalize(v);
    for (int level = 0; level < levels; ++level) {
        std::map<uint64_t, uint32_t> midpoint;
        auto mid = [&](uint32_t a, uint32_t b) {
            uint64_t key = uint64_t(std::min(a, b)) << 32 | std::max(a, b);
            auto it = midpoint.find(key);
            if (it != midpoint.end()) return it->second;
            uint32_t v = uint32_t(m.positions.size() / 3);
            for (int k = 0; k < 3; ++k) m.positions.push_back((m.positions[a * 3 + k] + m.positions[b * 3 + k]) / 2);
            normalize(v);
            midpoint[key] = v;
            return v;
        };
        std::vector<uint32_t> next;
        for (size_t f = 0; f < m.indices.size(); f += 3) {
            uint32_t a = m.indices[f], b = m.indices[f + 1], c = m.indices[f + 2];
            uint32_t ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
            next.insert(next.end(), {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca});
        }
        m.indices.swap(next);
    }
    // Bumps: sums of a few random directional waves.
    float dir[12][3], phase[12];
    for (int w = 0; w < 12; ++w) {
        for (int k = 0; k < 3; ++k) dir[w][k] = hash_noise(seed * 131 + w * 7 + k) * (1.5f + w * 0.6f);
        phase[w] = hash_noise(seed * 131 + w * 7 + 5) * 3.14159f;
    }
    for (size_t v = 0; v < m.positions.size() / 3; ++v) {
        float* p = &m.positions[v * 3];
        float r = 1.0f;
        for (int w = 0; w < 12; ++w)
            r += 0.12f / (1 + w * 0.5f) * std::sin(p[0] * dir[w][0] + p[1] * dir[w][1] + p[2] * dir[w][2] + phase[w]);
        p[0] *= r;
        p[1] *= r * 0.8f;
        p[2] *= r;
    }
    return m;
}

// A fence: posts and rails as long, thin, two-sided quads (fence triangles are the classic thin occluders).
MeshData fence(int posts, float spacing, float height) {
    MeshData m;
    auto quad = [&](std::array<float, 3> a, std::array<float, 3> b, std::array<float, 3> c, std::array<float, 3> d) {
        uint32_t base = uint32_t(m.positions.size() / 3);
        for (auto* p : {&a, &b, &c, &d}) m.positions.insert(m.positions.end(), p->begin(), p->end());
        m.indices.insert(m.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
    };
    const float w = 0.04f;
    for (int i = 0; i < posts; ++i) {
        float x = i * spacing;
        quad({x - w, 0, 0}, {x + w, 0, 0}, {x + w, height, 0}, {x - w, height, 0});
    }
    for (float y : {height * 0.35f, height * 0.8f})
        quad({0, y - w, 0}, {(posts - 1) * spacing, y - w, 0}, {(posts - 1) * spacing, y + w, 0}, {0, y + w, 0});
    return m;
}

// A small pillar with a capital: the instanced object.
MeshData pillar() {
    MeshData m;
    const uint32_t sides = 12;
    auto ring = [&](float y, float r) {
        for (uint32_t s = 0; s < sides; ++s) {
            float a = 2 * 3.14159265f * s / sides;
            m.positions.insert(m.positions.end(), {r * std::cos(a), y, r * std::sin(a)});
        }
    };
    float ys[] = {0, 0.1f, 1.6f, 1.75f, 1.9f}, rs[] = {0.3f, 0.22f, 0.18f, 0.32f, 0.32f};
    for (int i = 0; i < 5; ++i) ring(ys[i], rs[i]);
    for (uint32_t r = 0; r < 4; ++r)
        for (uint32_t s = 0; s < sides; ++s) {
            uint32_t a = r * sides + s, b = r * sides + (s + 1) % sides, c = a + sides, d = b + sides;
            m.indices.insert(m.indices.end(), {a, c, b, b, c, d});
        }
    uint32_t top = uint32_t(m.positions.size() / 3);
    m.positions.insert(m.positions.end(), {0, 1.9f, 0});
    for (uint32_t s = 0; s < sides; ++s)
        m.indices.insert(m.indices.end(), {top, 4 * sides + (s + 1) % sides, 4 * sides + s});
    return m;
}

std::vector<uint8_t> default_scene() {
    GltfWriter w;
    w.doc["materials"] =
        json::array({{{"name", "single_sided"}}, {{"name", "fence_two_sided"}, {"doubleSided", true}}});
    int ground = w.mesh("ground", grid_plane(64, 40.0f), 0);
    int blob_a = w.mesh("blob_a", blob(5, 1), 0);
    int blob_b = w.mesh("blob_b", blob(4, 2), 0);
    int fence_mesh = w.mesh("fence", fence(24, 0.75f, 1.2f), 1);
    int pillar_mesh = w.mesh("pillar", pillar(), 0);

    std::vector<int> children;
    children.push_back(w.node({{"name", "ground"}, {"mesh", ground}}));
    children.push_back(
        w.node({{"name", "blob_a"}, {"mesh", blob_a}, {"translation", {-4.0, 1.0, 2.0}}, {"scale", {1.5, 1.5, 1.5}}}));
    children.push_back(w.node({{"name", "blob_b"},
                               {"mesh", blob_b},
                               {"translation", {5.0, 0.9, -3.0}},
                               {"rotation", {0.0, 0.3826834, 0.0, 0.9238795}}}));
    children.push_back(w.node({{"name", "fence"}, {"mesh", fence_mesh}, {"translation", {-9.0, 0.0, 8.0}}}));
    // The pillar mesh is stored once and placed by eight nodes under a rotated group.
    std::vector<int> colonnade;
    for (int i = 0; i < 8; ++i)
        colonnade.push_back(w.node({{"name", "pillar_" + std::to_string(i)},
                                    {"mesh", pillar_mesh},
                                    {"translation", {i * 2.0 - 7.0, 0.0, 0.0}}}));
    children.push_back(w.node({{"name", "colonnade"},
                               {"children", colonnade},
                               {"translation", {0.0, 0.0, -9.0}},
                               {"rotation", {0.0, 0.0871557, 0.0, 0.9961947}}}));
    int root = w.node({{"name", "root"}, {"children", children}});
    w.doc["scenes"] = json::array({{{"name", "default"}, {"nodes", {root}}}});
    w.doc["scene"] = 0;
    return w.glb();
}

// ---------------------------------------------------------------- small per-format inputs

const float cube_v[8][3] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                            {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};
const int cube_q[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {2, 3, 7, 6}, {1, 2, 6, 5}, {0, 4, 7, 3}};

std::string cube_obj() {
    std::string s = "# unit cube, quads, written by clusterbake's make_data\n";
    for (auto& v : cube_v)
        s += "v " + std::to_string(v[0]) + " " + std::to_string(v[1]) + " " + std::to_string(v[2]) + "\n";
    for (auto& q : cube_q)
        s += "f " + std::to_string(q[0] + 1) + " " + std::to_string(q[1] + 1) + " " + std::to_string(q[2] + 1) + " " +
            std::to_string(q[3] + 1) + "\n";
    return s;
}

std::string cube_off() {
    std::string s = "OFF\n# unit cube\n8 6 12\n";
    for (auto& v : cube_v) s += std::to_string(v[0]) + " " + std::to_string(v[1]) + " " + std::to_string(v[2]) + "\n";
    for (auto& q : cube_q)
        s += "4 " + std::to_string(q[0]) + " " + std::to_string(q[1]) + " " + std::to_string(q[2]) + " " +
            std::to_string(q[3]) + "\n";
    return s;
}

std::string cube_ply(bool binary) {
    std::string s = std::string("ply\nformat ") + (binary ? "binary_little_endian" : "ascii") +
        " 1.0\nelement vertex 8\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 6\nproperty list uchar int vertex_indices\nend_header\n";
    for (auto& v : cube_v) {
        if (binary)
            s.append((const char*)v, 12);
        else
            s += std::to_string(v[0]) + " " + std::to_string(v[1]) + " " + std::to_string(v[2]) + "\n";
    }
    for (auto& q : cube_q) {
        if (binary) {
            s.push_back(4);
            s.append((const char*)q, 16);
        } else
            s += "4 " + std::to_string(q[0]) + " " + std::to_string(q[1]) + " " + std::to_string(q[2]) + " " +
                std::to_string(q[3]) + "\n";
    }
    return s;
}

std::string cube_stl(bool binary) {
    std::vector<std::array<int, 3>> tris;
    for (auto& q : cube_q) {
        tris.push_back({q[0], q[1], q[2]});
        tris.push_back({q[0], q[2], q[3]});
    }
    std::string s;
    if (binary) {
        s.assign(80, '\0');
        s.replace(0, 32, "clusterbake make_data binary STL");
        uint32_t n = uint32_t(tris.size());
        s.append((const char*)&n, 4);
        for (auto& t : tris) {
            float zero[3] = {0, 0, 0};
            s.append((const char*)zero, 12);
            for (int k : t) s.append((const char*)cube_v[k], 12);
            s.append(2, '\0');
        }
        return s;
    }
    s = "solid cube\n";
    for (auto& t : tris) {
        s += "  facet normal 0 0 0\n    outer loop\n";
        for (int k : t)
            s += "      vertex " + std::to_string(cube_v[k][0]) + " " + std::to_string(cube_v[k][1]) + " " +
                std::to_string(cube_v[k][2]) + "\n";
        s += "    endloop\n  endfacet\n";
    }
    return s + "endsolid cube\n";
}

// A .gltf with one embedded buffer exercising strips, fans, lines, a sparse accessor, quantised positions
// and byteStride: the seed of the glTF fuzzer.
std::string primitive_modes_gltf() {
    GltfWriter w;
    float strip[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 2, 0, 1, 2, 0};
    int sv = w.view(strip, sizeof strip, 34962);
    w.doc["accessors"].push_back({{"bufferView", sv}, {"componentType", 5126}, {"count", 6}, {"type", "VEC3"}});
    // Interleaved: position (3 x int16, normalized) padded to 8 bytes per vertex.
    int16_t quant[] = {0, 0, 0, 0, 32767, 0, 0, 0, 32767, 32767, 0, 0, 0, 32767, 0, 0};
    int qv = w.view(quant, sizeof quant, 34962);
    w.doc["bufferViews"][qv]["byteStride"] = 8;
    w.doc["accessors"].push_back(
        {{"bufferView", qv}, {"componentType", 5122}, {"normalized", true}, {"count", 4}, {"type", "VEC3"}});
    uint16_t sparse_idx[] = {1};
    float sparse_val[] = {0.5f, 0.25f, 0.125f};
    int si = w.view(sparse_idx, sizeof sparse_idx, 0);
    int sval = w.view(sparse_val, sizeof sparse_val, 0);
    w.doc["accessors"].push_back({{"bufferView", sv},
                                  {"componentType", 5126},
                                  {"count", 6},
                                  {"type", "VEC3"},
                                  {"sparse",
                                   {{"count", 1},
                                    {"indices", {{"bufferView", si}, {"componentType", 5123}}},
                                    {"values", {{"bufferView", sval}}}}}});
    json prims = json::array({{{"attributes", {{"POSITION", 0}}}, {"mode", 5}},
                              {{"attributes", {{"POSITION", 1}}}, {"mode", 6}},
                              {{"attributes", {{"POSITION", 2}}}, {"mode", 4}},
                              {{"attributes", {{"POSITION", 0}}}, {"mode", 1}}});
    w.doc["meshes"] = json::array({{{"name", "modes"}, {"primitives", prims}}});
    w.doc["nodes"] = json::array({{{"mesh", 0}}});
    w.doc["scenes"] = json::array({{{"nodes", {0}}}});
    w.doc["scene"] = 0;
    w.doc["extensionsUsed"] = {"KHR_mesh_quantization"};
    w.doc["extensionsRequired"] = {"KHR_mesh_quantization"};
    return w.gltf_embedded();
}

bool write(const std::string& path, const void* data, size_t size) {
    std::ofstream out(path, std::ios::binary);
    out.write((const char*)data, std::streamsize(size));
    if (!out) std::fprintf(stderr, "make_data: cannot write %s\n", path.c_str());
    return bool(out);
}
bool write(const std::string& path, const std::string& s) { return write(path, s.data(), s.size()); }

}  // namespace

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: make_data OUTDIR\n");
        return 1;
    }
    std::string dir = argv[1];
    std::error_code ec;
    std::filesystem::create_directories(dir + "/small", ec);
    std::vector<uint8_t> scene = default_scene();
    bool ok = write(dir + "/default_scene.glb", scene.data(), scene.size()) &&
        write(dir + "/small/cube.obj", cube_obj()) && write(dir + "/small/cube.off", cube_off()) &&
        write(dir + "/small/cube_ascii.ply", cube_ply(false)) &&
        write(dir + "/small/cube_binary.ply", cube_ply(true)) &&
        write(dir + "/small/cube_ascii.stl", cube_stl(false)) &&
        write(dir + "/small/cube_binary.stl", cube_stl(true)) &&
        write(dir + "/small/primitive_modes.gltf", primitive_modes_gltf());
    return ok ? 0 : 1;
}
