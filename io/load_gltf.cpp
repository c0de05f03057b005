// glTF 2.0 loading: tinygltf parses the JSON and buffers (images are never decoded), this file turns
// accessors into flat arrays, checking every range against its buffer before reading a byte of it.
#include <draco/compression/decode.h>
#include <meshoptimizer.h>
#include <tiny_gltf.h>

#include <nlohmann/json.hpp>

#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include "draco_header.h"
#include "file_access.h"
#include "load.h"

namespace cb {
namespace {

constexpr const char* meshopt_name = "EXT_meshopt_compression";
constexpr const char* instancing_name = "EXT_mesh_gpu_instancing";

// Extensions the loader reads into the geometry.
bool is_applied_extension(const std::string& name) {
    return name == "KHR_draco_mesh_compression" || name == "KHR_mesh_quantization" || name == meshopt_name ||
        name == instancing_name;
}

// Extensions whose presence changes nothing about positions, indices, instances or sidedness, so a file
// that requires them is still loaded exactly.
bool is_no_geometry_extension(const std::string& name) {
    static const char* known[] = {"KHR_texture_transform", "KHR_texture_basisu",     "KHR_lights_punctual",
                                  "KHR_materials_common",  "EXT_texture_webp",       "EXT_texture_avif",
                                  "KHR_xmp_json_ld",       "KHR_materials_variants", "KHR_animation_pointer"};
    for (const char* k : known)
        if (name == k) return true;
    return name.rfind("KHR_materials_", 0) == 0;  // every material extension: no geometry
}

// The kinds of objects whose extensions cannot change what the loader reads: an unknown extension found
// only on these is skipped without a word. On any other object (meshes, nodes, accessors, bufferViews,
// buffers, scenes, the document itself) it could.
bool owner_without_geometry(const std::string& owner) {
    static const char* owners[] = {"materials",  "textures", "images",  "samplers",
                                   "animations", "skins",    "cameras", "asset"};
    for (const char* o : owners)
        if (owner == o) return true;
    return false;
}

// Where each extension of the document was found, by the kind of object that holds it ("meshes",
// "nodes", "the document"), in the order first seen.
struct ExtensionSightings {
    std::vector<std::string> order;
    std::map<std::string, std::set<std::string>> owners;

