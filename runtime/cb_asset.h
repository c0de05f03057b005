// clusterbake asset: layout constants and a validating read-only view. Header-only C++17, no
// dependencies, no exceptions, no allocation. MIT licensed (runtime/LICENSE). Spec: docs/FORMAT.md.
//
//   cb::AssetView view;
//   cb::AssetError e = cb::open_asset(bytes, size, &view);   // checks everything before any use
//   if (e != cb::AssetError::ok) { ... cb::asset_error_text(e) ... }
//
// Every offset, count and index is checked once in open_asset; afterwards the view's arrays may be
// indexed within the ranges its records state.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>

namespace cb {

constexpr char asset_magic[8] = {'C', 'L', 'B', 'A', 'K', 'E', '\r', '\n'};
constexpr uint32_t asset_version = 4;
constexpr uint32_t asset_alignment = 16;
constexpr uint32_t max_cluster_vertices = 256;  // a fine cluster's vertex list, addressed by 8-bit local indices

enum class SectionType : uint32_t {
    meshes = 1,           // MeshRecord per mesh
    positions = 2,        // float x, y, z per vertex, all meshes back to back; each mesh's in order of first use
    triangles = 3,        // uint8 x 3 per triangle: indices into its fine cluster's vertex list, in cluster order
    fine_clusters = 4,    // FineCluster per fine cluster
    coarse_clusters = 5,  // ClusterRange per coarse cluster: mesh-local fine cluster range
    instances = 6,        // InstanceRecord per instance
    // Bounds, each optional, one record per cluster of its level (see the volume structs below).
    fine_obbs = 7,
    coarse_obbs = 8,
    fine_spheres = 9,
    coarse_spheres = 10,
    fine_capsules = 11,
    coarse_capsules = 12,
    fine_cones = 13,  // need the same level's obbs: a cone's apexes sit on the line through its box centre
    coarse_cones = 14,
    fine_slabs = 15,
    coarse_slabs = 16,
    double_sided = 17,  // uint32 words: bit t of the whole triangle array set when triangle t is double-sided
    mesh_flags = 18,    // uint32 per mesh: MeshFlags
    vertex_refs = 19,   // uint16 per entry: fine clusters' reused vertices, as distances back from first_vertex
    source = 20,        // UTF-8 text: what the asset was made from (input hash, options, tool); not for queries
};

enum MeshFlags : uint32_t {
    mesh_closed = 1,            // every edge is shared by exactly two triangles, wound opposite ways
    mesh_has_double_sided = 2,  // some triangle is double-sided
};

// Bounding volumes as the runtime uses them, rounded outward: every vertex of the cluster is inside,
// evaluated in double against these floats. Boxes and cones are stored packed (PackedObb, PackedCone) and
// decoded by unpack_obb / unpack_cone; the fitter measures against the decoded values.
struct Obb {  // Inside: |dot(p - center, axis[i])| <= half[i], i = 0, 1, 2
    float center[3];
    float axis[3][3];  // right-handed, unit to float precision
    float half[3];
};

struct Sphere {  // 16 bytes. Inside: |p - center| <= radius
    float center[3];
    float radius;
};

struct Capsule {  // 28 bytes. Inside: distance(p, segment a-b) <= radius; a == b for a sphere
    float a[3], b[3];
    float radius;
};

// Normal cone with apex. When `valid`, a point p != front_apex with angle(p - front_apex, axis) below the
// half-angle is strictly on the front side of every triangle of the cluster that has an area, and a point
// e with angle(back_apex - e, axis) below it strictly on the back side. `valid` 0: never cull.
struct Cone {
    float front_apex[3];
    float back_apex[3];
    float axis[3];         // unit to float precision
    float cos_half_angle;  // rounded up (never wider than proven)
    float sin_half_angle;  // rounded down
    uint32_t valid;
};

// A box as stored: centre and half-extents as floats, the rotation as a unit quaternion in "smallest three"
// form (the largest component, made positive, is left out and recomputed).
struct PackedObb {  // 32 bytes
    float center[3];
    float half[3];
    int16_t rotation[3];  // the three other components, each times 32767 * sqrt(2)
    uint16_t largest;     // which component (0..3: x, y, z, w) was left out
};

// A cone as stored: its axis in octahedral form, its apexes as distances along the axis from the centre of
// the same cluster's box (so cones need boxes). cos_half_angle 2: no valid cone.
struct PackedCone {        // 16 bytes
    int16_t axis[2];       // octahedral, each times 32767
    float front, back;     // apex = box centre + front (back) * axis, computed in double, rounded to float
    float cos_half_angle;  // rounded up; the sine is derived and rounded down
};

struct Slab {  // 20 bytes. Inside: low <= dot(p, axis) <= high
    float axis[3];
    float low, high;
};

struct AssetHeader {  // 64 bytes at offset 0
    char magic[8];
    uint32_t version;
    uint32_t flags;        // none defined: must be 0
    uint32_t header_size;  // sizeof(AssetHeader)
    uint32_t section_count;
    uint64_t file_size;
    uint64_t checksum;     // asset_checksum: every byte of the file but these 8
    uint8_t reserved[24];  // zero
};

struct SectionEntry {       // 32 bytes each, right after the header
    uint32_t type;          // SectionType
    uint32_t element_size;  // bytes per element
    uint64_t offset;        // from the start of the file, a multiple of asset_alignment
    uint64_t size;          // bytes
    uint64_t count;         // elements: size == count * element_size
};

struct MeshRecord {                           // 40 bytes
    uint32_t first_vertex, vertex_count;      // into positions
    uint32_t first_triangle, triangle_count;  // into triangles
    uint32_t first_fine, fine_count;          // into fine_clusters
    uint32_t first_coarse, coarse_count;      // into coarse_clusters
    uint32_t first_ref, ref_count;            // into vertex_refs
};

// A fine cluster: a range of the mesh's triangles whose corners index the cluster's vertex list, which is
// its own new vertices (a range of the mesh's positions) followed by reused ones from earlier clusters (a
// range of vertex_refs, each entry the distance back from first_vertex, 1 to 65535; a vertex farther back
// is stored again as a new one). Each of the three ranges starts where the previous cluster's ended.
struct FineCluster {  // 16 bytes, all mesh-local
    uint32_t first_triangle;
    uint32_t first_vertex;
    uint32_t first_ref;
    uint8_t triangle_count;  // 1 or more
    uint8_t vertex_count;    // new vertices
    uint8_t ref_count;       // reused vertices; vertex_count + ref_count <= max_cluster_vertices
    uint8_t reserved;        // 0
};

struct ClusterRange {  // 8 bytes
    uint32_t first, count;
};

struct InstanceRecord {  // 112 bytes
    uint32_t mesh;
    uint32_t reserved;
    uint64_t reserved2;
    double transform[12];  // affine, column-major 3x4: columns x, y, z axes then translation
};

static_assert(sizeof(AssetHeader) == 64 && sizeof(SectionEntry) == 32 && sizeof(MeshRecord) == 40 &&
                  sizeof(FineCluster) == 16 && sizeof(ClusterRange) == 8 && sizeof(InstanceRecord) == 112 &&
                  sizeof(PackedObb) == 32 && sizeof(Sphere) == 16 && sizeof(Capsule) == 28 &&
                  sizeof(PackedCone) == 16 && sizeof(Slab) == 20,
              "asset records must have their documented sizes");

// ---- decoding boxes and cones. Deterministic double arithmetic rounded to float; the fitter measures
// its stored extents and apexes against these decoded values with a margin of a few float steps, so a
// compiler that contracts a multiply-add here differently still decodes a conservative volume.
//
// The decoders are always inlined: a program that builds the query for wider lanes (AVX2, AVX-512) beside
// its baseline code must not end up with one out-of-line copy of them compiled for the wider lanes, which
// the linker could keep for every caller (tests/check_portable.sh).
#if defined(__GNUC__)
#define CB_DECODE_INLINE inline __attribute__((always_inline))
#else
#define CB_DECODE_INLINE inline
#endif

CB_DECODE_INLINE Obb unpack_obb(const PackedObb& p) {
    double q[4], sum = 0;
    for (int i = 0, k = 0; i < 4; ++i) {
        if (i == int(p.largest & 3)) continue;
        q[i] = double(p.rotation[k++]) / (32767.0 * 1.4142135623730951);
        sum += q[i] * q[i];
    }
    q[p.largest & 3] = std::sqrt(sum < 1 ? 1 - sum : 0);
    double len = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    double x = q[0] / len, y = q[1] / len, z = q[2] / len, w = q[3] / len;
    // Columns of the rotation matrix: the box axes.
    const double axis[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)},
                               {2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)},
                               {2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)}};
    Obb b;
    for (int i = 0; i < 3; ++i) {
        b.center[i] = p.center[i];
        b.half[i] = p.half[i];
        for (int k = 0; k < 3; ++k) b.axis[i][k] = float(axis[i][k]);
    }
    return b;
}

