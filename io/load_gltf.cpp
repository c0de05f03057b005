// glTF 2.0 loading: tinygltf parses the JSON and buffers (images are never decoded), this file turns
// accessors into flat arrays, checking every range against its buffer before reading a byte of it.
#include <draco/compression/decode.h>
#include <tiny_gltf.h>

#include <nlohmann/json.hpp>

#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <sstream>

#include "draco_header.h"
#include "file_access.h"
#include "load.h"

namespace cb {
namespace {

// Extensions whose presence changes nothing about positions, indices or sidedness, so a file that
// requires them is still loaded exactly.
bool is_known_extension(const std::string& name) {
    static const char* known[] = {"KHR_draco_mesh_compression", "KHR_mesh_quantization",  "KHR_texture_transform",
                                  "KHR_texture_basisu",         "KHR_lights_punctual",    "KHR_materials_common",
                                  "EXT_texture_webp",           "KHR_materials_variants", "KHR_animation_pointer"};
    for (const char* k : known)
        if (name == k) return true;
    return name.rfind("KHR_materials_", 0) == 0;  // every material extension: no geometry
}

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
// Parts the loader never reads ("extras", and extensions other than Draco's: their names are a prefix, an
// underscore and a lower-case letter) are dropped as they are parsed, with whatever they nest, so that
// neither this document nor tinygltf's model holds them: a few megabytes of "[[],[],..." there made both
// hold hundreds. `pruned` tells whether anything was dropped.
bool never_read(const std::string& key) {
    if (key == "extras") return true;
    const size_t underscore = key.find('_');
    if (underscore == 0 || underscore == std::string::npos || underscore + 1 == key.size()) return false;
    for (size_t i = 0; i < underscore; ++i)
        if (!std::isupper(uint8_t(key[i])) && !std::isdigit(uint8_t(key[i]))) return false;
    return std::islower(uint8_t(key[underscore + 1])) && key != "KHR_draco_mesh_compression";
}

nlohmann::json parse_document(const uint8_t* data, size_t size, bool binary, const std::string& name, bool& pruned) {
    const uint8_t* begin = binary ? data + 20 : data;
    const size_t length = binary ? read_u32(data + 12) : size;
    nlohmann::json doc;
    pruned = false;
    auto keep = [&pruned](int, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
        if (event != nlohmann::json::parse_event_t::key || !parsed.is_string() || !never_read(parsed)) return true;
        pruned = true;
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

// Returns the glTF (or GLB) bytes with viewless indices detached from `doc` (in place: only its buffers
// are read later) and what parse_document dropped left out, or an empty vector when nothing changed.
std::vector<uint8_t> prepare_for_tinygltf(const uint8_t* data, size_t size, bool binary, nlohmann::json& doc,
                                          bool pruned, DetachedIndices& detached) {
    if (!detach_viewless_indices(doc, detached) && !pruned) return {};
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

struct Context {
    const tinygltf::Model& model;
    std::string file;
    std::string where;  // "mesh 3 primitive 1: accessor 7" and so on
    const DetachedIndices* detached = nullptr;
    MemoryUse* memory = nullptr;

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

StridedRange view_range(const Context& ctx, int view_index, size_t offset, size_t count, size_t element_size,
                        bool allow_stride) {
    const auto& views = ctx.model.bufferViews;
    if (view_index < 0 || size_t(view_index) >= views.size())
        ctx.fail("bufferView " + std::to_string(view_index) + " does not exist");
    const tinygltf::BufferView& view = views[view_index];
    if (view.buffer < 0 || size_t(view.buffer) >= ctx.model.buffers.size())
        ctx.fail("bufferView " + std::to_string(view_index) + ": buffer " + std::to_string(view.buffer) +
                 " does not exist");
    const tinygltf::Buffer& buffer = ctx.model.buffers[view.buffer];
    if (view.byteOffset > buffer.data.size() || view.byteLength > buffer.data.size() - view.byteOffset)
        ctx.fail("bufferView " + std::to_string(view_index) + ": range " + std::to_string(view.byteOffset) + "+" +
                 std::to_string(view.byteLength) + " past the end of buffer " + std::to_string(view.buffer) + " (" +
                 std::to_string(buffer.data.size()) + " bytes)");
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
    return {buffer.data.data() + view.byteOffset + offset, stride};
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
                 MemoryUse& memory)
        : ctx_{model, file, "", &detached, &memory} {}

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
            if (scene_.instances.size() >= max_instances) node_ctx.fail("more than 4 million instances");
            uint32_t id = mesh_id(node.mesh);
            node_ctx.need(sizeof(Instance) + node.name.size(), "an instance");
            ctx_.memory->held += sizeof(Instance) + node.name.size();
            scene_.instances.push_back({id, with_origin(world, origins_[id]), node.name});
        }
        on_path_[node_index] = true;
        path.push_back({node_index, 0, world});
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
    nlohmann::json doc = parse_document(data, size, binary, name, pruned);
    std::string access = buffer_access_problem(doc, base_dir, options);
    if (!access.empty()) throw LoadError(name + ": " + access);
    DetachedIndices detached;
    std::vector<uint8_t> prepared = prepare_for_tinygltf(data, size, binary, doc, pruned, detached);
    if (!prepared.empty()) data = prepared.data(), size = prepared.size();

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
    for (const std::string& ext : model.extensionsRequired)
        if (!is_known_extension(ext)) throw LoadError(name + ": unsupported required extension " + ext);
    MemoryUse memory{0, options.memory_budget};
    Scene scene = SceneBuilder(model, name, detached, memory).build();
    validate_scene(scene, name);
    return scene;
}

}  // namespace cb