    void add(const std::string& name, const std::string& owner) {
        auto [it, fresh] = owners.try_emplace(name);
        if (fresh) order.push_back(name);
        it->second.insert(owner);
    }
};

// tinygltf 2.7 refuses a primitive whose indices accessor has no bufferView, yet that is what every
// KHR_draco_mesh_compression primitive looks like (its data lives in the extension), and what a sparse or
// all-zero index accessor looks like. Such "indices" are taken out of the JSON before tinygltf reads it and
// kept here, by (mesh, primitive).
using DetachedIndices = std::map<std::pair<size_t, size_t>, int>;

bool detach_viewless_indices(nlohmann::json& doc, DetachedIndices& detached) {
    if (!doc.is_object() || !doc.contains("meshes") || !doc["meshes"].is_array()) return false;
    const nlohmann::json* accessors =
        doc.contains("accessors") && doc["accessors"].is_array() ? &doc["accessors"] : nullptr;
    bool changed = false;
    for (size_t m = 0; m < doc["meshes"].size(); ++m) {
        nlohmann::json& mesh = doc["meshes"][m];
        if (!mesh.is_object() || !mesh.contains("primitives") || !mesh["primitives"].is_array()) continue;
        for (size_t p = 0; p < mesh["primitives"].size(); ++p) {
            nlohmann::json& prim = mesh["primitives"][p];
            if (!prim.is_object() || !prim.contains("indices") || !prim["indices"].is_number_unsigned()) continue;
            size_t k = prim["indices"].get<size_t>();
            if (!accessors || k >= accessors->size() || !(*accessors)[k].is_object() ||
                (*accessors)[k].contains("bufferView"))
                continue;  // well-formed, or an error tinygltf reports itself
            detached[{m, p}] = int(k);
            prim.erase("indices");
            changed = true;
        }
    }
    return changed;
}

uint32_t read_u32(const uint8_t* p) {
    return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}
void write_u32(std::vector<uint8_t>& out, size_t at, uint32_t v) {
    for (int i = 0; i < 4; ++i) out[at + i] = uint8_t(v >> (8 * i));
}

// tinygltf 2.7 checks the BIN chunk's length without its 8-byte chunk header and then copies past the end
// of the file (found by fuzz_gltf). The container is checked here first. Returns an empty string when the
// layout is sound, else what is wrong.
std::string glb_layout_error(const uint8_t* data, size_t size) {
    if (size < 20) return "GLB shorter than its 20-byte header";
    if (read_u32(data + 4) != 2) return "GLB version " + std::to_string(read_u32(data + 4)) + " (only 2 is supported)";
    uint64_t length = read_u32(data + 8);
    if (length > size)
        return "GLB header says " + std::to_string(length) + " bytes, file has " + std::to_string(size) +
            " (truncated?)";
    uint64_t json_end = 20 + uint64_t(read_u32(data + 12));
    if (read_u32(data + 16) != 0x4E4F534Au) return "GLB first chunk is not JSON";
    if (json_end > length) return "GLB JSON chunk runs past the end of the file";
    if (json_end == length) return "";
    if (json_end + 8 > length) return "GLB has a partial chunk header after the JSON chunk";
    uint64_t bin_end = json_end + 8 + uint64_t(read_u32(data + json_end));
    if (bin_end > length) return "GLB BIN chunk runs past the end of the file (truncated?)";
    return "";
}

// The document's JSON (a GLB's JSON chunk, whose layout glb_layout_error has checked). Parsed here rather
// than by tinygltf, whose error is the JSON library's raw exception text: a file that is not glTF at all is
// said to be so, with where its JSON breaks.
// Parts the loader never reads ("extras", and extensions other than the three it decodes: their names are
// a prefix, an underscore and a lower-case letter) are dropped as they are parsed, with whatever they nest,
// so that neither this document nor tinygltf's model holds them: a few megabytes of "[[],[],..." there
// made both hold hundreds. `pruned` tells whether anything was dropped. The name of every extension met on
// the way, and the kind of object it is on, go into `seen` all the same.
bool never_read(const std::string& key) {
    if (key == "extras") return true;
    const size_t underscore = key.find('_');
    if (underscore == 0 || underscore == std::string::npos || underscore + 1 == key.size()) return false;
    for (size_t i = 0; i < underscore; ++i)
        if (!std::isupper(uint8_t(key[i])) && !std::isdigit(uint8_t(key[i]))) return false;
    return std::islower(uint8_t(key[underscore + 1])) && key != "KHR_draco_mesh_compression" && key != meshopt_name &&
        key != instancing_name;
}

nlohmann::json parse_document(const uint8_t* data, size_t size, bool binary, const std::string& name, bool& pruned,
                              ExtensionSightings& seen) {
    const uint8_t* begin = binary ? data + 20 : data;
    const size_t length = binary ? read_u32(data + 12) : size;
    nlohmann::json doc;
    pruned = false;
    // keys[d]: the last key read at depth d, or "[" where an array holds that level. The top-level object's
    // keys are at depth 1, so an extension's name is a key whose parent key is "extensions", and keys[1]
    // names the kind of object it is on.
    std::vector<std::string> keys;
    int dropping = -1;  // the depth of a key whose value is being dropped, -1 when none
    auto keep = [&](int depth, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
        using event_t = nlohmann::json::parse_event_t;
        if (depth < 0) return true;
        const size_t d = size_t(depth);
        if (event == event_t::array_start) {
            if (keys.size() < d + 2) keys.resize(d + 2);
            keys[d + 1] = "[";
            return true;
        }
        if (event != event_t::key || !parsed.is_string()) return true;
        if (dropping >= 0 && depth > dropping) return false;  // inside what is dropped: neither read nor seen
        dropping = -1;
        const std::string& key = parsed.get_ref<const std::string&>();
        if (keys.size() < d + 1) keys.resize(d + 1);
        keys[d] = key;
        if (d >= 2 && keys[d - 1] == "extensions")
            seen.add(key, d == 2 || keys[1] == "extensions" ? "the document" : keys[1]);
        if (!never_read(key)) return true;
        pruned = true;
        dropping = depth;
        return false;
    };
    try {
        doc = nlohmann::json::parse(begin, begin + length, keep);
    } catch (const nlohmann::json::parse_error& e) {
        const std::string at = "parse error at byte " + std::to_string(e.byte);
        if (binary) throw LoadError(name + ": GLB JSON chunk is not JSON text (" + at + " of the chunk)");
        throw LoadError(name + ": not a glTF file: neither binary glTF (magic 'glTF') nor JSON text (" + at + ")");
    } catch (const nlohmann::json::exception& e) {  // such as a number past double's range
        std::string what = e.what();
        what.erase(0, what.find("] ") == std::string::npos ? 0 : what.find("] ") + 2);
        throw LoadError(name + (binary ? ": GLB JSON chunk: " : ": JSON: ") + what);
    }
    const auto asset = doc.is_object() ? doc.find("asset") : doc.end();
    if (asset == doc.end() || !asset->is_object() || !asset->contains("version") || !(*asset)["version"].is_string())
        throw LoadError(name + ": not a glTF file: JSON without an \"asset\" object naming its \"version\"");
    return doc;
}

// What is wrong with an external buffer file of the document, or empty: tinygltf's message for it ("File
// not found : x.bin") names neither the buffer nor where it looked.
std::string buffer_file_problem(const nlohmann::json& doc, const std::string& base_dir) {
    const auto buffers = doc.find("buffers");
    if (buffers == doc.end() || !buffers->is_array()) return {};
    for (size_t i = 0; i < buffers->size(); ++i) {
        const nlohmann::json& b = (*buffers)[i];
        if (!b.is_object() || !b.contains("uri") || !b["uri"].is_string()) continue;
        const std::string uri = b["uri"];
        if (uri.rfind("data:", 0) == 0) continue;
        const std::filesystem::path path = std::filesystem::path(base_dir) / percent_decoded(uri);
        const std::string where = "buffer " + std::to_string(i) + ": '" + uri + "'";
        std::error_code ec;
        if (!std::filesystem::exists(path, ec)) return where + ": no such file (looked for " + path.string() + ")";
        if (!std::filesystem::is_regular_file(path, ec)) return where + ": not a regular file";
        const uint64_t bytes = std::filesystem::file_size(path, ec);
        if (b.contains("byteLength") && b["byteLength"].is_number_unsigned() &&
            b["byteLength"].get<uint64_t>() != bytes)
            return where + ": " + std::to_string(bytes) + " bytes, but its byteLength is " +
                std::to_string(b["byteLength"].get<uint64_t>());
    }
    return {};
}

// EXT_meshopt_compression's fallback buffers hold the uncompressed data for loaders without the
// extension; this one decodes the compressed views instead and never reads them. Often they have no data
// at all (no URI, only a byteLength), which tinygltf takes for the GLB's BIN chunk and refuses. A fallback
// buffer is one marked so ("fallback": true), or one without a URI (other than a GLB's buffer 0) that only
// compressed views name as their buffer. Each is replaced in `doc` by a one-byte buffer, and its index and
// declared length are kept here.
using FallbackBuffers = std::map<int, uint64_t>;

bool is_marked_fallback(const nlohmann::json& b) {
    const auto ext = b.find("extensions");
    if (ext == b.end() || !ext->is_object()) return false;
    const auto meshopt = ext->find(meshopt_name);
    if (meshopt == ext->end() || !meshopt->is_object()) return false;
    const auto flag = meshopt->find("fallback");
    return flag != meshopt->end() && flag->is_boolean() && flag->get<bool>();
}

bool detach_fallback_buffers(nlohmann::json& doc, bool binary, FallbackBuffers& fallback) {
    const auto buffers = doc.find("buffers");
    if (buffers == doc.end() || !buffers->is_array()) return false;
    // Per buffer: how many views name it, and how many of those are compressed.
    std::vector<size_t> views(buffers->size(), 0), compressed(buffers->size(), 0);
    if (const auto v = doc.find("bufferViews"); v != doc.end() && v->is_array())
        for (const nlohmann::json& view : *v) {
            if (!view.is_object() || !view.contains("buffer") || !view["buffer"].is_number_unsigned()) continue;
            const size_t b = view["buffer"].get<size_t>();
            if (b >= buffers->size()) continue;
            ++views[b];
            const auto ext = view.find("extensions");
            compressed[b] += ext != view.end() && ext->is_object() && ext->contains(meshopt_name);
        }
    for (size_t i = 0; i < buffers->size(); ++i) {
        nlohmann::json& b = (*buffers)[i];
        if (!b.is_object()) continue;
        const bool placeholder = !b.contains("uri") && !(binary && i == 0) && views[i] > 0 && compressed[i] == views[i];
        if (!is_marked_fallback(b) && !placeholder) continue;
        const auto length = b.find("byteLength");
        fallback[int(i)] = length != b.end() && length->is_number_unsigned() ? length->get<uint64_t>() : 0;
        b = {{"byteLength", 1}, {"uri", "data:application/octet-stream;base64,AA=="}};
    }
    return !fallback.empty();
}

// Returns the glTF (or GLB) bytes with viewless indices detached from `doc` (in place: only its buffers
// are read later) and what parse_document dropped or detach_fallback_buffers replaced left out, or an empty
// vector when nothing changed.
std::vector<uint8_t> prepare_for_tinygltf(const uint8_t* data, size_t size, bool binary, nlohmann::json& doc,
                                          bool changed, DetachedIndices& detached) {
    if (!detach_viewless_indices(doc, detached) && !changed) return {};
    const size_t json_size = binary ? read_u32(data + 12) : size;
    std::string text = doc.dump();
    if (!binary) return std::vector<uint8_t>(text.begin(), text.end());
    while (text.size() % 4) text.push_back(' ');  // chunks stay 4-byte aligned
    size_t tail = 20 + json_size;                 // the BIN chunk and anything after, unchanged
    std::vector<uint8_t> out(20);
    std::memcpy(out.data(), data, 12);
    out.insert(out.end(), text.begin(), text.end());
    out.insert(out.end(), data + tail, data + size);
    write_u32(out, 8, uint32_t(out.size()));
    write_u32(out, 12, uint32_t(text.size()));
    write_u32(out, 16, 0x4E4F534Au);
    return out;
}

// The bytes a load holds for what the file declares: the scene built so far, checked against the budget
// before each allocation a declared count decides.
struct MemoryUse {
    uint64_t held = 0;
    uint64_t budget = default_memory_budget;
};

// EXT_meshopt_compression's state for one load: the fallback buffers (detach_fallback_buffers) and the
// views decoded so far, each decoded once however many accessors read it.
struct MeshoptViews {
    FallbackBuffers fallback;
    std::map<int, std::vector<uint8_t>> decoded;
};

struct Context {
    const tinygltf::Model& model;
    std::string file;
    std::string where;  // "mesh 3 primitive 1: accessor 7" and so on
    const DetachedIndices* detached = nullptr;
    MemoryUse* memory = nullptr;
    MeshoptViews* meshopt = nullptr;