// The stored box is {p : |dot(p - center, axis[i])| <= half[i]} for float axes that are unit and orthogonal
// only to float precision (about 1e-7), so its corners are not exactly center +- half[i] axis[i]. Half
// extents grown by 1e-6 of their sum give a box in the axes' own span that holds it: use them wherever the
// box is taken as center + sum of +-half[i] axis[i] (corners, support functions, nearest points).
inline void padded_halves(const Obb& b, double out[3]) {
    double pad = 1e-6 * (double(b.half[0]) + double(b.half[1]) + double(b.half[2]));
    for (int i = 0; i < 3; ++i) out[i] = double(b.half[i]) + pad;
}

// The unit axis of an octahedral pair.
CB_DECODE_INLINE void unpack_octahedral(const int16_t* e, double* out) {
    double x = double(e[0]) / 32767.0, y = double(e[1]) / 32767.0, z = 1 - std::fabs(x) - std::fabs(y);
    if (z < 0) {
        double fx = (1 - std::fabs(y)) * (x < 0 ? -1 : 1), fy = (1 - std::fabs(x)) * (y < 0 ? -1 : 1);
        x = fx;
        y = fy;
    }
    double len = std::sqrt(x * x + y * y + z * z);
    out[0] = x / len;
    out[1] = y / len;
    out[2] = z / len;
}

