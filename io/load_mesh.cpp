// Binary STL loading through OpenMesh's reader (ASCII STL is read in double by load_text.cpp).
//
// OpenMesh's own mesh kernels are half-edge structures: they drop or split faces that are non-manifold or
// repeat a vertex. Shadows need every triangle exactly as written, so the readers feed a flat importer
// instead, which keeps each polygon (fan-triangulated) and each vertex as given.
#include <OpenMesh/Core/IO/IOManager.hh>
#include <OpenMesh/Core/IO/importer/BaseImporter.hh>
#include <OpenMesh/Core/IO/reader/BaseReader.hh>
#include <OpenMesh/Core/Utils/Endian.hh>

#include <cctype>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <sstream>

#include "load.h"

namespace cb {
namespace {

using namespace OpenMesh;
using OpenMesh::IO::BaseImporter;

class FlatImporter final : public BaseImporter {
public:
    std::vector<double> points;       // x, y, z per vertex, as read
    std::vector<uint32_t> triangles;  // fan-triangulated polygons
    std::string error;                // first problem seen; the reader cannot be stopped mid-file
    size_t faces = 0;

    VertexHandle add_vertex(const Vec3f& p) override { return push(p[0], p[1], p[2]); }
    VertexHandle add_vertex(const Vec3d& p) override { return push(p[0], p[1], p[2]); }
    VertexHandle add_vertex() override { return push(0, 0, 0); }

    FaceHandle add_face(const VHandles& v) override {
        size_t face = faces++;
        if (v.size() < 3) {
            note("face " + std::to_string(face) + " has " + std::to_string(v.size()) + " vertices");
            return FaceHandle();
        }
        for (VertexHandle h : v)
            if (!h.is_valid() || size_t(h.idx()) >= points.size() / 3) {
                note("face " + std::to_string(face) + ": index " + std::to_string(h.idx()) + " out of range (" +
                     std::to_string(points.size() / 3) + " vertices)");
                return FaceHandle();
            }
        for (size_t i = 1; i + 1 < v.size(); ++i)
            triangles.insert(triangles.end(), {uint32_t(v[0].idx()), uint32_t(v[i].idx()), uint32_t(v[i + 1].idx())});
        return FaceHandle(int(face));
    }

    // Everything below is data clusterbake does not use: accept and ignore.
    HalfedgeHandle add_edge(VertexHandle, VertexHandle) override { return HalfedgeHandle(); }
    FaceHandle add_face(HalfedgeHandle) override { return FaceHandle(); }
    void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<Vec2f>&) override {}
    void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<Vec3f>&) override {}
    void set_face_texindex(FaceHandle, int) override {}
    void set_point(VertexHandle h, const Vec3f& p) override {
        if (h.is_valid() && size_t(h.idx()) < points.size() / 3)
            for (int c = 0; c < 3; ++c) points[size_t(h.idx()) * 3 + c] = p[c];
    }
    void set_halfedge(VertexHandle, HalfedgeHandle) override {}
    void set_normal(VertexHandle, const Vec3f&) override {}
    void set_normal(VertexHandle, const Vec3d&) override {}
    void set_color(VertexHandle, const Vec3uc&) override {}
    void set_color(VertexHandle, const Vec4uc&) override {}
    void set_color(VertexHandle, const Vec3f&) override {}
    void set_color(VertexHandle, const Vec4f&) override {}
    void set_texcoord(VertexHandle, const Vec2f&) override {}
    void set_status(VertexHandle, const Attributes::StatusInfo&) override {}
    void set_next(HalfedgeHandle, HalfedgeHandle) override {}
    void set_face(HalfedgeHandle, FaceHandle) override {}
    void request_face_texcoords2D() override {}
    void set_texcoord(HalfedgeHandle, const Vec2f&) override {}
    void set_texcoord(VertexHandle, const Vec3f&) override {}
    void set_texcoord(HalfedgeHandle, const Vec3f&) override {}
    void set_status(HalfedgeHandle, const Attributes::StatusInfo&) override {}
    void set_color(EdgeHandle, const Vec3uc&) override {}
    void set_color(EdgeHandle, const Vec4uc&) override {}
    void set_color(EdgeHandle, const Vec3f&) override {}
    void set_color(EdgeHandle, const Vec4f&) override {}
    void set_status(EdgeHandle, const Attributes::StatusInfo&) override {}
    void set_normal(FaceHandle, const Vec3f&) override {}
    void set_normal(FaceHandle, const Vec3d&) override {}
    void set_color(FaceHandle, const Vec3uc&) override {}
    void set_color(FaceHandle, const Vec4uc&) override {}
    void set_color(FaceHandle, const Vec3f&) override {}
    void set_color(FaceHandle, const Vec4f&) override {}
    void set_status(FaceHandle, const Attributes::StatusInfo&) override {}
    void add_texture_information(int, std::string) override {}
    size_t n_vertices() const override { return points.size() / 3; }
    size_t n_faces() const override { return faces; }
    size_t n_edges() const override { return 0; }

private:
    VertexHandle push(double x, double y, double z) {
        points.insert(points.end(), {x, y, z});
        return VertexHandle(int(points.size() / 3 - 1));
    }
    void note(const std::string& what) {
        if (error.empty()) error = what;
    }
};

