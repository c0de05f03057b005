// OBJ and OFF readers.
//
// OpenMesh's readers for these two text formats lose data that shadows need: its OBJ reader silently drops
// faces that repeat a vertex (f 1 1 3), ignores line continuations and skips vertices it cannot parse
// (inf, nan) so later faces point at the wrong vertex; its OFF reader rejects comments and headers run
// together with their counts ("OFF8 6 12"). These formats are small enough to read exactly here, with an
// error naming the line for anything malformed. STL goes through OpenMesh (load_mesh.cpp). Faces of more
// than three vertices are triangulated in their plane (polygon_triangulate.h).
#include <cmath>
#include <limits>
#include <string_view>

#include "load.h"
#include "polygon_triangulate.h"
#include "text_scan.h"

namespace cb {
namespace {

// Positions must be finite and representable as float, since that is how they are stored.
void push_position(Mesh& mesh, const double xyz[3], const std::string& where) {
    for (int k = 0; k < 3; ++k)
        if (!std::isfinite(xyz[k]) || std::fabs(xyz[k]) > std::numeric_limits<float>::max())
            throw LoadError(where + ": position is not a finite float (" + std::to_string(xyz[k]) + ")");
    mesh.positions.insert(mesh.positions.end(), {float(xyz[0]), float(xyz[1]), float(xyz[2])});
}

void push_polygon(PolygonTriangulator& triangulator, Mesh& mesh, const std::vector<uint32_t>& poly) {
    triangulator.add(mesh.positions.data(), poly.data(), poly.size(), mesh.indices);
}

Scene counted_scene(Mesh mesh, const std::string& name, const PolygonTriangulator& triangulator) {
    Scene scene = single_mesh_scene(std::move(mesh), name);
    scene.report.polygons = triangulator.counts();
    return scene;
}

}  // namespace

Scene load_obj_memory(const uint8_t* data, size_t size, const std::string& name) {
    if (size == 0) throw LoadError(name + ": empty file");
    LineReader reader{std::string_view(reinterpret_cast<const char*>(data), size)};
    Mesh mesh;
    std::string line;
    std::vector<std::string_view> tok;
    std::vector<uint32_t> poly;
    PolygonTriangulator triangulator;
    bool saw_any = false;
    while (reader.next(line, true)) {
        split(line, tok);
        if (tok.empty()) continue;
        std::string where = name + ": line " + std::to_string(reader.line_number);
        if (tok[0] == "v") {
            saw_any = true;
            if (tok.size() < 4) throw LoadError(where + ": vertex needs 3 coordinates");
            double xyz[3];
            for (int k = 0; k < 3; ++k)
                if (!parse_double(tok[1 + k], xyz[k]))
                    throw LoadError(where + ": bad coordinate " + quoted(tok[1 + k]));
            push_position(mesh, xyz, where + ": vertex " + std::to_string(mesh.vertex_count() + 1));
        } else if (tok[0] == "f") {
            saw_any = true;
            poly.clear();
            long long count = static_cast<long long>(mesh.vertex_count());
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
            push_polygon(triangulator, mesh, poly);
        }
        // vt, vn, g, o, s, l, p, usemtl, mtllib and the rest carry nothing shadows need.
    }
    if (!saw_any) throw LoadError(name + ": no vertices or faces (not an OBJ file?)");
    return counted_scene(std::move(mesh), name, triangulator);
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

    Mesh mesh;
    mesh.positions.reserve(size_t(nv) * 3);
    for (long long v = 0; v < nv; ++v) {
        do {
            if (!reader.next(line, false))
                throw LoadError(name + ": truncated: " + std::to_string(v) + " of " + std::to_string(nv) + " vertices");
            split(line, tok);
        } while (tok.empty());
        std::string where = name + ": line " + std::to_string(reader.line_number) + ": vertex " + std::to_string(v);
        if (tok.size() < 3) throw LoadError(where + ": needs 3 coordinates");
        double xyz[3];
        for (int k = 0; k < 3; ++k)
            if (!parse_double(tok[k], xyz[k])) throw LoadError(where + ": bad coordinate " + quoted(tok[k]));
        push_position(mesh, xyz, where);
    }
    std::vector<uint32_t> poly;
    PolygonTriangulator triangulator;
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
        push_polygon(triangulator, mesh, poly);  // anything after the indices is a face colour
    }
    return counted_scene(std::move(mesh), name, triangulator);
}

}  // namespace cb