CB_DECODE_INLINE Cone unpack_cone(const PackedCone& p, const PackedObb& box) {
    Cone c{};
    if (!(p.cos_half_angle <= 1)) return c;  // stored 2: no valid cone
    double a[3];
    unpack_octahedral(p.axis, a);
    for (int k = 0; k < 3; ++k) {
        c.axis[k] = float(a[k]);
        c.front_apex[k] = float(double(box.center[k]) + double(p.front) * a[k]);
        c.back_apex[k] = float(double(box.center[k]) + double(p.back) * a[k]);
    }
    c.cos_half_angle = p.cos_half_angle;
    double cosine = p.cos_half_angle, sine = std::sqrt(cosine < 1 ? 1 - cosine * cosine : 0) * (1 - 1e-6);
    c.sin_half_angle = float(sine);
    if (double(c.sin_half_angle) > sine) c.sin_half_angle = std::nextafter(c.sin_half_angle, 0.0f);  // round down
    c.valid = 1;
    return c;
}

// Per level (fine or coarse): each pointer null when the asset has no such section. Boxes and cones are
// read through obb(i) and cone(i), which decode them.
struct LevelBounds {
    const PackedObb* obbs = nullptr;
    const Sphere* spheres = nullptr;
    const Capsule* capsules = nullptr;
    const PackedCone* cones = nullptr;  // only with obbs
    const Slab* slabs = nullptr;