    [[noreturn]] void fail(const std::string& what) const {
        throw LoadError(file + ": " + (where.empty() ? "" : where + ": ") + what);
    }

    // Fails unless `bytes` more (for `what`) fit the memory budget beside what the load already holds.
    void need(uint64_t bytes, const std::string& what) const {
        if (bytes <= memory->budget && memory->held <= memory->budget - bytes) return;
        fail(what + " needs " + byte_size_text(bytes) + " more, over the memory budget of " +
             byte_size_text(memory->budget) + " (--memory-budget)");
    }
};

// All bytes of the model's buffers: what an accessor without a bufferView may not exceed.
uint64_t buffer_bytes(const tinygltf::Model& model) {
    uint64_t total = 0;
    for (const tinygltf::Buffer& b : model.buffers) total += b.data.size();
    return total;
}

// tinygltf's message, one line and short: some quote a whole data URI.
std::string first_line(const std::string& s) {
    size_t begin = s.find_first_not_of(" \n\r\t");
    if (begin == std::string::npos) return "unknown error";
    size_t end = s.find_first_of("\r\n", begin);
    std::string line = s.substr(begin, end == std::string::npos ? std::string::npos : end - begin);
    return line.size() > 200 ? line.substr(0, 197) + "..." : line;
}

size_t component_size(int component_type) {
    switch (component_type) {
        case TINYGLTF_COMPONENT_TYPE_BYTE:
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
        case TINYGLTF_COMPONENT_TYPE_SHORT:
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
        case TINYGLTF_COMPONENT_TYPE_INT:
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
        case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
        default: return 0;
    }
}

// One component as double, with glTF's normalisation rules for integer types.
double read_component(const uint8_t* p, int component_type, bool normalized) {
    switch (component_type) {
        case TINYGLTF_COMPONENT_TYPE_FLOAT: {
            float f;
            std::memcpy(&f, p, 4);
            return f;
        }
        case TINYGLTF_COMPONENT_TYPE_BYTE: {
            int8_t v;
            std::memcpy(&v, p, 1);
            return normalized ? std::max(v / 127.0, -1.0) : v;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? p[0] / 255.0 : p[0];
        case TINYGLTF_COMPONENT_TYPE_SHORT: {
            int16_t v;
            std::memcpy(&v, p, 2);
            return normalized ? std::max(v / 32767.0, -1.0) : v;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
            uint16_t v;
            std::memcpy(&v, p, 2);
            return normalized ? v / 65535.0 : v;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
            uint32_t v;
            std::memcpy(&v, p, 4);
            return v;
        }
        case TINYGLTF_COMPONENT_TYPE_INT: {
            int32_t v;
            std::memcpy(&v, p, 4);
            return v;
        }
        default: return 0;
    }
}

// The bytes of `count` elements of `element_size` bytes starting `offset` into a buffer view, with the
// view's stride (or tight packing). Checks the whole range against the view and the view against its buffer.
struct StridedRange {
    const uint8_t* base = nullptr;
    size_t stride = 0;
};

// A non-negative integer property of an extension object: -1 when absent, fails when not such an integer.
int64_t extension_integer(const Context& ctx, const tinygltf::Value& object, const char* key) {
    if (!object.Has(key)) return -1;
    const tinygltf::Value& v = object.Get(key);
    double d = v.IsInt() ? double(v.Get<int>()) : v.IsReal() ? v.Get<double>() : -1;
    if (!(d >= 0 && d <= 9007199254740992.0 && d == std::floor(d)))
        ctx.fail(std::string(key) + " is not a non-negative integer");
    return int64_t(d);
}

// Decoded bytes a compressed stream of `length` bytes may hold, by mode. The attribute codec stores, for
// each byte of an element, 2 header bits a group of 16 elements of a block: at least a byte for 64 bytes
// decoded. The triangle codec spends at least one byte on each triangle, the index codec one on each
// index. A larger declaration is refused before anything is allocated for it.
constexpr uint64_t meshopt_attribute_bytes_per_byte = 64;

// The bytes of an EXT_meshopt_compression bufferView, decoded (and filtered) on first use. Every rule of
// the extension on count, byteStride, mode and filter is checked first, and the declared size against the
// compressed stream's and the memory budget.
const std::vector<uint8_t>& meshopt_view(const Context& outer, int view_index, const tinygltf::Value& ext) {
    if (auto it = outer.meshopt->decoded.find(view_index); it != outer.meshopt->decoded.end()) return it->second;
    Context ctx = outer;
    ctx.where = (outer.where.empty() ? "" : outer.where + ": ") + "bufferView " + std::to_string(view_index) + ": " +
        meshopt_name;
    const tinygltf::BufferView& view = ctx.model.bufferViews[view_index];
    if (!ext.IsObject()) ctx.fail("not an object");
    const int64_t buffer_index = extension_integer(ctx, ext, "buffer");
    const int64_t offset = std::max<int64_t>(0, extension_integer(ctx, ext, "byteOffset"));
    const int64_t length = extension_integer(ctx, ext, "byteLength");
    const int64_t stride = extension_integer(ctx, ext, "byteStride");
    const int64_t count = extension_integer(ctx, ext, "count");
    if (buffer_index < 0 || length < 0 || stride < 0 || count < 0)
        ctx.fail("needs buffer, byteLength, byteStride and count");
    const std::string mode = ext.Has("mode") && ext.Get("mode").IsString() ? ext.Get("mode").Get<std::string>() : "";
    const std::string filter =
        ext.Has("filter") && ext.Get("filter").IsString() ? ext.Get("filter").Get<std::string>() : "NONE";
    if (mode != "ATTRIBUTES" && mode != "TRIANGLES" && mode != "INDICES")
        ctx.fail("mode '" + mode + "' is none of ATTRIBUTES, TRIANGLES, INDICES");
    if (filter != "NONE" && filter != "OCTAHEDRAL" && filter != "QUATERNION" && filter != "EXPONENTIAL")
        ctx.fail("filter '" + filter + "' is none of NONE, OCTAHEDRAL, QUATERNION, EXPONENTIAL");
    const std::string layout = "count " + std::to_string(count) + ", byteStride " + std::to_string(stride);
    if (mode == "ATTRIBUTES" && (stride == 0 || stride % 4 != 0 || stride > 256))
        ctx.fail("ATTRIBUTES with byteStride " + std::to_string(stride) + " (a multiple of 4, at most 256)");
    if (mode != "ATTRIBUTES" && stride != 2 && stride != 4)
        ctx.fail(mode + " with byteStride " + std::to_string(stride) + " (2 or 4)");
    if (mode == "TRIANGLES" && count % 3 != 0)
        ctx.fail("TRIANGLES with count " + std::to_string(count) + ", not a multiple of 3");
    if (mode != "ATTRIBUTES" && filter != "NONE") ctx.fail(mode + " with filter " + filter + " (only NONE)");
    if ((filter == "OCTAHEDRAL" && stride != 4 && stride != 8) || (filter == "QUATERNION" && stride != 8))
        ctx.fail("filter " + filter + " with byteStride " + std::to_string(stride));
    if (view.byteStride != 0 && int64_t(view.byteStride) != stride)
        ctx.fail("byteStride " + std::to_string(stride) + " differs from the bufferView's " +
                 std::to_string(view.byteStride));
    const uint64_t decoded_bytes = uint64_t(count) * uint64_t(stride);  // below 2^53 x 256: no overflow
    if (decoded_bytes != view.byteLength)
        ctx.fail(layout + " make " + std::to_string(decoded_bytes) + " bytes, but the bufferView's byteLength is " +
                 std::to_string(view.byteLength));
    if (size_t(buffer_index) >= ctx.model.buffers.size())
        ctx.fail("buffer " + std::to_string(buffer_index) + " does not exist");
    if (ctx.meshopt->fallback.count(int(buffer_index)))
        ctx.fail("buffer " + std::to_string(buffer_index) + " is a fallback buffer, not compressed data");
    const std::vector<unsigned char>& buffer = ctx.model.buffers[size_t(buffer_index)].data;
    if (uint64_t(offset) > buffer.size() || uint64_t(length) > buffer.size() - uint64_t(offset))
        ctx.fail("range " + std::to_string(offset) + "+" + std::to_string(length) + " past the end of buffer " +
                 std::to_string(buffer_index) + " (" + std::to_string(buffer.size()) + " bytes)");
    const uint8_t* stream = buffer.data() + offset;
    const uint64_t most = mode == "ATTRIBUTES" ? meshopt_attribute_bytes_per_byte * uint64_t(length)
        : mode == "TRIANGLES"                  ? 3 * uint64_t(length) * uint64_t(stride)
                                               : uint64_t(length) * uint64_t(stride);
    if (decoded_bytes > most)
        ctx.fail(layout + " declare " + std::to_string(decoded_bytes) + " bytes from a stream of " +
                 std::to_string(length) + " (at most " + std::to_string(most) + ")");
    if (mode == "ATTRIBUTES" && length > 0 && stream[0] != 0xa0)
        ctx.fail("attribute stream header 0x" +
                 [](uint8_t b) {
                     const char* hex = "0123456789abcdef";
                     return std::string{hex[b >> 4], hex[b & 15]};
                 }(stream[0]) +
                 " (version 0's is 0xa0; KHR_meshopt_compression's later versions are not read)");
    ctx.need(decoded_bytes, layout);
    std::vector<uint8_t> out(decoded_bytes);
    const int rc = mode == "ATTRIBUTES"
        ? meshopt_decodeVertexBuffer(out.data(), size_t(count), size_t(stride), stream, size_t(length))
        : mode == "TRIANGLES"
        ? meshopt_decodeIndexBuffer(out.data(), size_t(count), size_t(stride), stream, size_t(length))
        : meshopt_decodeIndexSequence(out.data(), size_t(count), size_t(stride), stream, size_t(length));
    if (rc != 0)
        ctx.fail("bad compressed data: " + mode + " stream of " + std::to_string(length) +
                 " bytes does not decode to " + layout + " (meshoptimizer error " + std::to_string(rc) + ")");
    if (filter == "OCTAHEDRAL") meshopt_decodeFilterOct(out.data(), size_t(count), size_t(stride));
    if (filter == "QUATERNION") meshopt_decodeFilterQuat(out.data(), size_t(count), size_t(stride));
    if (filter == "EXPONENTIAL") meshopt_decodeFilterExp(out.data(), size_t(count), size_t(stride));
    ctx.memory->held += decoded_bytes;
    return ctx.meshopt->decoded.emplace(view_index, std::move(out)).first->second;
}

StridedRange view_range(const Context& ctx, int view_index, size_t offset, size_t count, size_t element_size,
                        bool allow_stride) {
    const auto& views = ctx.model.bufferViews;
    if (view_index < 0 || size_t(view_index) >= views.size())
        ctx.fail("bufferView " + std::to_string(view_index) + " does not exist");
    const tinygltf::BufferView& view = views[view_index];
    const uint8_t* bytes = nullptr;
    if (auto ext = view.extensions.find(meshopt_name); ext != view.extensions.end()) {
        bytes = meshopt_view(ctx, view_index, ext->second).data();
    } else {
        if (view.buffer < 0 || size_t(view.buffer) >= ctx.model.buffers.size())
            ctx.fail("bufferView " + std::to_string(view_index) + ": buffer " + std::to_string(view.buffer) +
                     " does not exist");
        if (ctx.meshopt->fallback.count(view.buffer))
            ctx.fail("bufferView " + std::to_string(view_index) + ": reads buffer " + std::to_string(view.buffer) +
                     ", an " + meshopt_name + " fallback buffer, without being compressed itself");
        const tinygltf::Buffer& buffer = ctx.model.buffers[view.buffer];
        if (view.byteOffset > buffer.data.size() || view.byteLength > buffer.data.size() - view.byteOffset)
            ctx.fail("bufferView " + std::to_string(view_index) + ": range " + std::to_string(view.byteOffset) + "+" +
                     std::to_string(view.byteLength) + " past the end of buffer " + std::to_string(view.buffer) + " (" +
                     std::to_string(buffer.data.size()) + " bytes)");
        bytes = buffer.data.data() + view.byteOffset;
    }
    size_t stride = allow_stride && view.byteStride != 0 ? view.byteStride : element_size;
    if (stride < element_size)
        ctx.fail("bufferView " + std::to_string(view_index) + ": byteStride " + std::to_string(stride) +
                 " smaller than an element (" + std::to_string(element_size) + " bytes)");
    // count <= 2^32 and stride <= 2^32 in practice; guard the product against overflow anyway.
    unsigned __int128 needed =
        count == 0 ? 0 : (unsigned __int128)offset + (unsigned __int128)stride * (count - 1) + element_size;
    if (needed > view.byteLength)
        ctx.fail("needs " + std::to_string((unsigned long long)needed) + " bytes of bufferView " +
                 std::to_string(view_index) + " which has " + std::to_string(view.byteLength));
    return {bytes + offset, stride};
}

// A sparse accessor's declared count, index type and offsets, checked before its views are read.
void check_sparse(const Context& ctx, const tinygltf::Accessor& acc, size_t element_size) {
    const auto& sp = acc.sparse;
    if (sp.count < 0 || size_t(sp.count) > acc.count)
        ctx.fail("sparse count " + std::to_string(sp.count) + " exceeds accessor count " + std::to_string(acc.count));
    int itype = sp.indices.componentType;
    if (itype != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && itype != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        itype != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
        ctx.fail("sparse indices componentType " + std::to_string(itype) + " is not unsigned");
    if (sp.indices.byteOffset < 0 || sp.values.byteOffset < 0) ctx.fail("negative sparse byteOffset");
    Context part = ctx;
    part.where = ctx.where + ": sparse indices";
    view_range(part, sp.indices.bufferView, size_t(sp.indices.byteOffset), size_t(sp.count), component_size(itype),
               false);
    part.where = ctx.where + ": sparse values";
    view_range(part, sp.values.bufferView, size_t(sp.values.byteOffset), size_t(sp.count), element_size, false);
}

// Bytes of zeros an accessor without a bufferView may declare beyond what the file's buffers hold.
constexpr uint64_t zero_filled_allowance = uint64_t(1) << 16;

// Reads any numeric accessor as doubles (count * components), applying sparse substitution.
std::vector<double> read_accessor(Context ctx, int accessor_index, int want_type) {
    const auto& accessors = ctx.model.accessors;
    if (accessor_index < 0 || size_t(accessor_index) >= accessors.size())
        ctx.fail("accessor " + std::to_string(accessor_index) + " does not exist");
    const tinygltf::Accessor& acc = accessors[accessor_index];
    ctx.where += (ctx.where.empty() ? "" : ": ") + std::string("accessor ") + std::to_string(accessor_index);
    if (acc.type != want_type) ctx.fail("unexpected accessor type " + std::to_string(acc.type));
    size_t csize = component_size(acc.componentType);
    if (csize == 0) ctx.fail("unknown componentType " + std::to_string(acc.componentType));
    size_t ncomp = size_t(tinygltf::GetNumComponentsInType(uint32_t(acc.type)));
    if (acc.count > std::numeric_limits<uint32_t>::max())
        ctx.fail("count " + std::to_string(acc.count) + " exceeds 2^32-1");

    // Every range is checked against the bytes that exist before anything is allocated. Without a
    // bufferView an accessor is zeros (plus sparse values): its count costs no bytes of the file, so it may
    // not declare more than the file's buffers could hold.
    const size_t element_size = csize * ncomp;
    StridedRange r;
    if (acc.bufferView >= 0) {
        r = view_range(ctx, acc.bufferView, acc.byteOffset, acc.count, element_size, true);
    } else if (uint64_t(acc.count) * element_size > buffer_bytes(ctx.model) + zero_filled_allowance) {
        ctx.fail("count " + std::to_string(acc.count) + " without a bufferView (zero-filled) needs " +
                 std::to_string(uint64_t(acc.count) * element_size) + " bytes, more than the file's buffers hold");
    }
    if (acc.sparse.isSparse) check_sparse(ctx, acc, element_size);
    ctx.need(uint64_t(acc.count) * ncomp * sizeof(double), "count " + std::to_string(acc.count));
    std::vector<double> out(acc.count * ncomp, 0.0);
    if (acc.bufferView >= 0) {
        for (size_t i = 0; i < acc.count; ++i)
            for (size_t c = 0; c < ncomp; ++c)
                out[i * ncomp + c] =
                    read_component(r.base + i * r.stride + c * csize, acc.componentType, acc.normalized);
    }
    if (acc.sparse.isSparse) {
        const auto& sp = acc.sparse;
        const int itype = sp.indices.componentType;
        StridedRange ir = view_range(ctx, sp.indices.bufferView, size_t(sp.indices.byteOffset), size_t(sp.count),
                                     component_size(itype), false);
        StridedRange vr =
            view_range(ctx, sp.values.bufferView, size_t(sp.values.byteOffset), size_t(sp.count), element_size, false);
        for (size_t s = 0; s < size_t(sp.count); ++s) {
            double target = read_component(ir.base + s * ir.stride, itype, false);
            if (target >= double(acc.count))
                ctx.fail("sparse index " + std::to_string(uint64_t(target)) + " out of range (" +
                         std::to_string(acc.count) + " elements)");
            size_t t = size_t(target);
            for (size_t c = 0; c < ncomp; ++c)
                out[t * ncomp + c] =
                    read_component(vr.base + s * vr.stride + c * csize, acc.componentType, acc.normalized);
        }
    }
    return out;
}

// Indices as uint32 (only unsigned component types are valid glTF index types).
std::vector<uint32_t> read_indices(const Context& ctx, int accessor_index) {
    const auto& accessors = ctx.model.accessors;
    if (accessor_index >= 0 && size_t(accessor_index) < accessors.size()) {
        int t = accessors[accessor_index].componentType;
        if (t != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && t != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
            t != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
            ctx.fail("indices accessor " + std::to_string(accessor_index) + ": componentType " + std::to_string(t) +
                     " is not an unsigned integer type");
    }
    std::vector<double> raw = read_accessor(ctx, accessor_index, TINYGLTF_TYPE_SCALAR);
    return std::vector<uint32_t>(raw.begin(), raw.end());
}

// Faces and points a Draco stream may declare per byte of itself. Draco compresses a mesh to a byte or
// two a triangle, a very regular one to less: this leaves room for any real stream and none for a few
// bytes that declare a billion faces.
constexpr uint64_t draco_elements_per_byte = 256;

// What Draco's decoder holds per declared face and point (corner table, attribute and point maps).
constexpr uint64_t draco_bytes_per_face = 96, draco_bytes_per_point = 64;

// Checks the counts a Draco stream declares against its size and the memory budget before the decoder
// allocates for them.
void check_draco_counts(const Context& ctx, const uint8_t* data, size_t length) {
    DracoCounts declared;
    const std::string problem = read_draco_counts(data, length, declared);
    if (!problem.empty()) ctx.fail("Draco: " + problem);
    if (declared.faces > draco_elements_per_byte * length || declared.points > draco_elements_per_byte * length)
        ctx.fail("Draco: declares " + std::to_string(declared.faces) + " faces and " + std::to_string(declared.points) +
                 " points in a stream of " + std::to_string(length) + " bytes (at most " +
                 std::to_string(draco_elements_per_byte) + " a byte)");
    ctx.need(declared.faces * draco_bytes_per_face + declared.points * draco_bytes_per_point,
             "Draco's " + std::to_string(declared.faces) + " faces");
}

// Decodes a KHR_draco_mesh_compression primitive into positions and triangle indices.
void decode_draco(const Context& ctx, const tinygltf::Value& ext, std::vector<double>& positions,
                  std::vector<uint32_t>& indices) {
    const tinygltf::Value& view = ext.Get("bufferView");
    const tinygltf::Value& attrs = ext.Get("attributes");
    if (!view.IsInt() || !attrs.IsObject()) ctx.fail("KHR_draco_mesh_compression needs bufferView and attributes");
    const tinygltf::Value& pos_id = attrs.Get("POSITION");
    if (!pos_id.IsInt()) ctx.fail("KHR_draco_mesh_compression has no POSITION attribute");

    int view_index = view.Get<int>();
    size_t length = view_index >= 0 && size_t(view_index) < ctx.model.bufferViews.size()
        ? ctx.model.bufferViews[view_index].byteLength
        : 0;
    StridedRange r = view_range(ctx, view_index, 0, 1, length, false);
    check_draco_counts(ctx, r.base, length);

    draco::DecoderBuffer buffer;
    buffer.Init(reinterpret_cast<const char*>(r.base), length);
    draco::Decoder decoder;
    auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
    if (!decoded.ok()) ctx.fail("Draco: " + decoded.status().error_msg_string());
    std::unique_ptr<draco::Mesh> mesh = std::move(decoded).value();
    if (!mesh) ctx.fail("Draco: no mesh decoded");

    const draco::PointAttribute* att = mesh->GetAttributeByUniqueId(uint32_t(pos_id.Get<int>()));
    if (!att) ctx.fail("Draco: POSITION attribute id " + std::to_string(pos_id.Get<int>()) + " not in the stream");
    if (att->num_components() != 3)
        ctx.fail("Draco: POSITION has " + std::to_string(att->num_components()) + " components");

    uint32_t n = mesh->num_points();
    positions.resize(size_t(n) * 3);
    for (uint32_t i = 0; i < n; ++i) {
        float v[3];
        if (!att->ConvertValue<float, 3>(att->mapped_index(draco::PointIndex(i)), v))
            ctx.fail("Draco: cannot read position " + std::to_string(i));
        for (int c = 0; c < 3; ++c) positions[size_t(i) * 3 + c] = v[c];
    }
    indices.resize(size_t(mesh->num_faces()) * 3);
    for (uint32_t f = 0; f < mesh->num_faces(); ++f) {
        const draco::Mesh::Face& face = mesh->face(draco::FaceIndex(f));
        for (int c = 0; c < 3; ++c) indices[size_t(f) * 3 + c] = face[c].value();
    }
}

// Expands strips and fans to lists; lists pass through. The list index count must be a multiple of 3.
std::vector<uint32_t> triangulate(const Context& ctx, int mode, const std::vector<uint32_t>& idx) {
    std::vector<uint32_t> out;
    size_t n = idx.size();
    if (mode == TINYGLTF_MODE_TRIANGLES) {
        if (n % 3 != 0) ctx.fail("TRIANGLES with " + std::to_string(n) + " indices, not a multiple of 3");
        return idx;
    }
    if (n < 3) return out;
    ctx.need(uint64_t(n - 2) * 3 * sizeof(uint32_t), "a strip or fan of " + std::to_string(n) + " indices");
    out.reserve((n - 2) * 3);
    for (size_t i = 0; i + 2 < n; ++i) {
        if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
            // Odd triangles swap their first two vertices to keep a consistent winding.
            bool odd = i & 1;
            out.insert(out.end(), {idx[i + (odd ? 1 : 0)], idx[i + (odd ? 0 : 1)], idx[i + 2]});
        } else {  // fan
            out.insert(out.end(), {idx[0], idx[i + 1], idx[i + 2]});
        }
    }
    return out;
}

void load_primitive(Context ctx, size_t mesh_index, size_t prim_index, const tinygltf::Primitive& prim, Mesh& mesh,
                    LoadReport& report) {
    int indices_accessor = prim.indices;
    if (auto it = ctx.detached->find({mesh_index, prim_index}); it != ctx.detached->end())
        indices_accessor = it->second;
    int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
    if (mode == TINYGLTF_MODE_POINTS || mode == TINYGLTF_MODE_LINE || mode == TINYGLTF_MODE_LINE_LOOP ||
        mode == TINYGLTF_MODE_LINE_STRIP) {
        ++report.skipped_primitives;
        return;
    }
    if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN)
        ctx.fail("unknown primitive mode " + std::to_string(mode));

    std::vector<double> positions;
    std::vector<uint32_t> indices;
    auto draco = prim.extensions.find("KHR_draco_mesh_compression");
    if (draco != prim.extensions.end()) {
        decode_draco(ctx, draco->second, positions, indices);
        ++report.draco_primitives;
        // The accessors only describe the decoded data; their counts must agree with it.
        auto pos = prim.attributes.find("POSITION");
        if (pos != prim.attributes.end() && pos->second >= 0 && size_t(pos->second) < ctx.model.accessors.size() &&
            ctx.model.accessors[pos->second].count != positions.size() / 3)
            ctx.fail("Draco decoded " + std::to_string(positions.size() / 3) + " vertices but POSITION accessor " +
                     std::to_string(pos->second) + " says " + std::to_string(ctx.model.accessors[pos->second].count));
        if (indices_accessor >= 0 && size_t(indices_accessor) < ctx.model.accessors.size() &&
            ctx.model.accessors[indices_accessor].count != indices.size())
            ctx.fail("Draco decoded " + std::to_string(indices.size() / 3) + " triangles but indices accessor " +
                     std::to_string(indices_accessor) + " has " +
                     std::to_string(ctx.model.accessors[indices_accessor].count) + " indices");
        if (mode != TINYGLTF_MODE_TRIANGLES) ctx.fail("Draco primitive with mode " + std::to_string(mode));
    } else {
        auto pos = prim.attributes.find("POSITION");
        if (pos == prim.attributes.end()) ctx.fail("no POSITION attribute");
        positions = read_accessor(ctx, pos->second, TINYGLTF_TYPE_VEC3);
        if (indices_accessor >= 0) {
            indices = read_indices(ctx, indices_accessor);
        } else {
            indices.resize(positions.size() / 3);
            for (size_t i = 0; i < indices.size(); ++i) indices[i] = uint32_t(i);
        }
        indices = triangulate(ctx, mode, indices);
    }

    size_t vertex_count = positions.size() / 3;
    for (size_t i = 0; i < indices.size(); ++i)
        if (indices[i] >= vertex_count)
            ctx.fail("index " + std::to_string(indices[i]) + " out of range (" + std::to_string(vertex_count) +
                     " vertices)");
    for (size_t i = 0; i < positions.size(); ++i)
        if (!std::isfinite(positions[i]) || std::fabs(positions[i]) > std::numeric_limits<float>::max())
            ctx.fail("vertex " + std::to_string(i / 3) + ": position is not a finite float (" +
                     std::to_string(positions[i]) + ")");

    size_t base = mesh.vertex_count();
    if (base + vertex_count > std::numeric_limits<uint32_t>::max()) ctx.fail("more than 2^32-1 vertices in one mesh");
    const uint64_t kept = uint64_t(positions.size()) * sizeof(float) + uint64_t(indices.size()) * sizeof(uint32_t);
    ctx.need(kept, std::to_string(vertex_count) + " vertices and " + std::to_string(indices.size() / 3) + " triangles");
    ctx.memory->held += kept;
    Primitive p;
    p.first_triangle = uint32_t(mesh.triangle_count());
    p.triangle_count = uint32_t(indices.size() / 3);
    p.double_sided = prim.material >= 0 && size_t(prim.material) < ctx.model.materials.size() &&
        ctx.model.materials[prim.material].doubleSided;
    mesh.positions.insert(mesh.positions.end(), positions.begin(), positions.end());
    for (uint32_t i : indices) mesh.indices.push_back(uint32_t(base + i));
    mesh.primitives.push_back(p);
    ++report.primitives;
}

Transform node_local(const Context& ctx, const tinygltf::Node& node) {
    Transform m = identity_transform();
    if (node.matrix.size() == 16) {
        for (int i = 0; i < 16; ++i) m[i] = node.matrix[i];
    } else {
        if (!node.matrix.empty()) ctx.fail("matrix has " + std::to_string(node.matrix.size()) + " values, not 16");
        double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
        if (!node.translation.empty()) {
            if (node.translation.size() != 3) ctx.fail("translation needs 3 values");
            for (int i = 0; i < 3; ++i) t[i] = node.translation[i];
        }
        if (!node.rotation.empty()) {
            if (node.rotation.size() != 4) ctx.fail("rotation needs 4 values");
            for (int i = 0; i < 4; ++i) q[i] = node.rotation[i];
            double len = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
            if (!(len > 0) || !std::isfinite(len)) ctx.fail("rotation quaternion has zero or non-finite length");
            for (double& c : q) c /= len;  // exporters write unit quaternions to a few digits only
        }
        if (!node.scale.empty()) {
            if (node.scale.size() != 3) ctx.fail("scale needs 3 values");
            for (int i = 0; i < 3; ++i) s[i] = node.scale[i];
        }
        m = trs_transform(t, q, s);
    }
    for (double v : m)
        if (!std::isfinite(v)) ctx.fail("transform has a non-finite value");
    if (m[3] != 0 || m[7] != 0 || m[11] != 0 || m[15] != 1) ctx.fail("transform is not affine (projective row)");
    return m;
}

class SceneBuilder {
public:
    SceneBuilder(const tinygltf::Model& model, const std::string& file, const DetachedIndices& detached,
                 MemoryUse& memory, MeshoptViews& meshopt)
        : ctx_{model, file, "", &detached, &memory, &meshopt} {}

    Scene build() {
        const auto& model = ctx_.model;
        mesh_slot_.assign(model.meshes.size(), -1);
        on_path_.assign(model.nodes.size(), false);
        std::vector<int> roots;
        int scene_index = model.defaultScene;
        if (scene_index >= int(model.scenes.size()))
            ctx_.fail("scene " + std::to_string(scene_index) + " does not exist");
        if (scene_index >= 0) {
            roots = model.scenes[scene_index].nodes;
        } else {
            // No default scene: every node that is nobody's child is a root.
            std::vector<bool> is_child(model.nodes.size(), false);
            for (const auto& n : model.nodes)
                for (int c : n.children)
                    if (c >= 0 && size_t(c) < model.nodes.size()) is_child[c] = true;
            for (size_t i = 0; i < model.nodes.size(); ++i)
                if (!is_child[i]) roots.push_back(int(i));
        }
        for (int r : roots) walk(r);
        for (size_t m = 0; m < model.meshes.size(); ++m)
            if (mesh_slot_[m] < 0) ++scene_.report.unreferenced_meshes;
        scene_.report.meshopt_views = uint32_t(ctx_.meshopt->decoded.size());
        return std::move(scene_);
    }

private:
    static constexpr size_t max_instances = 4'000'000;

    // glTF wants node trees, where every node is visited once; a node shared by several parents (a DAG,
    // loaded as one instance per path) multiplies the paths below it, exponentially in its depth. Visits
    // are capped by the file's node count, so a few hundred bytes cannot make millions of instances.
    size_t max_visits() const { return 65'536 + 64 * ctx_.model.nodes.size(); }

    // A node on the path from the root being walked, with its world transform and the next child to enter.
    struct Step {
        int node;
        size_t next_child;
        Transform world;
    };

    // Depth first from `root`, in the order a recursion would take, on a stack of our own: the file
    // decides the depth, and a chain of 20,000 nodes is as valid as a chain of 2.
    void walk(int root) {
        std::vector<Step> path;
        enter(root, identity_transform(), path);
        while (!path.empty()) {
            Step& top = path.back();
            const std::vector<int>& children = ctx_.model.nodes[top.node].children;
            if (top.next_child == children.size()) {
                on_path_[top.node] = false;
                path.pop_back();
                continue;
            }
            const int child = children[top.next_child++];
            const Transform parent = top.world;  // `top` moves when `path` grows
            enter(child, parent, path);
        }
    }

    // Checks the node, makes its instance when it holds a mesh, and puts it on the path.
    void enter(int node_index, const Transform& parent, std::vector<Step>& path) {
        const auto& nodes = ctx_.model.nodes;
        Context node_ctx = ctx_;
        node_ctx.where = "node " + std::to_string(node_index);
        if (node_index < 0 || size_t(node_index) >= nodes.size())
            ctx_.fail("node " + std::to_string(node_index) + " does not exist");
        if (on_path_[node_index]) node_ctx.fail("node cycle (the node is its own ancestor)");
        if (++visits_ > max_visits())
            node_ctx.fail("more than " + std::to_string(max_visits()) +
                          " node visits: nodes shared by several parents multiply the paths to them");
        const tinygltf::Node& node = nodes[node_index];
        Transform world = multiply(parent, node_local(node_ctx, node));
        if (node.mesh >= 0) {
            if (size_t(node.mesh) >= ctx_.model.meshes.size())
                node_ctx.fail("mesh " + std::to_string(node.mesh) + " does not exist");
            uint32_t id = mesh_id(node.mesh);
            if (auto gpu = node.extensions.find(instancing_name); gpu != node.extensions.end()) {
                add_gpu_instances(node_ctx, node, gpu->second, world, id);
            } else {
                add_instance(node_ctx, node, with_origin(world, origins_[id]), id);
            }
        }
        on_path_[node_index] = true;
        path.push_back({node_index, 0, world});
    }

    void add_instance(const Context& node_ctx, const tinygltf::Node& node, const Transform& world, uint32_t mesh) {
        if (scene_.instances.size() >= max_instances) node_ctx.fail("more than 4 million instances");
        node_ctx.need(sizeof(Instance) + node.name.size(), "an instance");
        ctx_.memory->held += sizeof(Instance) + node.name.size();
        scene_.instances.push_back({mesh, world, node.name});
    }

    // EXT_mesh_gpu_instancing: the node's mesh drawn once per element of its TRANSLATION, ROTATION and SCALE
    // accessors, each element's T x R x S after the node's world transform, in double. The node's children
    // are not instanced. A mirroring scale is kept in the transform, as a mirrored node's is.
    void add_gpu_instances(Context node_ctx, const tinygltf::Node& node, const tinygltf::Value& ext,
                           const Transform& world, uint32_t mesh) {
        node_ctx.where += std::string(": ") + instancing_name;
        if (!ext.IsObject() || !ext.Get("attributes").IsObject()) node_ctx.fail("no attributes object");
        const tinygltf::Value& attributes = ext.Get("attributes");
        const char* names[3] = {"TRANSLATION", "ROTATION", "SCALE"};
        const int types[3] = {TINYGLTF_TYPE_VEC3, TINYGLTF_TYPE_VEC4, TINYGLTF_TYPE_VEC3};
        std::vector<double> values[3];
        int64_t count = -1;
        for (int a = 0; a < 3; ++a) {
            if (!attributes.Has(names[a])) continue;
            const tinygltf::Value& index = attributes.Get(names[a]);
            Context actx = node_ctx;
            actx.where += std::string(" ") + names[a];
            if (!index.IsInt()) actx.fail("is not an accessor index");
            values[a] = read_accessor(actx, index.Get<int>(), types[a]);
            const int64_t n = int64_t(values[a].size() / (a == 1 ? 4 : 3));
            if (count >= 0 && n != count)
                actx.fail("has " + std::to_string(n) + " elements, the other attributes " + std::to_string(count));
            count = n;
        }
        if (count < 0) node_ctx.fail("names none of TRANSLATION, ROTATION, SCALE: how many instances is unknown");
        ++scene_.report.instanced_nodes;
        scene_.report.gpu_instances += uint64_t(count);
        for (int64_t i = 0; i < count; ++i) {
            double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
            for (int c = 0; c < 3; ++c) {
                if (!values[0].empty()) t[c] = values[0][size_t(i) * 3 + c];
                if (!values[2].empty()) s[c] = values[2][size_t(i) * 3 + c];
            }
            if (!values[1].empty()) {
                for (int c = 0; c < 4; ++c) q[c] = values[1][size_t(i) * 4 + c];
                const double len = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
                if (!(len > 0) || !std::isfinite(len))
                    node_ctx.fail("instance " + std::to_string(i) + ": rotation has zero or non-finite length");
                for (double& c : q) c /= len;  // quantized rotations are unit to their precision only
            }
            const Transform m = multiply(world, trs_transform(t, q, s));
            for (double v : m)
                if (!std::isfinite(v))
                    node_ctx.fail("instance " + std::to_string(i) + ": transform has a non-finite value");
            add_instance(node_ctx, node, with_origin(m, origins_[mesh]), mesh);
        }
    }

    uint32_t mesh_id(int gltf_mesh) {
        if (mesh_slot_[gltf_mesh] >= 0) return uint32_t(mesh_slot_[gltf_mesh]);
        const tinygltf::Mesh& src = ctx_.model.meshes[gltf_mesh];
        Mesh mesh;
        mesh.name = src.name;
        for (size_t p = 0; p < src.primitives.size(); ++p) {
            Context pctx = ctx_;
            pctx.where = "mesh " + std::to_string(gltf_mesh) + " primitive " + std::to_string(p);
            load_primitive(pctx, size_t(gltf_mesh), p, src.primitives[p], mesh, scene_.report);
        }
        mesh_slot_[gltf_mesh] = int(scene_.meshes.size());
        origins_.push_back(shift_exactly(mesh.positions));  // once per mesh, composed into each of its instances
        scene_.meshes.push_back(std::move(mesh));
        return uint32_t(mesh_slot_[gltf_mesh]);
    }

    Context ctx_;
    Scene scene_;
    std::vector<int> mesh_slot_;   // glTF mesh index -> Scene mesh index, -1 until first used
    std::vector<Origin> origins_;  // per Scene mesh: its frame's origin in the glTF mesh's coordinates
    std::vector<bool> on_path_;    // nodes on the current root-to-node path, for cycle detection
    size_t visits_ = 0;
};

}  // namespace

// Every extension the document names, in extensionsUsed, extensionsRequired or on an object, with what the
// load does with it. One it does not know that could change the geometry (on a mesh, node, accessor,
// bufferView, buffer, scene or the document, or required and on no object at all) fails the load when
// required and is a warning when optional; one found only on materials, textures, animations and the like
// is skipped.
static std::vector<ExtensionUse> classify_extensions(const nlohmann::json& doc, const ExtensionSightings& seen,
                                                     const std::string& name, std::vector<std::string>& warnings) {
    std::vector<std::string> order;
    std::set<std::string> required, listed;
    auto names = [&doc](const char* key) {
        std::vector<std::string> out;
        const auto it = doc.find(key);
        if (it == doc.end() || !it->is_array()) return out;
        for (const nlohmann::json& n : *it)
            if (n.is_string()) out.push_back(n.get<std::string>());
        return out;
    };
    const std::vector<std::string> used = names("extensionsUsed"), declared_required = names("extensionsRequired");
    required.insert(declared_required.begin(), declared_required.end());
    for (const std::vector<std::string>* list : {&used, &declared_required, &seen.order})
        for (const std::string& n : *list)
            if (listed.insert(n).second) order.push_back(n);
    std::vector<ExtensionUse> out;
    for (const std::string& n : order) {
        ExtensionUse use;
        use.name = n;
        use.required = required.count(n) > 0;
        bool geometry = false;
        if (auto it = seen.owners.find(n); it != seen.owners.end()) {
            for (const std::string& owner : it->second) {
                use.where += (use.where.empty() ? "" : ", ") + owner;
                geometry = geometry || !owner_without_geometry(owner);
            }
        } else {
            geometry = use.required;  // such as KHR_mesh_quantization: it changes how accessors read
        }
        if (is_applied_extension(n)) {
            use.status = ExtensionUse::Status::applied;
        } else if (is_no_geometry_extension(n) || !geometry) {
            use.status = ExtensionUse::Status::no_geometry;
        } else {
            const std::string on = use.where.empty() ? "" : " (on " + use.where + ")";
            if (use.required) throw LoadError(name + ": unsupported required extension " + n + on);
            use.status = ExtensionUse::Status::unsupported;
            warnings.push_back(name + ": optional extension " + n + on +
                               " is not supported and could change the geometry: loaded without it");
        }
        out.push_back(std::move(use));
    }
    return out;
}

// The first external buffer of the document the load may not read, as "buffer 0: 'uri': why", or empty.
// Images are never read, so only buffers are checked.
std::string buffer_access_problem(const nlohmann::json& doc, const std::string& base_dir, const LoadOptions& options) {
    const auto buffers = doc.find("buffers");
    if (buffers == doc.end() || !buffers->is_array()) return {};
    const std::string root_name = options.root.empty() ? "the scene's folder" : "the input root";
    for (size_t i = 0; i < buffers->size(); ++i) {
        const nlohmann::json& b = (*buffers)[i];
        if (!b.is_object() || !b.contains("uri") || !b["uri"].is_string()) continue;
        const std::string uri = b["uri"];
        if (uri.rfind("data:", 0) == 0) continue;
        const std::string where = "buffer " + std::to_string(i) + ": '" + uri + "': ";
        if (base_dir.empty()) return where + "an external file, but the scene was not read from a folder";
        if (options.allow_outside_files) continue;
        std::string problem = outside_root_problem(uri, base_dir, options.root, root_name);
        if (!problem.empty()) return where + "refused: " + problem + " (--allow-outside-files reads it)";
    }
    return {};
}

// tinygltf's own file reading, confined to the load's root (again, should a file change after the check
// above) and with each file it reads (external buffers; images are compiled out) added to the source hash
// under its name relative to the scene's folder.
struct FileReader {
    SourceHasher* hasher;
    std::string base_dir;
    const LoadOptions& options;

    static bool read(std::vector<unsigned char>* out, std::string* err, const std::string& path, void* self) {
        const FileReader& r = *static_cast<const FileReader*>(self);
        if (r.base_dir.empty()) {
            *err += path + ": no external files for a scene not read from a folder\n";
            return false;
        }
        std::string problem = r.options.allow_outside_files
            ? ""
            : path_outside_root(path, r.options.root.empty() ? r.base_dir : r.options.root, "the root");
        if (!problem.empty()) {
            *err += path + ": refused: " + problem + "\n";
            return false;
        }
        if (!tinygltf::ReadWholeFile(out, err, path, nullptr)) return false;
        if (!r.hasher) return true;
        std::string prefix = r.base_dir.back() == '/' ? r.base_dir : r.base_dir + "/";
        std::string relative = path.compare(0, prefix.size(), prefix) == 0 ? path.substr(prefix.size()) : path;
        r.hasher->add(relative, out->data(), out->size());
        return true;
    }

    // tinygltf joins every URI to the folder, an absolute one too ("folder//abs/x.bin"): when outside files
    // are allowed, such a URI means the absolute path it names.
    static std::string expand(const std::string& joined, void* self) {
        const FileReader& r = *static_cast<const FileReader*>(self);
        const std::string prefix = r.base_dir.empty() || r.base_dir.back() == '/' ? r.base_dir : r.base_dir + "/";
        if (r.options.allow_outside_files && !prefix.empty() && joined.size() > prefix.size() &&
            joined.compare(0, prefix.size(), prefix) == 0 && joined[prefix.size()] == '/')
            return joined.substr(prefix.size());
        return joined;
    }
};

Scene load_gltf_memory(const uint8_t* data, size_t size, const std::string& name, const std::string& base_dir,
                       SourceHasher* source, const LoadOptions& options) {
    if (size == 0) throw LoadError(name + ": empty file");
    if (size > std::numeric_limits<unsigned int>::max()) throw LoadError(name + ": larger than 4 GiB");
    bool binary = size >= 4 && std::memcmp(data, "glTF", 4) == 0;
    if (binary) {
        std::string layout = glb_layout_error(data, size);
        if (!layout.empty()) throw LoadError(name + ": " + layout);
    }
    bool pruned;
    ExtensionSightings seen;
    nlohmann::json doc = parse_document(data, size, binary, name, pruned, seen);
    std::vector<std::string> warnings;
    std::vector<ExtensionUse> extensions = classify_extensions(doc, seen, name, warnings);
    MeshoptViews meshopt;
    const bool detached_fallback = detach_fallback_buffers(doc, binary, meshopt.fallback);
    std::string access = buffer_access_problem(doc, base_dir, options);
    if (!access.empty()) throw LoadError(name + ": " + access);
    DetachedIndices detached;
    std::vector<uint8_t> prepared =
        prepare_for_tinygltf(data, size, binary, doc, pruned || detached_fallback, detached);
    if (!prepared.empty()) {
        data = prepared.data();
        size = prepared.size();
    }

    tinygltf::TinyGLTF loader;
    // Images are never decoded; a no-op loader keeps tinygltf from failing on embedded ones.
    loader.SetImageLoader([](tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*,
                             int, void*) { return true; },
                          nullptr);
    FileReader reader{source, base_dir, options};
    loader.SetFsCallbacks(
        {tinygltf::FileExists, FileReader::expand, FileReader::read, tinygltf::WriteWholeFile, &reader});
    tinygltf::Model model;
    std::string err, warn;
    bool ok = binary ? loader.LoadBinaryFromMemory(&model, &err, &warn, data, unsigned(size), base_dir)
                     : loader.LoadASCIIFromString(&model, &err, &warn, reinterpret_cast<const char*>(data),
                                                  unsigned(size), base_dir);
    if (!ok) {
        std::string buffer = buffer_file_problem(doc, base_dir);
        throw LoadError(name + ": " + (buffer.empty() ? first_line(err.empty() ? warn : err) : buffer));
    }
    MemoryUse memory{0, options.memory_budget};
    Scene scene = SceneBuilder(model, name, detached, memory, meshopt).build();
    scene.report.extensions = std::move(extensions);
    scene.report.warnings = std::move(warnings);
    validate_scene(scene, name);
    return scene;
}

}  // namespace cb
