// PLY reader: ASCII, binary little- and big-endian; vertex x/y/z, face lists (triangulated by
// polygon_triangulate.h) and tristrips (-1 restarts). Every count is checked against the bytes that remain
// before anything is allocated, every index against the vertex count.
//
// Not OpenMesh's PLY reader, which the fuzzer breaks: it loops forever on a header without end_header,
// writes out of bounds on a property that precedes every element, and grows without bound on a malformed
// ASCII list.
#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>

#include "load.h"
#include "parallel.h"
#include "populate_pages.h"
#include "polygon_triangulate.h"
#include "text_scan.h"

namespace cb {
namespace {

enum class Encoding { ascii, little, big };

struct Property {
    std::string name;
    int type = 0;        // size in bytes, negative for signed integers, 0x40|size for floating point
    int count_type = 0;  // for lists: the type of the element count
    bool list = false;
};

struct Element {
    std::string name;
    uint64_t count = 0;
    std::vector<Property> properties;
};

constexpr int float_flag = 0x40;

int type_code(std::string_view t) {
    if (t == "char" || t == "int8") return -1;
    if (t == "uchar" || t == "uint8") return 1;
    if (t == "short" || t == "int16") return -2;
    if (t == "ushort" || t == "uint16") return 2;
    if (t == "int" || t == "int32") return -4;
    if (t == "uint" || t == "uint32") return 4;
    if (t == "float" || t == "float32") return float_flag | 4;
    if (t == "double" || t == "float64") return float_flag | 8;
    return 0;
}

size_t type_size(int code) { return size_t(std::abs(code) & 0xf); }

class Body {
public:
    Body(std::string_view bytes, Encoding enc, const std::string& name) : bytes_(bytes), enc_(enc), name_(name) {}

    // Reads one value of `type` as double; throws on end of data or (ASCII) a malformed number. The
    // element name and row only make the message.
    double read(int type, const std::string& element, uint64_t row) {
        if (enc_ == Encoding::ascii) {
            std::string_view tok = next_token();
            if (tok.empty()) fail(element, row, "unexpected end of data");
            double v;
            if (!parse_double(tok, v)) fail(element, row, quoted(tok) + " is not a number");
            return v;
        }
        size_t n = type_size(type);
        if (pos_ + n > bytes_.size()) fail(element, row, "unexpected end of data");
        uint8_t b[8];
        std::memcpy(b, bytes_.data() + pos_, n);
        pos_ += n;
        if (enc_ == Encoding::big) std::reverse(b, b + n);
        switch (type) {
            case -1: {
                int8_t v;
                std::memcpy(&v, b, 1);
                return v;
            }
            case 1: return b[0];
            case -2: {
                int16_t v;
                std::memcpy(&v, b, 2);
                return v;
            }
            case 2: {
                uint16_t v;
                std::memcpy(&v, b, 2);
                return v;
            }
            case -4: {
                int32_t v;
                std::memcpy(&v, b, 4);
                return v;
            }
            case 4: {
                uint32_t v;
                std::memcpy(&v, b, 4);
                return v;
            }
            case float_flag | 4: {
                float v;
                std::memcpy(&v, b, 4);
                return v;
            }
            default: {
                double v;
                std::memcpy(&v, b, 8);
                return v;
            }
        }
    }

    size_t remaining() const { return bytes_.size() - pos_; }

    [[noreturn]] void fail(const std::string& what) const { throw LoadError(name_ + ": " + what); }
    [[noreturn]] void fail(const std::string& element, uint64_t row, const std::string& what) const {
        fail(element + " " + std::to_string(row) + ": " + what);
    }

private:
    std::string_view next_token() {
        while (pos_ < bytes_.size() && std::isspace(static_cast<unsigned char>(bytes_[pos_]))) ++pos_;
        size_t start = pos_;
        while (pos_ < bytes_.size() && !std::isspace(static_cast<unsigned char>(bytes_[pos_]))) ++pos_;
        return bytes_.substr(start, pos_ - start);
    }