    CB_DECODE_INLINE Obb obb(uint32_t i) const { return unpack_obb(obbs[i]); }
    CB_DECODE_INLINE Cone cone(uint32_t i) const { return unpack_cone(cones[i], obbs[i]); }
};

enum class AssetError {
    ok = 0,
    too_small,
    bad_magic,
    bad_version,
    bad_header,
    size_mismatch,
    bad_checksum,
    bad_section_table,
    misaligned_section,
    section_out_of_bounds,
    duplicate_section,
    missing_section,
    bad_element_size,
    bad_mesh_range,
    bad_cluster_range,
    bad_index,
    bad_instance,
    non_finite,
    bad_bounds_count,
    bad_packed_bounds,
};

inline const char* asset_error_text(AssetError e) {
    switch (e) {
        case AssetError::ok: return "ok";
        case AssetError::too_small: return "file too small for a header";
        case AssetError::bad_magic: return "not a clusterbake asset (bad magic)";
        case AssetError::bad_version: return "unsupported version";
        case AssetError::bad_header: return "malformed header";
        case AssetError::size_mismatch: return "file size differs from the header's (truncated?)";
        case AssetError::bad_checksum: return "checksum mismatch (corrupted)";
        case AssetError::bad_section_table: return "section table out of bounds";
        case AssetError::misaligned_section: return "section not 16-byte aligned";
        case AssetError::section_out_of_bounds: return "section past the end of the file";
        case AssetError::duplicate_section: return "section type appears twice";
        case AssetError::missing_section: return "required section missing";
        case AssetError::bad_element_size: return "section element size or count inconsistent";
        case AssetError::bad_mesh_range: return "mesh record range out of bounds";
        case AssetError::bad_cluster_range: return "cluster range out of bounds or not contiguous";
        case AssetError::bad_index: return "triangle or vertex reference out of range";
        case AssetError::bad_instance: return "instance names a missing mesh";
        case AssetError::non_finite: return "non-finite position, transform or bound";
        case AssetError::bad_bounds_count: return "a per-cluster, per-triangle or per-mesh section has the wrong count";
        case AssetError::bad_packed_bounds:
            return "packed box or cone malformed (negative extent, bad quaternion index or cone angle), or cones "
                   "without boxes";
    }
    return "unknown error";
}

// The asset's checksum, fed in pieces of any size (the writer sums the file as it streams it out). The bytes
// are read as little-endian 64-bit words in stripes of four, one word to each of four running lanes: four
// independent multiplies a stripe, where a hash of one byte at a time waits on a multiply per byte (about
// 6 GB/s against 0.3 GB/s, docs/PERFORMANCE.md). The last stripe is zero-padded; the byte count and the
// lanes are merged through splitmix64's finaliser. docs/FORMAT.md spells it out.
class AssetChecksum {
public:
    void add(const uint8_t* p, size_t n) {
        total_ += n;
        if (pending_ > 0) {
            const size_t take = n < 32 - pending_ ? n : 32 - pending_;
            for (size_t i = 0; i < take; ++i) stripe_[pending_ + i] = p[i];
            pending_ += take;
            p += take;
            n -= take;
            if (pending_ < 32) return;
            stripe(stripe_);
            pending_ = 0;
        }
        for (; n >= 32; p += 32, n -= 32) stripe(p);
        for (size_t i = 0; i < n; ++i) stripe_[i] = p[i];
        pending_ = n;
    }