// OpenMesh's STL reader tells ASCII from binary by the size a binary file of its facet count would have,
// which holds only for a file on disk; from a stream it must be told. Same idea here.
bool looks_like_binary_stl(const uint8_t* data, size_t size) {
    if (size < 84) return false;
    uint32_t n = uint32_t(data[80]) | uint32_t(data[81]) << 8 | uint32_t(data[82]) << 16 | uint32_t(data[83]) << 24;
    return uint64_t(n) * 50 + 84 == size;
}

// A file that is not binary STL must be ASCII STL, which starts with "solid": OpenMesh's reader would take
// any other text as an STL without facets.
void check_stl_kind(const uint8_t* data, size_t size, const std::string& name) {
    size_t at = 0;
    while (at < size && std::isspace(data[at])) ++at;
    if (size - at >= 5 && std::memcmp(data + at, "solid", 5) == 0) return;
    std::string binary = "at least 84 bytes";
    if (size >= 84) {
        uint64_t n = uint64_t(data[80]) | uint64_t(data[81]) << 8 | uint64_t(data[82]) << 16 | uint64_t(data[83]) << 24;
        binary = "its header's " + std::to_string(n) + " facets need " + std::to_string(84 + 50 * n) +
            " bytes, it has " + std::to_string(size);
    }
    throw LoadError(name + ": not an STL file: neither binary STL (" + binary +
                    ") nor ASCII STL (starts with 'solid')");
}

}  // namespace

Scene load_mesh_memory(const uint8_t* data, size_t size, FileFormat format, const std::string& name, unsigned threads) {
    switch (format) {
        case FileFormat::obj: return load_obj_memory(data, size, name);
        case FileFormat::off: return load_off_memory(data, size, name);
        case FileFormat::ply: return load_ply_memory(data, size, name, threads);
        case FileFormat::stl: return load_stl_memory(data, size, name);
        default: throw LoadError(name + ": not an OBJ, PLY, OFF or STL file");
    }
}

Scene load_stl_memory(const uint8_t* data, size_t size, const std::string& name) {
    if (size == 0) throw LoadError(name + ": empty file");
    if (!looks_like_binary_stl(data, size)) {
        check_stl_kind(data, size, name);
        return load_ascii_stl_memory(data, size, name);
    }

    // OpenMesh reports problems on its own log streams; keep them off the user's terminal. The IO manager
    // is a process-wide singleton, so reads are serialised.
    static std::mutex reader_mutex;
    std::lock_guard<std::mutex> lock(reader_mutex);
    static bool quiet = [] {
        omerr().disable();
        omlog().disable();
        omout().disable();
        return true;
    }();
    (void)quiet;

    FlatImporter importer;
    IO::Options options;
    options += IO::Options::Binary;
    std::istringstream stream(std::string(reinterpret_cast<const char*>(data), size), std::ios::binary);
    bool ok = IO::IOManager().read(stream, "stl", importer, options);
    if (!importer.error.empty()) throw LoadError(name + ": " + importer.error);
    if (!ok) throw LoadError(name + ": OpenMesh's STL reader rejected the file (malformed or truncated)");

    for (size_t i = 0; i < importer.points.size(); ++i) {
        double v = importer.points[i];
        if (!std::isfinite(v) || std::fabs(v) > std::numeric_limits<float>::max())
            throw LoadError(name + ": vertex " + std::to_string(i / 3) + ": position is not a finite float (" +
                            std::to_string(v) + ")");
    }
    Mesh mesh;
    mesh.positions.assign(importer.points.begin(), importer.points.end());  // floats in the file: exact
    mesh.indices = std::move(importer.triangles);
    Origin origin = shift_exactly(mesh.positions);
    return single_mesh_scene(std::move(mesh), name, origin);
}

}  // namespace cb
