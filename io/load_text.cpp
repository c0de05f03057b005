// OBJ, OFF and ASCII STL readers.
//
// OpenMesh's readers for these text formats lose data that shadows need: its OBJ reader silently drops
// faces that repeat a vertex (f 1 1 3), ignores line continuations and skips vertices it cannot parse
// (inf, nan) so later faces point at the wrong vertex; its OFF reader rejects comments and headers run
// together with their counts ("OFF8 6 12"); its ASCII STL reader parses floats, and merges corners that
// are equal as floats, which far from the origin are distinct points. These formats are small enough to
// read exactly here, in double, with an error naming the line for anything malformed. Binary STL goes
// through OpenMesh (load_mesh.cpp). Faces of more than three vertices are triangulated in their plane
// (polygon_triangulate.h).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string_view>
#include <unordered_map>

#include "load.h"
#include "polygon_triangulate.h"
#include "text_scan.h"

namespace cb {
namespace {

// Coordinates must be finite and representable as float, since positions are stored as floats (relative
// to the mesh's origin, which is nearer still).
void push_coordinates(std::vector<double>& xyz, const double v[3], const std::string& where) {
    for (int k = 0; k < 3; ++k)
        if (!std::isfinite(v[k]) || std::fabs(v[k]) > std::numeric_limits<float>::max())
            throw LoadError(where + ": position is not a finite float (" + std::to_string(v[k]) + ")");
    xyz.insert(xyz.end(), {v[0], v[1], v[2]});
}

// Faces kept as read (vertex count, then indices) until every position is known: they are triangulated on
// the floats the mesh ends up with.
void push_polygon(std::vector<uint32_t>& polygons, const std::vector<uint32_t>& poly) {
    polygons.push_back(uint32_t(poly.size()));
    polygons.insert(polygons.end(), poly.begin(), poly.end());
}

// The mesh centred on its box (mesh_frame.h), its polygons triangulated, in one validated scene.
Scene centred_scene(const std::vector<double>& xyz, const std::vector<uint32_t>& polygons, const std::string& name) {
    Mesh mesh;
    Origin origin = store_centred(xyz, mesh.positions);
    PolygonTriangulator triangulator;
    for (size_t at = 0; at < polygons.size(); at += 1 + polygons[at])
        triangulator.add(mesh.positions.data(), &polygons[at + 1], polygons[at], mesh.indices);
    Scene scene = single_mesh_scene(std::move(mesh), name, origin);
    scene.report.polygons = triangulator.counts();
    return scene;
}

}  // namespace

Scene load_obj_memory(const uint8_t* data, size_t size, const std::string& name) {
    if (size == 0) throw LoadError(name + ": empty file");
    LineReader reader{std::string_view(reinterpret_cast<const char*>(data), size)};
    std::vector<double> xyz;
    std::vector<uint32_t> poly, polygons;
    std::string line;
    std::vector<std::string_view> tok;
    bool saw_any = false;
    while (reader.next(line, true)) {
        split(line, tok);
        if (tok.empty()) continue;
        std::string where = name + ": line " + std::to_string(reader.line_number);
        if (tok[0] == "v") {
            saw_any = true;
            if (tok.size() < 4) throw LoadError(where + ": vertex needs 3 coordinates");
            double v[3];
            for (int k = 0; k < 3; ++k)
                if (!parse_double(tok[1 + k], v[k])) throw LoadError(where + ": bad coordinate " + quoted(tok[1 + k]));
            push_coordinates(xyz, v, where + ": vertex " + std::to_string(xyz.size() / 3 + 1));
        } else if (tok[0] == "f") {
            saw_any = true;
            poly.clear();
            long long count = static_cast<long long>(xyz.size() / 3);
            for (size_t k = 1; k < tok.size(); ++k) {
                std::string_view ref = tok[k].substr(0, tok[k].find('/'));  // v, v/vt, v//vn, v/vt/vn
                long long i;
                if (!parse_int(ref, i)) throw LoadError(where + ": bad face index " + quoted(tok[k]));
                long long resolved = i > 0 ? i - 1 : count + i;  // negative indices count back from the last vertex
                if (i == 0 || resolved < 0 || resolved >= count)
                    throw LoadError(where + ": face index " + std::to_string(i) + " out of range (" +
                                    std::to_string(count) + " vertices)");
                poly.push_back(uint32_t(resolved));
            }
            if (poly.size() < 3) throw LoadError(where + ": face with " + std::to_string(poly.size()) + " vertices");
            push_polygon(polygons, poly);
        }
        // vt, vn, g, o, s, l, p, usemtl, mtllib and the rest carry nothing shadows need.
    }
    if (!saw_any) throw LoadError(name + ": no vertices or faces (not an OBJ file?)");
    return centred_scene(xyz, polygons, name);
}

Scene load_off_memory(const uint8_t* data, size_t size, const std::string& name) {
    if (size == 0) throw LoadError(name + ": empty file");
    LineReader reader{std::string_view(reinterpret_cast<const char*>(data), size)};
    std::string line;
    std::vector<std::string_view> tok, counts;

    // Header: [ST][C][N]OFF, optionally followed on the same line by the counts (even with no space).
    while (reader.next(line, false)) {
        split(line, tok);
        if (!tok.empty()) break;
    }
    if (tok.empty()) throw LoadError(name + ": empty file");
    std::string_view keyword = tok[0];
    size_t off = keyword.find("OFF");
    std::string_view prefix = off == std::string_view::npos ? keyword : keyword.substr(0, off);
    if (off == std::string_view::npos || prefix.find_first_not_of("STCN") != std::string_view::npos)
        throw LoadError(name + ": line " + std::to_string(reader.line_number) + ": not an OFF header " +
                        quoted(keyword));
    std::string_view rest = keyword.substr(off + 3);
    if (rest == "BINARY" || (tok.size() > 1 && tok[1] == "BINARY"))
        throw LoadError(name + ": binary OFF is not supported");
    if (!rest.empty()) counts.push_back(rest);
    for (size_t k = 1; k < tok.size(); ++k) counts.push_back(tok[k]);
    while (counts.empty() && reader.next(line, false)) split(line, counts);

    long long nv, nf;
    if (counts.size() < 2 || !parse_int(counts[0], nv) || !parse_int(counts[1], nf) || nv < 0 || nf < 0)
        throw LoadError(name + ": line " + std::to_string(reader.line_number) + ": bad vertex/face counts");
    // Each vertex and face needs at least a few bytes: refuse counts the file cannot hold before allocating.
    if (uint64_t(nv) + uint64_t(nf) > size)
        throw LoadError(name + ": counts " + std::to_string(nv) + " vertices, " + std::to_string(nf) +
                        " faces exceed what the file can hold (truncated?)");

    std::vector<double> xyz;
    xyz.reserve(size_t(std::min<uint64_t>(uint64_t(nv), size / 6)) * 3);  // a vertex takes 6 bytes or more
    for (long long v = 0; v < nv; ++v) {
        do {
            if (!reader.next(line, false))
                throw LoadError(name + ": truncated: " + std::to_string(v) + " of " + std::to_string(nv) + " vertices");
            split(line, tok);
        } while (tok.empty());
        std::string where = name + ": line " + std::to_string(reader.line_number) + ": vertex " + std::to_string(v);
        if (tok.size() < 3) throw LoadError(where + ": needs 3 coordinates");
        double c[3];
        for (int k = 0; k < 3; ++k)
            if (!parse_double(tok[k], c[k])) throw LoadError(where + ": bad coordinate " + quoted(tok[k]));
        push_coordinates(xyz, c, where);
    }
    std::vector<uint32_t> poly, polygons;
    for (long long f = 0; f < nf; ++f) {
        do {
            if (!reader.next(line, false))
                throw LoadError(name + ": truncated: " + std::to_string(f) + " of " + std::to_string(nf) + " faces");
            split(line, tok);
        } while (tok.empty());
        std::string where = name + ": line " + std::to_string(reader.line_number) + ": face " + std::to_string(f);
        long long n;
        if (!parse_int(tok[0], n) || n < 3 || size_t(n) + 1 > tok.size())
            throw LoadError(where + ": bad vertex count " + quoted(tok[0]));
        poly.clear();
        for (long long k = 1; k <= n; ++k) {
            long long i;
            if (!parse_int(tok[size_t(k)], i) || i < 0 || i >= nv)
                throw LoadError(where + ": index " + quoted(tok[size_t(k)]) + " out of range (" + std::to_string(nv) +
                                " vertices)");
            poly.push_back(uint32_t(i));
        }
        push_polygon(polygons, poly);  // anything after the indices is a face colour
    }
    return centred_scene(xyz, polygons, name);
}

namespace {

// STL corners merged by exact value, as OpenMesh's reader merges them (-0 equals 0).
struct CornerKey {
    uint64_t bits[3];
    bool operator==(const CornerKey& o) const {
        return bits[0] == o.bits[0] && bits[1] == o.bits[1] && bits[2] == o.bits[2];
    }
};

struct CornerHash {
    size_t operator()(const CornerKey& k) const {
        uint64_t h = 0x9e3779b97f4a7c15ULL;
        for (uint64_t b : k.bits) {
            h = (h ^ b) * 0xff51afd7ed558ccdULL;
            h ^= h >> 29;
        }
        return size_t(h);
    }
};

CornerKey corner_key(const double v[3]) {
    CornerKey k;
    for (int i = 0; i < 3; ++i) {
        double x = v[i] + 0.0;  // -0 becomes 0
        std::memcpy(&k.bits[i], &x, 8);
    }
    return k;
}

}  // namespace

Scene load_ascii_stl_memory(const uint8_t* data, size_t size, const std::string& name) {
    LineReader reader{std::string_view(reinterpret_cast<const char*>(data), size)};
    std::unordered_map<CornerKey, uint32_t, CornerHash> ids;
    std::vector<double> xyz;
    std::vector<uint32_t> polygons, facet;
    std::string line;
    std::vector<std::string_view> tok;
    while (reader.next(line, false)) {
        split(line, tok);
        if (tok.empty() || tok[0] != "vertex") continue;  // facet normals are not used: real exporters write anything
        std::string where = name + ": line " + std::to_string(reader.line_number);
        if (tok.size() != 4) throw LoadError(where + ": vertex needs 3 coordinates");
        double v[3];
        for (int k = 0; k < 3; ++k)
            if (!parse_double(tok[1 + k], v[k]) || !std::isfinite(v[k]))
                throw LoadError(where + ": " + quoted(tok[1 + k]) + " is not a finite number");
        auto [it, added] = ids.try_emplace(corner_key(v), uint32_t(xyz.size() / 3));
        if (added) push_coordinates(xyz, v, where + ": vertex " + std::to_string(it->second));
        facet.push_back(it->second);
        if (facet.size() < 3) continue;
        // A facet with a repeated corner is dropped, as OpenMesh's reader drops it.
        if (facet[0] != facet[1] && facet[1] != facet[2] && facet[0] != facet[2]) push_polygon(polygons, facet);
        facet.clear();
    }
    if (!facet.empty())
        throw LoadError(name + ": truncated: the last facet has " + std::to_string(facet.size()) + " vertices");
    return centred_scene(xyz, polygons, name);
}

}  // namespace cb