    uint64_t finish() const {
        AssetChecksum last = *this;
        if (last.pending_ > 0) {
            for (size_t i = last.pending_; i < 32; ++i) last.stripe_[i] = 0;
            last.stripe(last.stripe_);
        }
        uint64_t h = mix(total_);
        for (int j = 0; j < 4; ++j) h = mix(h ^ last.lane_[j]) + uint64_t(j);
        return mix(h);
    }

private:
    static constexpr uint64_t step_a = 0x9e3779b97f4a7c15ULL, step_b = 0xbf58476d1ce4e5b9ULL,
                              step_c = 0x94d049bb133111ebULL;
    static uint64_t word(const uint8_t* p) {
        uint64_t w = 0;
        for (int k = 0; k < 8; ++k) w |= uint64_t(p[k]) << (8 * k);
        return w;
    }
    static uint64_t rotate(uint64_t x, int r) { return (x << r) | (x >> (64 - r)); }
    // splitmix64's finaliser: each output bit depends on every input bit.
    static uint64_t mix(uint64_t x) {
        x = (x ^ (x >> 30)) * step_b;
        x = (x ^ (x >> 27)) * step_c;
        return x ^ (x >> 31);
    }
    void stripe(const uint8_t* p) {
        for (int j = 0; j < 4; ++j) lane_[j] = rotate(lane_[j] + word(p + 8 * j) * step_b, 31) * step_a;
    }

    uint64_t lane_[4] = {step_a, step_b, step_c, 0};
    uint64_t total_ = 0;
    uint8_t stripe_[32] = {};
    size_t pending_ = 0;
};

// The asset's checksum (AssetChecksum) of every byte of the file but the checksum field's own 8, so that the
// header and the section table are covered as well as the sections.
inline uint64_t asset_checksum(const uint8_t* bytes, size_t size) {
    const size_t at = offsetof(AssetHeader, checksum);
    AssetChecksum sum;
    sum.add(bytes, at);
    sum.add(bytes + at + 8, size - at - 8);
    return sum.finish();
}

// Arrays point into the caller's bytes (which must stay alive and be 8-byte aligned for the doubles of
// InstanceRecord; a memory-mapped file or a new[]-ed buffer is).
struct AssetView {
    const MeshRecord* meshes = nullptr;
    uint32_t mesh_count = 0;
    const float* positions = nullptr;
    uint32_t vertex_count = 0;
    const uint8_t* triangles = nullptr;  // 3 local indices per triangle; read through triangle()
    uint32_t triangle_count = 0;
    const uint16_t* vertex_refs = nullptr;
    uint32_t ref_count = 0;
    const FineCluster* fine = nullptr;
    uint32_t fine_count = 0;
    const ClusterRange* coarse = nullptr;
    uint32_t coarse_count = 0;
    const InstanceRecord* instances = nullptr;
    uint32_t instance_count = 0;
    LevelBounds fine_bounds, coarse_bounds;
    const uint32_t* double_sided_bits = nullptr;  // null: every triangle single-sided
    const uint32_t* mesh_flags = nullptr;         // null: no flags known
    const char* source = nullptr;                 // the source section's text, not terminated; null: none
    uint32_t source_size = 0;

    bool double_sided(size_t triangle) const {
        return double_sided_bits && (double_sided_bits[triangle / 32] >> (triangle % 32) & 1);
    }
    // The mesh-local vertex indices of triangle `t` (mesh-local) of fine cluster `c` (mesh-local).
    void triangle(const MeshRecord& mesh, uint32_t c, uint32_t t, uint32_t out[3]) const {
        const FineCluster& f = fine[mesh.first_fine + c];
        const uint8_t* local = triangles + (size_t(mesh.first_triangle) + t) * 3;
        for (int k = 0; k < 3; ++k)
            out[k] = local[k] < f.vertex_count
                ? f.first_vertex + local[k]
                : f.first_vertex - vertex_refs[size_t(mesh.first_ref) + f.first_ref + local[k] - f.vertex_count];
    }
    // The position of mesh-local vertex `v`.
    const float* position(const MeshRecord& mesh, uint32_t v) const {
        return positions + (size_t(mesh.first_vertex) + v) * 3;
    }
};

