// The in-memory scene every clusterbake stage reads: flat arrays, nothing decoded that shadows do not need.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "source_files.h"

namespace cb {

// A contiguous range of a mesh's triangles that came from one glTF primitive (or the whole file for
// OBJ/PLY/OFF/STL). Sidedness is the one material fact the shadow runtime needs.
struct Primitive {
    uint32_t first_triangle = 0;
    uint32_t triangle_count = 0;
    bool double_sided = false;
};

// Geometry in the mesh's own frame, whose origin the loader puts near the mesh (mesh_frame.h), so that
// floats hold it to float precision relative to its size wherever it lies. A mesh used by several nodes is
// stored once.
struct Mesh {
    std::string name;
    std::vector<float> positions;   // x, y, z per vertex, in the mesh's frame
    std::vector<uint32_t> indices;  // 3 per triangle, each < vertex_count()
    std::vector<Primitive> primitives;

    size_t vertex_count() const { return positions.size() / 3; }
    size_t triangle_count() const { return indices.size() / 3; }
};

// Column-major 4x4 affine transform (glTF's convention), kept in double so composed node chains stay exact
// enough for coordinates near 1e6.
using Transform = std::array<double, 16>;

constexpr Transform identity_transform() { return {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}; }

// glTF's translation, rotation (unit quaternion x, y, z, w) and scale as one transform: T x R x S.
inline Transform trs_transform(const double* t, const double* q, const double* s) {
    const double x = q[0], y = q[1], z = q[2], w = q[3];
    const double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),
                         2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
                         2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y)};
    Transform m = identity_transform();
    for (int col = 0; col < 3; ++col)
        for (int row = 0; row < 3; ++row) m[col * 4 + row] = r[col * 3 + row] * s[col];
    m[12] = t[0];
    m[13] = t[1];
    m[14] = t[2];
    return m;
}

// `world` maps the mesh's frame to world space: the source's transform (a glTF node's composed chain,
// identity for the other formats) times the translation to the mesh frame's origin. World positions are
// transform_point(world, position), in double: the file's coordinates (exactly for float inputs, to float
// precision relative to the mesh's size for text).
struct Instance {
    uint32_t mesh = 0;
    Transform world = identity_transform();
    std::string node_name;
};

// The faces of more than three vertices in an OBJ, OFF or PLY file, by how they were triangulated
// (polygon_triangulate.h).
struct PolygonCounts {
    uint64_t total = 0;       // faces of 4 or more vertices
    uint64_t concave = 0;     // simple but not convex in their plane (or with repeated vertices): ear clipping
    uint64_t not_simple = 0;  // their projection crosses or touches itself: the fan, as written
    uint64_t degenerate = 0;  // no area at all: the fan, as written
};

// A glTF extension the file names (in extensionsUsed, extensionsRequired or on any of its objects), and
// what the loader did with it.
struct ExtensionUse {
    enum class Status {
        applied,      // read into the geometry (Draco, meshopt, quantization, GPU instancing)
        no_geometry,  // changes nothing the loader reads (materials, textures, lights...): skipped
        unsupported,  // unknown, on objects that carry geometry: loaded without it, with a warning
    };
    std::string name;
    bool required = false;
    Status status = Status::no_geometry;
    std::string where;  // the kinds of objects it is on ("meshes, nodes"), or empty when on none
};

// Things the loader skipped or noticed; reported by `clusterbake info`, never silently dropped.
struct LoadReport {
    uint32_t primitives = 0;               // triangle primitives loaded
    uint32_t skipped_primitives = 0;       // POINTS / LINES / LINE_LOOP / LINE_STRIP
    uint32_t draco_primitives = 0;         // decoded from KHR_draco_mesh_compression
    uint32_t meshopt_views = 0;            // bufferViews decoded from EXT_meshopt_compression
    uint32_t instanced_nodes = 0;          // nodes with EXT_mesh_gpu_instancing
    uint64_t gpu_instances = 0;            // instances those nodes made, one per element of their accessors
    uint64_t degenerate_triangles = 0;     // repeated index or zero area, kept in the mesh
    uint64_t unreferenced_meshes = 0;      // glTF meshes no node of the chosen scene uses
    PolygonCounts polygons;                // OBJ, OFF and PLY faces of more than three vertices
    std::vector<ExtensionUse> extensions;  // glTF: every extension the file names, in the order first named
    std::vector<std::string> warnings;     // one line each, naming the file: what the load could not honour
    SourceFiles source;                    // the files read and their hash (load_scene only)
};

struct Scene {
    std::vector<Mesh> meshes;
    std::vector<Instance> instances;
    LoadReport report;
};

// Applies an affine column-major transform to a point.
inline std::array<double, 3> transform_point(const Transform& m, double x, double y, double z) {
    return {m[0] * x + m[4] * y + m[8] * z + m[12], m[1] * x + m[5] * y + m[9] * z + m[13],
            m[2] * x + m[6] * y + m[10] * z + m[14]};
}

// Returns a*b for column-major affine transforms.
Transform multiply(const Transform& a, const Transform& b);

// True when the triangle has a repeated index or its three positions are collinear (zero area, exactly).
bool is_degenerate(const Mesh& mesh, size_t triangle);

// How many of the mesh's triangles are degenerate, counted in parts on `threads` (0: all).
uint64_t count_degenerate(const Mesh& mesh, unsigned threads = 1);

}  // namespace cb