    std::string_view bytes_;
    size_t pos_ = 0;
    Encoding enc_;
    const std::string& name_;
};

// The fewest bytes a record of the element can take: binary, its scalars and its lists' counts (every list
// may be empty); ASCII, a digit and a separator a value.
uint64_t least_record_bytes(const Element& e, Encoding enc) {
    uint64_t bytes = 0;
    for (const Property& p : e.properties)
        bytes += enc == Encoding::ascii ? 2 : type_size(p.list ? p.count_type : p.type);
    return bytes == 0 ? 1 : bytes;
}

int find_property(const Element& e, const char* name) {
    for (size_t i = 0; i < e.properties.size(); ++i)
        if (e.properties[i].name == name) return int(i);
    return -1;
}

// Binary little-endian files of float vertices and triangle faces, the form scanners and exporters write for
// large meshes: every record has a fixed size, so they are read straight into the mesh without going
// through doubles. False, with `mesh` left to be discarded, whenever the file is not exactly that or a
// record is not as expected (a polygon, an index out of range, a coordinate that is not finite): the general
// reader then takes the file and words the error. The result is the general reader's, bit for bit.
bool read_float_triangles(std::string_view body, const std::vector<Element>& elements, const Element& vertex_el,
                          const int xyz_prop[3], Mesh& mesh, unsigned threads) {
    if constexpr (std::endian::native != std::endian::little) return false;
    const Element* face_el = nullptr;
    size_t at = 0, vertex_at = 0, vertex_stride = 0, face_at = 0, index_bytes = 0;
    size_t xyz_offset[3] = {0, 0, 0};
    for (const Element& e : elements) {
        bool scalar = std::none_of(e.properties.begin(), e.properties.end(), [](const Property& p) { return p.list; });
        size_t stride = 0;
        if (scalar) {
            for (size_t p = 0; p < e.properties.size(); ++p) {
                for (int k = 0; k < 3; ++k)
                    if (&e == &vertex_el && int(p) == xyz_prop[k]) xyz_offset[k] = stride;
                stride += type_size(e.properties[p].type);
            }
        } else if (e.name == "face" && !face_el && e.properties.size() == 1 &&
                   type_size(e.properties[0].count_type) == 1 && std::abs(e.properties[0].type) == 4 &&
                   (e.properties[0].name == "vertex_indices" || e.properties[0].name == "vertex_index")) {
            face_el = &e;
            face_at = at;
            index_bytes = 1 + 3 * 4;
            stride = index_bytes;
        } else {
            return false;
        }
        if (&e == &vertex_el) {
            for (int k = 0; k < 3; ++k)
                if (e.properties[size_t(xyz_prop[k])].type != (float_flag | 4)) return false;
            vertex_at = at;
            vertex_stride = stride;
        }
        if (stride && e.count > (body.size() - at) / stride) return false;  // truncated: the general reader says where
        at += size_t(e.count) * stride;
    }
    if (!face_el) return false;

    // Fixed-size records: parts of them go to threads, each record to its own place.
    constexpr size_t smallest_part = size_t(1) << 18;
    std::atomic<bool> taken{true};  // false once a part meets a record it cannot take as it is
    const size_t vertices = size_t(vertex_el.count), faces = size_t(face_el->count);
    parallel_resize(mesh.positions, vertices * 3, threads);
    const Parts vertex_parts(vertices, smallest_part);
    parallel_for(vertex_parts.count(), threads, [&](size_t p) {
        const char* v = body.data() + vertex_at + vertex_parts.first(p) * vertex_stride;
        for (size_t r = vertex_parts.first(p); r < vertex_parts.last(p); ++r, v += vertex_stride)
            for (int k = 0; k < 3; ++k) {
                float c;
                std::memcpy(&c, v + xyz_offset[k], 4);
                if (!std::isfinite(c)) {
                    taken = false;
                    return;
                }
                mesh.positions[r * 3 + k] = c;
            }
    });
    const bool signed_index = face_el->properties[0].type < 0;
    parallel_resize(mesh.indices, faces * 3, threads);
    const Parts face_parts(faces, smallest_part);
    parallel_for(face_parts.count(), threads, [&](size_t p) {
        const char* f = body.data() + face_at + face_parts.first(p) * index_bytes;
        for (size_t r = face_parts.first(p); r < face_parts.last(p); ++r, f += index_bytes) {
            bool good = f[0] == 3;
            for (int k = 0; k < 3; ++k) {
                uint32_t i;
                std::memcpy(&i, f + 1 + 4 * k, 4);
                good &= !(signed_index && int32_t(i) < 0) && i < vertices;
                mesh.indices[r * 3 + k] = i;
            }
            if (!good) {
                taken = false;
                return;
            }
        }
    });
    return taken;
}

// The header: the encoding and the elements with their properties, up to end_header.
struct Header {
    Encoding enc = Encoding::ascii;
    std::vector<Element> elements;
    size_t body_at = 0;  // the first byte after end_header's line
};

Property parse_property(const std::vector<std::string_view>& tok, const std::function<void(const std::string&)>& bad) {
    Property p;
    if (tok.size() == 5 && tok[1] == "list") {
        p.list = true;
        p.count_type = type_code(tok[2]);
        p.type = type_code(tok[3]);
        p.name = tok[4];
        if (p.count_type == 0 || (p.count_type > 0 && (p.count_type & float_flag))) bad("bad list count type");
    } else if (tok.size() == 3) {
        p.type = type_code(tok[1]);
        p.name = tok[2];
    } else {
        bad("malformed property line");
    }
    if (p.type == 0) bad("unknown property type");
    return p;
}

Header read_header(std::string_view text, const std::string& name) {
    if (text.substr(0, 4) != "ply\n" && text.substr(0, 5) != "ply\r\n")
        throw LoadError(name + ": not a PLY file (no 'ply' magic line)");
    LineReader reader{text};
    std::string line;
    std::vector<std::string_view> tok;
    Header h;
    bool has_format = false, ended = false;
    reader.next(line, false);
    auto bad = [&](const std::string& what) {
        throw LoadError(name + ": line " + std::to_string(reader.line_number) + ": " + what);
    };
    while (!ended && reader.next(line, false)) {
        split(line, tok);
        if (tok.empty() || tok[0] == "comment" || tok[0] == "obj_info") continue;
        if (tok[0] == "format") {
            if (has_format || tok.size() != 3 || tok[2] != "1.0") bad("malformed format line");
            if (tok[1] == "ascii")
                h.enc = Encoding::ascii;
            else if (tok[1] == "binary_little_endian")
                h.enc = Encoding::little;
            else if (tok[1] == "binary_big_endian")
                h.enc = Encoding::big;
            else
                bad("unknown format " + quoted(tok[1]));
            has_format = true;
        } else if (tok[0] == "element") {
            long long count;
            if (tok.size() != 3 || !parse_int(tok[2], count) || count < 0) bad("malformed element line");
            h.elements.push_back({std::string(tok[1]), uint64_t(count), {}});
        } else if (tok[0] == "property") {
            if (h.elements.empty()) bad("property before any element");
            h.elements.back().properties.push_back(parse_property(tok, bad));
        } else if (tok[0] == "end_header") {
            ended = true;
        }
        // Anything else is free text that real exporters write into headers ("Created by Blender..."): skipped.
    }
    if (!ended) throw LoadError(name + ": header has no end_header (truncated?)");
    if (!has_format) throw LoadError(name + ": header has no format line");
    h.body_at = reader.pos;
    return h;
}

// The vertex element, with its x, y and z properties; required, while faces or tristrips may be absent (a
// point cloud).
struct VertexElement {
    const Element* element = nullptr;
    int xyz[3] = {-1, -1, -1};  // property indices
};

VertexElement find_vertex_element(const std::vector<Element>& elements, const std::string& name) {
    VertexElement v;
    for (const Element& e : elements)
        if (e.name == "vertex") v.element = &e;
    if (!v.element) throw LoadError(name + ": no vertex element");
    const char* axes[3] = {"x", "y", "z"};
    for (int k = 0; k < 3; ++k) v.xyz[k] = find_property(*v.element, axes[k]);
    if (v.xyz[0] < 0 || v.xyz[1] < 0 || v.xyz[2] < 0) throw LoadError(name + ": vertex element lacks x, y or z");
    if (v.element->count > std::numeric_limits<uint32_t>::max()) throw LoadError(name + ": more than 2^32-1 vertices");
    return v;
}

// Whether the coordinates are floats in the file, kept exactly (shift_exactly); text and doubles are
// centred in double (store_centred).
bool exact_floats(const VertexElement& v, Encoding enc) {
    auto float_exact = [](int type) { return type == (float_flag | 4) || std::abs(type) <= 2; };
    if (enc == Encoding::ascii) return false;
    for (int k = 0; k < 3; ++k)
        if (!float_exact(v.element->properties[size_t(v.xyz[k])].type)) return false;
    return true;
}

// Appends a face (count, then its indices) or a tristrip's triangles (runs separated by -1, every other
// triangle flipped; each as 3, then its indices) to `pending`.
void append_polygons(const Element& e, uint64_t row, const std::vector<uint32_t>& list, Body& body,
                     std::vector<uint32_t>& pending) {
    if (e.name == "face") {
        if (list.size() < 3) body.fail(e.name, row, "face with " + std::to_string(list.size()) + " vertices");
        pending.push_back(uint32_t(list.size()));
        pending.insert(pending.end(), list.begin(), list.end());
        return;
    }
    size_t run = 0;
    for (size_t i = 0; i < list.size(); ++i) {
        if (list[i] == UINT32_MAX) {
            run = 0;
            continue;
        }
        if (++run >= 3) {
            bool odd = (run - 3) & 1;
            uint32_t a = list[i - 2], b = list[i - 1];
            pending.insert(pending.end(), {3, odd ? b : a, odd ? a : b, list[i]});
        }
    }
}

// Reads one list property of record `row`; with `keep`, its values into `list` as vertex indices, checked
// against `vertex_count` (a tristrip's -1 as UINT32_MAX), else skipped.
void read_list(const Element& e, uint64_t row, const Property& prop, bool keep, uint64_t vertex_count, Body& body,
               std::vector<uint32_t>& list) {
    double n = body.read(prop.count_type, e.name, row);
    if (!(n >= 0) || n > double(body.remaining()))
        body.fail(e.name, row, "list length " + std::to_string(n) + " exceeds the data");
    if (keep) list.clear();
    for (size_t k = 0; k < size_t(n); ++k) {
        double v = body.read(prop.type, e.name, row);
        if (!keep) continue;
        bool restart = e.name == "tristrips" && v == -1;
        if (!restart && !(v >= 0 && v < double(vertex_count) && v == std::floor(v)))
            body.fail(e.name, row,
                      "index " + std::to_string(v) + " out of range (" + std::to_string(vertex_count) + " vertices)");
        list.push_back(restart ? UINT32_MAX : uint32_t(v));
    }
}

// Any file the fast path does not take: every element's records read value by value, the vertices'
// positions into `xyz` and the faces and strip triangles into `pending` in file order (count, then
// indices), to be triangulated once the positions are final, whichever element came first.
void read_records(const Header& h, const VertexElement& vertex, Body& body, std::vector<double>& xyz,
                  std::vector<uint32_t>& pending) {
    std::vector<double> values;
    std::vector<uint32_t> list;
    const uint64_t vertex_count = vertex.element->count;
    for (const Element& e : h.elements) {
        // Refuse counts the remaining data cannot hold before reserving anything, and reserve no more
        // records than it can hold (a shorter file then says where it ends). An element without properties
        // holds nothing.
        if (e.properties.empty()) continue;
        if (e.count > body.remaining())
            body.fail("element " + e.name + ": count " + std::to_string(e.count) + " exceeds the data (truncated?)");
        bool is_vertex = &e == vertex.element;
        int list_prop = (e.name == "face" || e.name == "tristrips")
            ? std::max(find_property(e, "vertex_indices"), find_property(e, "vertex_index"))
            : -1;
        if (is_vertex)
            xyz.reserve(size_t(std::min<uint64_t>(e.count, body.remaining() / least_record_bytes(e, h.enc))) * 3);
        values.resize(e.properties.size());
        for (uint64_t r = 0; r < e.count; ++r) {
            for (size_t p = 0; p < e.properties.size(); ++p) {
                const Property& prop = e.properties[p];
                if (!prop.list) {
                    values[p] = body.read(prop.type, e.name, r);
                    continue;
                }
                bool keep = int(p) == list_prop;
                read_list(e, r, prop, keep, vertex_count, body, list);
                if (keep) append_polygons(e, r, list, body, pending);
            }
            if (is_vertex) {
                double v[3] = {values[size_t(vertex.xyz[0])], values[size_t(vertex.xyz[1])],
                               values[size_t(vertex.xyz[2])]};
                for (double c : v)
                    if (!std::isfinite(c) || std::fabs(c) > std::numeric_limits<float>::max())
                        body.fail("vertex " + std::to_string(r) + ": position is not a finite float (" +
                                  std::to_string(c) + ")");
                xyz.insert(xyz.end(), {v[0], v[1], v[2]});
            }
        }
    }
}

}  // namespace

Scene load_ply_memory(const uint8_t* data, size_t size, const std::string& name, unsigned threads) {
    if (size == 0) throw LoadError(name + ": empty file");
    std::string_view text(reinterpret_cast<const char*>(data), size);
    const Header header = read_header(text, name);
    const VertexElement vertex = find_vertex_element(header.elements, name);

    Mesh mesh;
    if (header.enc == Encoding::little &&
        read_float_triangles(text.substr(header.body_at), header.elements, *vertex.element, vertex.xyz, mesh,
                             threads)) {
        Origin origin = shift_exactly(mesh.positions, threads);
        return single_mesh_scene(std::move(mesh), name, origin, threads);
    }
    mesh = Mesh{};

    Body body(text.substr(header.body_at), header.enc, name);
    std::vector<double> xyz;
    std::vector<uint32_t> pending;
    read_records(header, vertex, body, xyz, pending);
    Origin origin;
    if (exact_floats(vertex, header.enc)) {
        mesh.positions.assign(xyz.begin(), xyz.end());  // each value a float: exact
        origin = shift_exactly(mesh.positions);
    } else {
        origin = store_centred(xyz, mesh.positions);
    }
    PolygonTriangulator triangulator;
    for (size_t at = 0; at < pending.size(); at += 1 + pending[at])
        triangulator.add(mesh.positions.data(), &pending[at + 1], pending[at], mesh.indices);

    Scene scene = single_mesh_scene(std::move(mesh), name, origin);
    scene.report.polygons = triangulator.counts();
    return scene;
}

}  // namespace cb