namespace asset_detail {

inline bool range_ok(uint64_t first, uint64_t count, uint64_t limit) {
    return first <= limit && count <= limit - first;
}

template <class T>
bool all_finite(const T* records, uint32_t count) {  // every float of the records
    const uint8_t* bytes = reinterpret_cast<const uint8_t*>(records);
    for (size_t i = 0; i < size_t(count) * (sizeof(T) / 4); ++i) {
        float f;
        std::memcpy(&f, bytes + i * 4, 4);
        if (!std::isfinite(f)) return false;
    }
    return true;
}

// Ranges must tile [0, total) in order: each starts where the previous ended.
inline bool ranges_tile(const ClusterRange* r, uint32_t n, uint32_t total) {
    uint64_t at = 0;
    for (uint32_t i = 0; i < n; ++i) {
        if (r[i].first != at || r[i].count == 0) return false;
        at += r[i].count;
    }
    return at == total;
}

// Fine clusters tile the mesh's triangles (none empty), its vertices and its reused-vertex entries, and
// every local index names an entry of its cluster's vertex list.
inline bool fine_clusters_ok(const FineCluster* f, uint32_t n, const MeshRecord& m, const uint8_t* triangles,
                             const uint16_t* refs) {
    uint64_t t = 0, v = 0, r = 0;
    for (uint32_t i = 0; i < n; ++i) {
        if (f[i].first_triangle != t || f[i].first_vertex != v || f[i].first_ref != r || f[i].triangle_count == 0 ||
            f[i].reserved != 0 || uint32_t(f[i].vertex_count) + f[i].ref_count > max_cluster_vertices)
            return false;
        if (t + f[i].triangle_count > m.triangle_count) return false;
        const uint8_t* local = triangles + (size_t(m.first_triangle) + t) * 3;
        for (size_t k = 0; k < size_t(f[i].triangle_count) * 3; ++k)
            if (local[k] >= uint32_t(f[i].vertex_count) + f[i].ref_count) return false;
        if (r + f[i].ref_count > m.ref_count) return false;
        for (uint32_t k = 0; k < f[i].ref_count; ++k)  // back to an earlier vertex of the mesh
            if (refs[r + k] == 0 || refs[r + k] > f[i].first_vertex) return false;
        t += f[i].triangle_count;
        v += f[i].vertex_count;
        r += f[i].ref_count;
    }
    return t == m.triangle_count && v == m.vertex_count && r == m.ref_count;
}

}  // namespace asset_detail

inline AssetError open_asset(const void* bytes, size_t size, AssetView* out) {
    using namespace asset_detail;
    const uint8_t* base = static_cast<const uint8_t*>(bytes);
    if (!bytes || size < sizeof(AssetHeader)) return AssetError::too_small;
    AssetHeader h;
    std::memcpy(&h, base, sizeof h);
    if (std::memcmp(h.magic, asset_magic, 8) != 0) return AssetError::bad_magic;
    if (h.version != asset_version) return AssetError::bad_version;
    if (h.header_size != sizeof(AssetHeader) || h.flags != 0) return AssetError::bad_header;
    for (uint8_t r : h.reserved)
        if (r != 0) return AssetError::bad_header;
    if (h.file_size != size) return AssetError::size_mismatch;
    if (h.section_count > 64 || sizeof(AssetHeader) + uint64_t(h.section_count) * sizeof(SectionEntry) > size)
        return AssetError::bad_section_table;
    if (asset_checksum(base, size) != h.checksum) return AssetError::bad_checksum;

    struct Known {
        SectionType type;
        uint32_t element_size;
        bool required;
        const void** data;
        uint32_t* count;
    };
    AssetView v;
    constexpr int known_count = 20;
    const void* ptr[known_count] = {};
    uint32_t bound_count[10] = {}, extra_count[2] = {};
    Known known[known_count] = {
        {SectionType::meshes, sizeof(MeshRecord), true, &ptr[0], &v.mesh_count},
        {SectionType::positions, 12, true, &ptr[1], &v.vertex_count},
        {SectionType::triangles, 3, true, &ptr[2], &v.triangle_count},
        {SectionType::fine_clusters, sizeof(FineCluster), true, &ptr[3], &v.fine_count},
        {SectionType::coarse_clusters, sizeof(ClusterRange), true, &ptr[4], &v.coarse_count},
        {SectionType::instances, sizeof(InstanceRecord), true, &ptr[5], &v.instance_count},
        {SectionType::fine_obbs, sizeof(PackedObb), false, &ptr[6], &bound_count[0]},
        {SectionType::coarse_obbs, sizeof(PackedObb), false, &ptr[7], &bound_count[1]},
        {SectionType::fine_spheres, sizeof(Sphere), false, &ptr[8], &bound_count[2]},
        {SectionType::coarse_spheres, sizeof(Sphere), false, &ptr[9], &bound_count[3]},
        {SectionType::fine_capsules, sizeof(Capsule), false, &ptr[10], &bound_count[4]},
        {SectionType::coarse_capsules, sizeof(Capsule), false, &ptr[11], &bound_count[5]},
        {SectionType::fine_cones, sizeof(PackedCone), false, &ptr[12], &bound_count[6]},
        {SectionType::coarse_cones, sizeof(PackedCone), false, &ptr[13], &bound_count[7]},
        {SectionType::fine_slabs, sizeof(Slab), false, &ptr[14], &bound_count[8]},
        {SectionType::coarse_slabs, sizeof(Slab), false, &ptr[15], &bound_count[9]},
        {SectionType::double_sided, 4, false, &ptr[16], &extra_count[0]},
        {SectionType::mesh_flags, 4, false, &ptr[17], &extra_count[1]},
        {SectionType::vertex_refs, 2, true, &ptr[18], &v.ref_count},
        {SectionType::source, 1, false, &ptr[19], &v.source_size},
    };
    bool seen[known_count] = {};
    for (uint32_t s = 0; s < h.section_count; ++s) {
        SectionEntry e;
        std::memcpy(&e, base + sizeof(AssetHeader) + size_t(s) * sizeof(SectionEntry), sizeof e);
        if (e.offset % asset_alignment != 0) return AssetError::misaligned_section;
        if (!range_ok(e.offset, e.size, size)) return AssetError::section_out_of_bounds;
        for (int k = 0; k < known_count; ++k) {
            if (e.type != uint32_t(known[k].type)) continue;  // unknown types are skipped: newer, optional data
            if (seen[k]) return AssetError::duplicate_section;
            seen[k] = true;
            if (e.element_size != known[k].element_size || e.count > UINT32_MAX ||
                e.size != e.count * uint64_t(e.element_size))
                return AssetError::bad_element_size;
            *known[k].data = base + e.offset;
            *known[k].count = uint32_t(e.count);
        }
    }
    for (int k = 0; k < known_count; ++k)
        if (known[k].required && !seen[k]) return AssetError::missing_section;
    if (seen[16] && extra_count[0] != (uint64_t(v.triangle_count) + 31) / 32) return AssetError::bad_bounds_count;
    if (seen[17] && extra_count[1] != v.mesh_count) return AssetError::bad_bounds_count;
    v.double_sided_bits = static_cast<const uint32_t*>(ptr[16]);
    v.mesh_flags = static_cast<const uint32_t*>(ptr[17]);
    // A bounds section holds one record per cluster of its level.
    for (int b = 0; b < 10; ++b)
        if (seen[6 + b] && bound_count[b] != (b % 2 == 0 ? v.fine_count : v.coarse_count))
            return AssetError::bad_bounds_count;
    v.meshes = static_cast<const MeshRecord*>(ptr[0]);
    v.positions = static_cast<const float*>(ptr[1]);
    v.triangles = static_cast<const uint8_t*>(ptr[2]);
    v.fine = static_cast<const FineCluster*>(ptr[3]);
    v.coarse = static_cast<const ClusterRange*>(ptr[4]);
    v.instances = static_cast<const InstanceRecord*>(ptr[5]);
    v.vertex_refs = static_cast<const uint16_t*>(ptr[18]);
    v.source = static_cast<const char*>(ptr[19]);
    LevelBounds* level[2] = {&v.fine_bounds, &v.coarse_bounds};
    for (int l = 0; l < 2; ++l) {
        level[l]->obbs = static_cast<const PackedObb*>(ptr[6 + l]);
        level[l]->spheres = static_cast<const Sphere*>(ptr[8 + l]);
        level[l]->capsules = static_cast<const Capsule*>(ptr[10 + l]);
        level[l]->cones = static_cast<const PackedCone*>(ptr[12 + l]);
        level[l]->slabs = static_cast<const Slab*>(ptr[14 + l]);
        uint32_t n = l == 0 ? v.fine_count : v.coarse_count;
        if (!all_finite(level[l]->spheres, level[l]->spheres ? n : 0) ||
            !all_finite(level[l]->capsules, level[l]->capsules ? n : 0) ||
            !all_finite(level[l]->slabs, level[l]->slabs ? n : 0))
            return AssetError::non_finite;
        if (level[l]->cones && !level[l]->obbs) return AssetError::bad_packed_bounds;
        for (uint32_t i = 0; level[l]->obbs && i < n; ++i) {
            const PackedObb& b = level[l]->obbs[i];
            for (int k = 0; k < 3; ++k)
                if (!std::isfinite(b.center[k]) || !std::isfinite(b.half[k])) return AssetError::non_finite;
            if (b.largest > 3 || !(b.half[0] >= 0 && b.half[1] >= 0 && b.half[2] >= 0))
                return AssetError::bad_packed_bounds;
        }
        for (uint32_t i = 0; level[l]->cones && i < n; ++i) {
            const PackedCone& c = level[l]->cones[i];
            if (!(c.cos_half_angle <= 1 || c.cos_half_angle == 2)) return AssetError::bad_packed_bounds;
            if (c.cos_half_angle <= 1 && (!std::isfinite(c.front) || !std::isfinite(c.back)))
                return AssetError::non_finite;
        }
    }

    for (size_t i = 0; i < size_t(v.vertex_count) * 3; ++i)
        if (!std::isfinite(v.positions[i])) return AssetError::non_finite;
    for (uint32_t m = 0; m < v.mesh_count; ++m) {
        const MeshRecord& r = v.meshes[m];
        if (!range_ok(r.first_vertex, r.vertex_count, v.vertex_count) ||
            !range_ok(r.first_triangle, r.triangle_count, v.triangle_count) ||
            !range_ok(r.first_fine, r.fine_count, v.fine_count) ||
            !range_ok(r.first_coarse, r.coarse_count, v.coarse_count) ||
            !range_ok(r.first_ref, r.ref_count, v.ref_count))
            return AssetError::bad_mesh_range;
        // Fine clusters tile the mesh's triangles, vertices and reused entries; coarse clusters tile its
        // fine clusters.
        if (!fine_clusters_ok(v.fine + r.first_fine, r.fine_count, r, v.triangles, v.vertex_refs + r.first_ref) ||
            !ranges_tile(v.coarse + r.first_coarse, r.coarse_count, r.fine_count))
            return AssetError::bad_cluster_range;
    }
    for (uint32_t i = 0; i < v.instance_count; ++i) {
        if (v.instances[i].mesh >= v.mesh_count) return AssetError::bad_instance;
        for (double d : v.instances[i].transform)
            if (!std::isfinite(d)) return AssetError::non_finite;
    }
    *out = v;
    return AssetError::ok;
}

}  // namespace cb
