// What every point light's traversal (cb_scan.h, cb_top_tree.h, cb_metric_tree.h) shares: the build options, the
// instance's frame (the mesh, the inverse of its transform, the light in the mesh's frame), the tile of points a
// batch query takes at once (their directions from the light in float, and a pyramid from the light that holds
// them), the float box filters, the tile's walk (walk_tile: the entered coarse clusters, then the pending fine
// ones, nearest first; a traversal gives only its searches) and the steps that test the clusters it finds (a
// cluster's triangles, cb_lit_triangles.h). A traversal is one more class on TraversalBase with the same small
// interface (build, occluded, occluded_tile, stack_size, node_count, memory_bytes, always_tested); no call is
// virtual. Header-only C++17, no exceptions, no allocation in queries. MIT licensed (runtime/LICENSE).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "../cb_asset.h"
#include "cb_lit_triangles.h"
#include "cb_math.h"
#include "../cb_segment.h"
#include "cb_simd.h"

namespace cb {

// How a query finds the fine clusters whose triangles it tests: one traversal type each. Outside the lanes'
// namespace (cb_simd.h), as cb::QueryStats is: code built for different lanes shares these two.
enum class Traversal : uint8_t {
    scan,      // no tree (ScanTraversal): the coarse clusters' bounding spheres are scanned against a tile's
               // pyramid, then each entered one's fine spheres against the pyramid of its points (the default:
               // the only per-light work is setting up the coarse boxes)
    top_two,   // TopTreeTraversal: a TOP tree over the coarse clusters whose cluster nodes enter a tree over
               // that coarse cluster's fine clusters (the thesis's two levels)
    top_one,   // TopTreeTraversal: one TOP tree over all the fine clusters
    mtsv_one,  // MetricTreeTraversal: one metric tree over the fine clusters' sphere and capsule cones
    mtsv_two,  // MetricTreeTraversal: a metric tree over the coarse clusters' cones whose nodes enter a tree
               // over their fine clusters'
};

// How MetricTreeTraversal (cb_metric_tree.h) chooses pivots and split distances.
enum class MetricBuild : uint8_t {
    heuristic,  // the thesis's: shuffled insertion, delta halved on each near step (the default)
    reference,  // pivots far from the others, median split distance (to measure the heuristic's trees)
};

inline namespace CB_LANES {

struct ScanBounds;    // cb_scan_bounds.h
struct BuildScratch;  // cb_top_tree.h

// The settings of a traversal's build (InstanceShadow::build).
struct ShadowBuildOptions {
    // Without coarse boxes in the asset, every traversal is one tree.
    Traversal traversal = Traversal::scan;
    // One-sided occluders (cb_segment.h): clusters whose front cone holds the light, and that have no
    // double-sided triangle, cannot block anything and are left out.
    bool one_sided = false;
    // The self-shadowing bias, a world-space distance (cb_segment.h): contacts nearer to the point do not
    // count. Zero or less: the scene's default, the Level's shadow_bias() through a LevelShadow, and
    // default_shadow_bias of the asset's world size (asset_world_size, a pass over its vertices) when an
    // InstanceShadow is built on its own; give it to build many.
    double bias = 0;
    // Traversal::scan: the asset's ScanBounds, indexed by mesh (make_scan_bounds), read by every query and so
    // kept alive and unchanged while the traversal is used. Without them, or when they were made from
    // another asset view, the scan makes its mesh's own at each build (a pass over its boxes).
    const ScanBounds* bounds = nullptr;
    // The trees' working arrays, kept between builds (one per concurrent build): a tree rebuilt every frame
    // then reuses memory instead of asking the system for fresh pages. The traversal's own arrays are reused
    // the same way when its object is.
    BuildScratch* scratch = nullptr;
    // Traversal::mtsv_one and mtsv_two: a cluster's volume is its capsule when that is at least this many times
    // as long (caps included) as it is wide, else its sphere; and how the metric trees are built. A capsule-cone
    // costs more to walk than a cone and, on compact clusters, prunes no better (docs/RUNTIME.md): only
    // clearly elongated clusters get one by default.
    double capsule_aspect = 4.0;
    MetricBuild metric_build = MetricBuild::heuristic;
};

// Points a batch query walks together (cb::occluded_batch): with close directions from the light, one
// walk with the pyramid that holds them all stands for a walk per point.
constexpr uint32_t tile_capacity = 64;
static_assert(tile_capacity == 64, "a tile's points are the bits of a uint64_t");

// The bits of a tile's first `count` points (count <= tile_capacity).
inline uint64_t tile_lanes(uint32_t count) { return count == 64 ? ~uint64_t(0) : (uint64_t(1) << count) - 1; }

// A box set up for one light's float separating-axis test (TraversalBase::box_filter).
struct BoxFilter {
    float lo[3], hi[3], hf[3], w[3][3], ax[3][3], tol;
    bool usable;  // false where float could overflow: the points are then tested in double
};

// Sizes (distances, coordinates from the light) below which the float filters cannot overflow: their largest
// terms are products of four such sizes.
constexpr double float_safe = 1e9;
// And sizes above which their margins stay far above the absolute rounding of results that fall to float's
// subnormals (1e-45): points nearer the light walk alone (in double), boxes and spheres that lie wholly within
// this of it are not filtered in float.
constexpr double float_tiny = 1e-7;

// A box set up for box_lanes: centre c from the light, half extents h (padded for the box's own rounding) and
// unit axes a (rows), in double; not usable where float could overflow or fall to subnormals.
inline BoxFilter make_box_filter(const double* c, const double* h, const double (*a)[3]) {
    BoxFilter b{};
    const double hs = h[0] + h[1] + h[2], c1 = std::fabs(c[0]) + std::fabs(c[1]) + std::fabs(c[2]);
    b.usable = c1 + hs < float_safe && c1 + hs > float_tiny;
    if (!b.usable) return b;
    for (int k = 0; k < 3; ++k) {
        double qk = math::dot3(c, a[k]), reach = h[k] + 1e-6 * (hs + c1);
        b.lo[k] = float(qk - reach);
        b.hi[k] = float(qk + reach);
        b.hf[k] = float(h[k]);
        double wk[3];
        math::cross3(a[k], c, wk);
        for (int j = 0; j < 3; ++j) {
            b.w[k][j] = float(wk[j]);
            b.ax[k][j] = float(a[k][j]);
        }
    }
    b.tol = float(2e-6 * (hs + c1));
    return b;
}

// The points of `subset` whose segment to the light may touch the box of `b` (usable) where a contact could
// block (from the light to blocking_start of each point's `from`, cb_segment.h: `reach` = 1 - that, in float;
// 1 takes the whole segment): separating axis tests in float over the subset's lanes (e, the points' offsets
// from the light, and fd, their distances), on the box's 3 axes and on the segment's direction crossed with each.
inline uint64_t box_lanes(const BoxFilter& b, uint64_t subset, const float* ex, const float* ey, const float* ez,
                          const float* fd, const float* reach) {
    const float(&lo)[3] = b.lo, (&hi)[3] = b.hi, (&hf)[3] = b.hf, (&w)[3][3] = b.w, (&ax)[3][3] = b.ax;
    const float tol = b.tol;
    uint32_t begin, end;
    simd::lane_span(subset, begin, end);
    uint64_t keep = 0;
    // Per lane, the smallest margin of the 9 checks (>= 0: no separating axis): on box axis k, the segment's
    // shadow [min(0, s g), max(0, s g)] (s = reach, the blocking part) must meet [lo, hi]; on e x axis k,
    // where the segment projects to 0, the box's centre projects to e . (axis k x c) = e . w[k], and its
    // support is hf[j] |g[m]| + hf[m] |g[j]|. The slack (1e-6 of the distance) holds s's rounding.
    using simd::Floats;
    const Floats zero = simd::splat(0.0f), micro = simd::splat(1e-6f), vtol = simd::splat(tol);
    for (uint32_t i = begin; i < end; i += simd::width) {
        if (!simd::group(subset, i)) continue;  // no point in these lanes (the subset is often sparse)
        const Floats x = simd::load(ex + i), y = simd::load(ey + i), z = simd::load(ez + i), d = simd::load(fd + i),
                     s = simd::load(reach + i);
        const Floats slack = micro * d;
        const Floats g[3] = {simd::dot(x, y, z, ax[0][0], ax[0][1], ax[0][2]),
                             simd::dot(x, y, z, ax[1][0], ax[1][1], ax[1][2]),
                             simd::dot(x, y, z, ax[2][0], ax[2][1], ax[2][2])};
        Floats m = simd::splat(INFINITY);
        for (int k = 0; k < 3; ++k) {
            const Floats gk = g[k] * s;
            m = simd::min(m, (simd::splat(hi[k]) + slack) - simd::min(gk, zero));
            m = simd::min(m, (simd::max(gk, zero) + slack) - simd::splat(lo[k]));
        }
        const Floats a[3] = {simd::abs(g[0]), simd::abs(g[1]), simd::abs(g[2])};
        const Floats td = vtol * d;
        for (int k = 0; k < 3; ++k) {
            const int j = (k + 1) % 3, n = (k + 2) % 3;
            const Floats support = simd::fma(simd::splat(hf[j]), a[n], simd::fma(simd::splat(hf[n]), a[j], td));
            m = simd::min(m, support - simd::abs(simd::dot(x, y, z, w[k][0], w[k][1], w[k][2])));
        }
        keep |= uint64_t(simd::bits(m >= zero)) << i;
    }
    return subset & keep;
}

// A box set up for one sun's float separating-axis test (SunTraversal::box_points): its centre from the
// scan bounds' origin, its axes, each axis's padded half extent (infinite where the ray runs nearly across
// it: no test there) with the side the ray heads to (sign) and how far along the axis it has gone at
// blocking_start (lift), and the axes z x a_k (z the sun's direction) with the box's support on them.
struct SunBox {
    float c[3], a[3][3], h[3], sign[3], lift[3], w[3][3], support[3], scale;
};

// What one thread's batch keeps from tile to tile (neighbouring tiles meet many of the same fine
// clusters): lit triangle groups and box set-ups, each under its traversal's name. clear() before the
// traversals change.
struct TileCache {
    lit::Cache lit;
    static constexpr uint32_t box_slots = 256;
    const void* box_owner[box_slots];
    uint32_t box_cluster[box_slots];
    BoxFilter box[box_slots];
    SunBox sun_box[box_slots];  // for a sun's traversal (an owner is of one kind)
    // Fine cluster f's slot for `owner` (each owner's run of slots starts at a place of its own, as lit's).
    static uint32_t box_slot(const void* owner, uint32_t f) { return (lit::owner_salt(owner) + f) % box_slots; }
    void clear() {
        lit.clear();
        for (const void*& o : box_owner) o = nullptr;
    }
};

// Indices [first, first + count) of some list.
struct IndexRange {
    uint32_t first = 0, count = 0;
};

// 0 .. n - 1 into `order`, shuffled the same way for every build (xorshift with a fixed seed): the trees insert
// their volumes in this order, which keeps them balanced whatever order the bake left the clusters in.
inline void insertion_order(uint32_t n, std::vector<uint32_t>& order) {
    order.resize(n);
    for (uint32_t i = 0; i < n; ++i) order[i] = i;
    uint64_t state = 0x9e3779b97f4a7c15ULL;
    for (uint32_t i = n; i > 1; --i) {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        std::swap(order[i - 1], order[state % i]);
    }
}

// The triangles of coarse cluster c of a mesh: its fine clusters' triangles follow one another.
inline IndexRange coarse_triangle_range(const AssetView& v, const MeshRecord& mesh, uint32_t c) {
    const ClusterRange& r = v.coarse[mesh.first_coarse + c];
    const FineCluster& a = v.fine[mesh.first_fine + r.first];
    const FineCluster& z = v.fine[mesh.first_fine + r.first + r.count - 1];
    return {a.first_triangle, z.first_triangle + z.triangle_count - a.first_triangle};
}

// No triangle of the range is double-sided: a light that sees them all from the front cannot be blocked by
// them one-sided.
inline bool all_single_sided(const AssetView& v, const MeshRecord& mesh, IndexRange triangles) {
    for (uint32_t t = triangles.first; t < triangles.first + triangles.count; ++t)
        if (v.double_sided(size_t(mesh.first_triangle) + t)) return false;
    return true;
}

// A frame about the direction m (its length does not matter): frame[0] the unit z along m, frame[1] and
// frame[2] unit axes across it (z x the coordinate axis m leans along least, then z x that). False when m
// has no length (or is not finite). Tiles of points (TraversalBase) and a level's tiles (cb_level.h) take
// their pyramids in such frames.
inline bool direction_frame(const double* m, double (*frame)[3]) {
    double ml = std::sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
    if (!(ml > 0)) return false;
    double *z = frame[0], *a = frame[1], *b = frame[2];
    for (int k = 0; k < 3; ++k) z[k] = m[k] / ml;
    int k0 = std::fabs(z[0]) < std::fabs(z[1]) ? (std::fabs(z[0]) < std::fabs(z[2]) ? 0 : 2)
                                               : (std::fabs(z[1]) < std::fabs(z[2]) ? 1 : 2);
    double axis[3] = {0, 0, 0};
    axis[k0] = 1;
    math::cross3(z, axis, a);
    double al = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    for (int k = 0; k < 3; ++k) a[k] /= al;
    math::cross3(z, a, b);
    return true;
}

// The ray z + x a + y b of a direction_frame: through (x, y) on the plane across z at distance 1.
inline void frame_ray(const double (*frame)[3], double x, double y, double* ray) {
    for (int k = 0; k < 3; ++k) ray[k] = frame[0][k] + x * frame[1][k] + y * frame[2][k];
}

// The points of `subset` (lanes of ex, ey, ez: their directions from the light, fd: their distances, in
// float) whose segment to the light may meet the sphere of centre (x, y, z) from the light and radius r: the
// ray from the light passes within the radius (|c x e| <= r |e|) and the sphere is not wholly behind the light
// or beyond the point. Float, branch-free; the radius must hold the float errors (ScanTraversal::lit_sphere).
inline uint64_t lit_sphere_points(float x, float y, float z, float r, uint64_t subset, const float* ex, const float* ey,
                                  const float* ez, const float* fd) {
    uint32_t begin, end;
    simd::lane_span(subset, begin, end);
    using simd::Floats;
    const Floats vx = simd::splat(x), vy = simd::splat(y), vz = simd::splat(z), vr = simd::splat(r),
                 r2 = simd::splat(r * r), zero = simd::splat(0.0f);
    uint64_t keep = 0;
    for (uint32_t i = begin; i < end; i += simd::width) {
        if (!simd::group(subset, i)) continue;
        const Floats px = simd::load(ex + i), py = simd::load(ey + i), pz = simd::load(ez + i), d = simd::load(fd + i);
        const Floats a = simd::fms(vy, pz, vz * py), b = simd::fms(vz, px, vx * pz), c = simd::fms(vx, py, vy * px);
        const Floats along = simd::dot(px, py, pz, vx, vy, vz), cross2 = simd::dot(a, b, c, a, b, c);
        Floats m = simd::fms(r2 * d, d, cross2);
        m = simd::min(m, simd::fma(vr, d, along));
        m = simd::min(m, simd::fms(d + vr, d, along));
        keep |= uint64_t(simd::bits(m >= zero)) << i;
    }
    return keep & subset;
}

// The points of `subset` (lanes of u, v, w: their coordinates in a sun's frame, across the direction and up
// along it toward the sun, from some centre, in float) whose ray toward the sun may meet the sphere of centre
// (cu, cv, cw) from that centre and radius r: the ray passes within the radius across the direction, and the
// sphere reaches above the point. The radius is grown by `slack`, which must be at least 1e-6 of every
// |coordinate|_1 involved, the sphere's and the points': the float coordinates err by 6e-8 of those, the
// distance across by under 3e-7, its square by a few float epsilons more than the radius's (which a factor
// 1 + 1e-6 holds). Every size below 1e18 and slack above 1e-15, so that the squares neither overflow nor fall
// to subnormals.
inline uint64_t sun_sphere_points(double cu, double cv, double cw, double r, double slack, uint64_t subset,
                                  const float* u, const float* v, const float* w) {
    if (!subset) return 0;
    using simd::Floats;
    const float grown = math::round_up((r + slack) * (1 + 1e-6));
    const Floats su = simd::splat(float(cu)), sv = simd::splat(float(cv)), r2 = simd::splat(grown * grown),
                 top = simd::splat(math::round_up(cw + r + slack));
    uint32_t begin, end;
    simd::lane_span(subset, begin, end);
    uint64_t keep = 0;
    for (uint32_t i = begin; i < end; i += simd::width) {
        if (!simd::group(subset, i)) continue;
        const Floats du = su - simd::load(u + i), dv = sv - simd::load(v + i);
        keep |= uint64_t(simd::bits((simd::fma(du, du, dv * dv) <= r2) & (simd::load(w + i) <= top))) << i;
    }
    return keep & subset;
}

// The state and the steps every traversal shares, for one instance and one light.
class TraversalBase {
public:
    static constexpr uint32_t none = 0xffffffffu;

    const double* world_light() const { return world_light_; }
    bool sun() const { return false; }                    // a point light (cb_sun.h answers suns)
    size_t skipped_clusters() const { return skipped_; }  // one-sided: fine clusters the light sees from the front
    size_t capsules() const { return capsules_; }         // volumes taken as capsule-cones (metric trees)

protected:
    struct Query {
        double p[3], e[3], dist, from;  // from: where contacts start to count (shadow_from, in world space)
        QueryStats* stats;
        const Obb* fine_obbs;  // the fine boxes decoded (ScanBounds), or null: from the asset
    };

    // A pyramid from the light that holds the directions of some points, and their distances to the light.
    struct Pyramid {
        alignas(16) float rx[4], ry[4], rz[4];  // unit edge rays (in float): every direction is a positive mix of them
        double dmax;
    };

    // A tile's points in the mesh's frame, and the pyramid from the light that holds their directions.
    struct Tile {
        uint32_t count;
        uint64_t alive;  // in the pyramid and not yet found in shadow
        uint64_t shadowed;
        bool small;  // every live point within float_safe of the light: the float filters apply
        double p[tile_capacity][3], dist[tile_capacity];
        alignas(64) double e[3][tile_capacity];  // p - light, by coordinate
        double from[tile_capacity];              // where each point's contacts start to count (shadow_from)
        uint64_t close;                          // from < 1e-6: a light more than a million biases away
        alignas(64) float keep[tile_capacity];   // 1 - from, in float (the triangles' plane test)
        alignas(64) float reach[tile_capacity];  // 1 - blocking_start(from), in float (box_points)
        alignas(64) float ex[tile_capacity], ey[tile_capacity], ez[tile_capacity],
            fd[tile_capacity];                   // e and dist in float
        alignas(64) float slack[tile_capacity];  // the plane checks' tolerance, 2e-6 of the distance
        alignas(64) float vl[tile_capacity];  // |e|_1 (l1) and a float just above it, for the triangle tests (TileView)
        double l1[tile_capacity], l1_lo, l1_hi;
        double frame[3][3];               // the mean direction from the light and two axes across it (make_frame)
        double across[2][tile_capacity];  // each point's central projection in that frame (x, then y)
        Pyramid pyramid;                  // holds the points walking now
        // Fine clusters met by the walk and the points inside their volumes, tested nearest to the light
        // first once the whole walk is done (or the list is full): a point in shadow then usually meets
        // its blocker before the cluster it lies on, and is not tested against that one (blockers often lie
        // in another coarse cluster, so the list waits for the whole walk).
        struct Pending {
            float near;
            uint32_t cluster;
            uint64_t points;
        };
        static constexpr uint32_t pending_capacity = 128;
        Pending pending[pending_capacity];
        uint32_t pending_count;
        // Coarse clusters entered, likewise: their fine clusters are found nearest first, each one's tested
        // before the next, so that farther ones leave out the points already found in shadow.
        struct Entered {
            float near;
            uint32_t id;  // its cluster node (trees), or the coarse cluster (scan)
            uint64_t points;
        };
        static constexpr uint32_t entered_capacity = 64;
        Entered entered[entered_capacity];
        uint32_t entered_count;
        QueryStats* stats;
        TileCache* cache;      // kept between tiles (may be null)
        const Obb* fine_obbs;  // the fine boxes decoded (ScanBounds), or null: from the asset
    };

    // The tile's frame: the mean direction z from the light of the points `which` (their offsets ex, ey, ez
    // from the light, in lanes) and two unit axes across it, and each point's central projection onto the
    // plane across z at distance 1. Returns the points it holds: all but those over 60 degrees off the mean.
    static uint64_t make_frame(Tile& t, uint64_t which, const double* ex, const double* ey, const double* ez) {
        using simd::Doubles;
        const Doubles zero = simd::dsplat(0), one = simd::dsplat(1);
        Doubles sum[3] = {zero, zero, zero};
        for (uint32_t i = 0; i < tile_capacity; i += simd::dwidth) {
            const uint32_t group = simd::double_group(which, i);
            if (!group) continue;
            const simd::DoubleMask in = simd::double_lanes(group);
            const Doubles inv = one / simd::load(t.dist + i);
            sum[0] = sum[0] + simd::select(in, simd::load(ex + i) * inv, zero);
            sum[1] = sum[1] + simd::select(in, simd::load(ey + i) * inv, zero);
            sum[2] = sum[2] + simd::select(in, simd::load(ez + i) * inv, zero);
        }
        const double m[3] = {simd::lane_sum(sum[0]), simd::lane_sum(sum[1]), simd::lane_sum(sum[2])};
        if (!direction_frame(m, t.frame)) return 0;
        const double *z = t.frame[0], *a = t.frame[1], *b = t.frame[2];
        uint64_t held = 0;
        for (uint32_t i = 0; i < tile_capacity; i += simd::dwidth) {
            if (!simd::double_group(which, i)) continue;
            const Doubles x = simd::load(ex + i), y = simd::load(ey + i), w = simd::load(ez + i);
            const Doubles depth = x * simd::dsplat(z[0]) + y * simd::dsplat(z[1]) + w * simd::dsplat(z[2]);
            const Doubles inv = one / depth;
            simd::store(t.across[0] + i,
                        (x * simd::dsplat(a[0]) + y * simd::dsplat(a[1]) + w * simd::dsplat(a[2])) * inv);
            simd::store(t.across[1] + i,
                        (x * simd::dsplat(b[0]) + y * simd::dsplat(b[1]) + w * simd::dsplat(b[2])) * inv);
            // over 60 degrees off: walks alone
            held |= uint64_t(simd::bits(depth > simd::dsplat(0.5) * simd::load(t.dist + i))) << i;
        }
        return held & which;
    }

    // The pyramid from the light through the rectangle in the tile's frame that bounds the projections of
    // the points `which` (held by the frame).
    static void make_pyramid(const Tile& t, uint64_t which, Pyramid& out) {
        using simd::Doubles;
        const Doubles inf = simd::dsplat(INFINITY), ninf = simd::dsplat(-INFINITY), zero = simd::dsplat(0);
        Doubles lo0 = inf, lo1 = inf, hi0 = ninf, hi1 = ninf, far = zero;
        for (uint32_t i = 0; i < tile_capacity; i += simd::dwidth) {
            const uint32_t group = simd::double_group(which, i);
            if (!group) continue;
            const simd::DoubleMask in = simd::double_lanes(group);
            const Doubles x = simd::load(t.across[0] + i), y = simd::load(t.across[1] + i);
            lo0 = simd::min(lo0, simd::select(in, x, inf));
            hi0 = simd::max(hi0, simd::select(in, x, ninf));
            lo1 = simd::min(lo1, simd::select(in, y, inf));
            hi1 = simd::max(hi1, simd::select(in, y, ninf));
            far = simd::max(far, simd::select(in, simd::load(t.dist + i), zero));
        }
        double lo[2] = {simd::lane_min(lo0), simd::lane_min(lo1)}, hi[2] = {simd::lane_max(hi0), simd::lane_max(hi1)};
        out.dmax = simd::lane_max(far);
        // Widened far beyond the rounding of x and y (a few 1e-16 for |x|, |y| below 2) and of the rays to
        // float (below 1e-7): the float rays still hold every point's direction.
        for (int k = 0; k < 2; ++k) {
            lo[k] -= 1e-6;
            hi[k] += 1e-6;
        }
        const double corner[4][2] = {{lo[0], lo[1]}, {hi[0], lo[1]}, {hi[0], hi[1]}, {lo[0], hi[1]}};
        for (int r = 0; r < 4; ++r) {
            double ray[3];
            frame_ray(t.frame, corner[r][0], corner[r][1], ray);
            const double l = std::sqrt(ray[0] * ray[0] + ray[1] * ray[1] + ray[2] * ray[2]);
            out.rx[r] = float(ray[0] / l);
            out.ry[r] = float(ray[1] / l);
            out.rz[r] = float(ray[2] / l);
        }
    }

    // Refits the tile's pyramid to the points `in` when they are not all its live points (narrower, so fewer
    // fine volumes or spheres meet it); returns the tile's pyramid, to be put back.
    static Pyramid narrow_pyramid(Tile& t, uint64_t in) {
        const Pyramid whole = t.pyramid;
        if (in != t.alive) make_pyramid(t, in, t.pyramid);
        return whole;
    }

    // Sorts by closing distance, ties in list order: each entry goes straight to its rank, the entries before
    // it in that order counted by instructions that each compare a whole vector of keys (no branch on the keys:
    // an insertion sort mispredicted one per entry). NaN counts as infinity.
    template <class T>
    static void sort_by_near(T* a, uint32_t count) {
        constexpr uint32_t most = 128;  // the longest list (Tile's capacities)
        static_assert(Tile::pending_capacity <= most && Tile::entered_capacity <= most, "lists sort_by_near can sort");
        if (count < 2 || count > most) return;
        alignas(64) float key[most + simd::width];
        for (uint32_t i = 0; i < count; ++i) key[i] = a[i].near == a[i].near ? a[i].near : INFINITY;
        const uint32_t groups = (count + simd::width - 1) / simd::width * simd::width;
        for (uint32_t i = count; i < groups; ++i) key[i] = INFINITY;  // past the end: never before anything
        T sorted[most];
        for (uint32_t i = 0; i < count; ++i) {
            const simd::Floats k = simd::splat(key[i]);
            uint32_t rank = 0;
            for (uint32_t g = 0; g < groups; g += simd::width) {
                const simd::Floats v = simd::load(key + g);
                const uint32_t less = simd::bits(v < k), tied = simd::bits(v <= k) & ~less;
                const uint32_t earlier = i >= g + simd::width ? ~0u
                    : i > g                                   ? (1u << (i - g)) - 1
                                                              : 0u;  // lanes before i
                rank += math::bit_count(less) + math::bit_count(tied & earlier);
            }
            sorted[rank] = a[i];
        }
        std::copy(sorted, sorted + count, a);
    }

    // The instance's frame for a light in world space, and the build's common settings; false when the
    // instance can block nothing: a singular transform flattens the mesh, and a light that is not finite
    // lights nothing.
    bool set_instance(const AssetView& view, Placement at, const double* world_light, bool one_sided, double bias) {
        view_ = &view;
        one_sided_ = one_sided;
        bias_ = bias > 0 ? bias : default_shadow_bias(asset_world_size(view));
        skipped_ = 0;
        for (int k = 0; k < 3; ++k) world_light_[k] = world_light[k];
        usable_ = invert_instance(at.transform, inverse_) && finite3(world_light);
        if (!usable_) return false;
        apply_instance(inverse_, world_light, light_);
        mesh_ = &view.meshes[at.mesh];
        return true;
    }

    // Sets up tile t for the `count` world points points + 3 * index[i] (xyz doubles) set in `alive`: in the
    // mesh's frame, from the light, in float, and the pyramid from the light that holds their directions.
    // t.alive gets the points the tile takes; `alone` those that go alone, in double (at or by the light, not
    // finite, or beyond float's range); neither gets those within the bias of the light (never blocked).
    // Returns the points over 60 degrees off the tile's mean direction, which the tile does not take either
    // (the traversal says where they go). `fine_obbs`: the fine boxes decoded (ScanBounds), or null to read
    // them from the asset.
    uint64_t start_tile(Tile& t, const double* points, const uint32_t* index, uint32_t count, uint64_t alive,
                        QueryStats* stats, TileCache* cache, const Obb* fine_obbs, uint64_t& alone) const {
        t.count = count;
        t.stats = stats;
        t.cache = cache;
        t.fine_obbs = fine_obbs;
        t.alive = t.shadowed = 0;
        t.pending_count = t.entered_count = 0;
        // The points of `alive` in double lanes, padded with the light (which nothing blocks): `from`, the point
        // in the mesh's frame, its offset and distance from the light, each lane the same operations in the same
        // order as shadow_from and apply_instance take on one point.
        using simd::Doubles;
        alignas(64) double wx[tile_capacity], wy[tile_capacity], wz[tile_capacity];
        double *ex = t.e[0], *ey = t.e[1], *ez = t.e[2];
        const uint64_t wanted = alive & tile_lanes(count);
        for (uint32_t g = 0; g < tile_capacity; g += simd::dwidth) {
            if (!simd::double_group(wanted, g)) continue;  // zeros below
            for (uint32_t i = g; i < g + simd::dwidth; ++i) {
                const double* q = wanted >> i & 1 ? points + size_t(index[i]) * 3 : world_light_;
                wx[i] = q[0];
                wy[i] = q[1];
                wz[i] = q[2];
            }
        }
        const double* m = inverse_;
        uint64_t blockable = 0, regular = 0, close = 0;
        for (uint32_t i = 0; i < tile_capacity; i += simd::dwidth) {
            if (!simd::double_group(wanted, i)) {  // (an instance often takes a few points)
                const Doubles zero = simd::dsplat(0);
                for (double* out : {t.from + i, t.dist + i, ex + i, ey + i, ez + i}) simd::store(out, zero);
                continue;
            }
            const Doubles x = simd::load(wx + i), y = simd::load(wy + i), z = simd::load(wz + i);
            const Doubles dx = simd::dsplat(world_light_[0]) - x, dy = simd::dsplat(world_light_[1]) - y,
                          dz = simd::dsplat(world_light_[2]) - z;
            const Doubles from = simd::dsplat(bias_) / simd::sqrt(simd::fused(dz, dz, simd::fused(dy, dy, dx * dx)));
            Doubles p[3], e[3];
            for (int k = 0; k < 3; ++k) {
                p[k] = simd::dsplat(m[k]) * x + simd::dsplat(m[3 + k]) * y + simd::dsplat(m[6 + k]) * z +
                    simd::dsplat(m[9 + k]);
                e[k] = p[k] - simd::dsplat(light_[k]);
            }
            const Doubles dist = simd::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
            simd::store(t.from + i, from);
            simd::store(t.dist + i, dist);
            simd::store(wx + i, p[0]);
            simd::store(wy + i, p[1]);
            simd::store(wz + i, p[2]);
            simd::store(ex + i, e[0]);
            simd::store(ey + i, e[1]);
            simd::store(ez + i, e[2]);
            blockable |= uint64_t(simd::bits(from <= simd::dsplat(1))) << i;  // may_block
            close |= uint64_t(simd::bits(from < simd::dsplat(1e-6))) << i;
            regular |= uint64_t(simd::bits((dist > simd::dsplat(float_tiny)) & (dist < simd::dsplat(1e30)))) << i;
        }
        for (uint64_t w = wanted; w; w &= w - 1) {  // the exact tests read the points they test only
            const uint32_t i = math::lowest_bit(w);
            t.p[i][0] = wx[i];
            t.p[i][1] = wy[i];
            t.p[i][2] = wz[i];
        }
        t.close = close;
        const uint64_t live = wanted & blockable;
        // Not regular: at or by the light, not finite, or beyond float's range.
        alone = live & ~regular;
        t.alive = live & regular;
        const uint64_t held = t.alive ? make_frame(t, t.alive, ex, ey, ez) : 0;
        const uint64_t off = t.alive & ~held;
        t.alive &= held;
        if (t.alive) {
            make_pyramid(t, t.alive, t.pyramid);
            t.small = t.pyramid.dmax < float_safe;
            // The float lanes of the groups that hold a live point (every lane test skips the other groups), in
            // double lanes: the same operations as on one point, each rounded to float once.
            const Doubles zero = simd::dsplat(0), one = simd::dsplat(1), unset = simd::dsplat(-1),
                          half = simd::dsplat(0.5), grow = simd::dsplat(1.000001), inf = simd::dsplat(INFINITY);
            Doubles l1_lo = inf, l1_hi = zero;  // over the live points (their l1 is finite)
            for (uint32_t g = 0; g < tile_capacity; g += simd::width) {
                if (!simd::group(t.alive, g)) continue;
                for (uint32_t i = g; i < g + simd::width; i += simd::dwidth) {
                    const simd::DoubleMask in = simd::double_lanes(simd::double_group(t.alive, i));
                    const Doubles x = simd::load(ex + i), y = simd::load(ey + i), z = simd::load(ez + i),
                                  from = simd::load(t.from + i);
                    simd::store_floats(t.ex + i, simd::select(in, x, zero));
                    simd::store_floats(t.ey + i, simd::select(in, y, zero));
                    simd::store_floats(t.ez + i, simd::select(in, z, zero));
                    // -1: never inside a volume
                    simd::store_floats(t.fd + i, simd::select(in, simd::load(t.dist + i), unset));
                    simd::store_floats(t.keep + i, simd::select(in, one - from, one));
                    simd::store_floats(t.reach + i, simd::select(in, one - half * from, one));  // blocking_start
                    const Doubles l1 = simd::abs(x) + simd::abs(y) + simd::abs(z);
                    simd::store(t.l1 + i, l1);
                    simd::store_floats(t.vl + i, l1 * grow);
                    l1_lo = simd::min(l1_lo, simd::select(in, l1, inf));
                    l1_hi = simd::max(l1_hi, simd::select(in, l1, zero));
                }
                simd::store(t.slack + g, simd::load(t.fd + g) * simd::splat(2e-6f));
            }
            t.l1_lo = simd::lane_min(l1_lo);
            t.l1_hi = simd::lane_max(l1_hi);
        }
        return off;
    }

    // The query of one point on its own, in double (q.from: not may_block when nothing can block it).
    Query make_query(const double* world_p, QueryStats* stats, const Obb* fine_obbs) const {
        Query q;
        q.from = shadow_from(world_p, world_light_, bias_);
        apply_instance(inverse_, world_p, q.p);
        for (int k = 0; k < 3; ++k) q.e[k] = q.p[k] - light_[k];
        q.dist = std::sqrt(q.e[0] * q.e[0] + q.e[1] * q.e[1] + q.e[2] * q.e[2]);
        q.stats = stats;
        q.fine_obbs = fine_obbs;
        return q;
    }

    BoxFilter box_filter(const Obb& box) const {
        double h[3], c[3], a[3][3];
        padded_halves(box, h);
        for (int k = 0; k < 3; ++k) {
            c[k] = double(box.center[k]) - light_[k];
            for (int j = 0; j < 3; ++j) a[k][j] = box.axis[k][j];
        }
        return make_box_filter(c, h, a);
    }

    // Fine cluster f's box filter.
    BoxFilter fine_box_filter(uint32_t f, const Obb* fine_obbs) const { return box_filter(fine_obb(f, fine_obbs)); }

    // Fine cluster f's box filter from the batch's cache, set up there when it is not yet.
    const BoxFilter& cached_fine_box_filter(uint32_t f, const Obb* fine_obbs, TileCache& cache) const {
        const uint32_t slot = TileCache::box_slot(this, f);
        if (cache.box_owner[slot] != this || cache.box_cluster[slot] != f) {
            cache.box[slot] = fine_box_filter(f, fine_obbs);
            cache.box_owner[slot] = this;
            cache.box_cluster[slot] = f;
        }
        return cache.box[slot];
    }

    // The points of `subset` whose segment to the light may touch the box of `b` (usable, and the tile small)
    // where a contact could block (box_lanes over the tile's points).
    static uint64_t box_points(const BoxFilter& b, uint64_t subset, const Tile& t) {
        return box_lanes(b, subset, t.ex, t.ey, t.ez, t.fd, t.reach);
    }

    // Tests fine cluster f's triangles for the points of `subset` still alive whose segment may touch its box.
    void test_points(uint32_t f, uint64_t subset, Tile& t) const {
        test_triangles(f, fine_box_points(f, subset & t.alive, t), t);
    }

    // The points of `subset` whose segment may touch fine cluster f's box.
    uint64_t fine_box_points(uint32_t f, uint64_t subset, Tile& t) const {
        if (!view_->fine_bounds.obbs || !subset) return subset;
        BoxFilter own;
        const BoxFilter& b =
            t.cache ? cached_fine_box_filter(f, t.fine_obbs, *t.cache) : (own = fine_box_filter(f, t.fine_obbs));
        uint64_t check = subset;  // the points whose box test is (also) done in double
        if (b.usable && t.small) {
            // The float filter first. For a light more than a million biases away its margin (1e-6 of the
            // distance) lets through the cluster a point lies on, whose segment leaves the thin box soon after
            // it starts to count: those points again in double, as the cluster's triangles cost far more.
            subset = box_points(b, subset, t);
            check = subset & t.close;
            if (!check) return subset;
        }
        const Obb box = fine_obb(f, t.fine_obbs);
        for (uint64_t w = check; w; w &= w - 1) {
            uint32_t i = math::lowest_bit(w);
            if (!segment_may_touch_box(box, t.p[i], light_, blocking_start(t.from[i]))) subset &= ~(uint64_t(1) << i);
        }
        return subset;
    }

    // Tests fine cluster f's triangles for the points of `subset` still alive.
    void test_triangles(uint32_t f, uint64_t subset, Tile& t) const {
        const uint64_t todo = subset & t.alive;
        if (!todo) return;
        // The tile's pyramid holds every point of `todo`: it is narrowed only while a scan or a fine walk works
        // for some points, and the clusters tested then are those that scan or walk found for them.
        const lit::TileView tile{t.ex,    t.ey,    t.ez,         t.vl,         t.keep,      t.l1,
                                 t.l1_lo, t.l1_hi, t.pyramid.rx, t.pyramid.ry, t.pyramid.rz};
        uint64_t hit = cluster_blocks_points(*view_, *mesh_, f, t.p, t.from, todo, light_, one_sided_, t.stats, nullptr,
                                             t.cache ? &t.cache->lit : nullptr, this, &tile);
        t.alive &= ~hit;
        t.shadowed |= hit;
    }

    // Tests the pending clusters, nearest closing distance first. A cluster's box is tested three clusters
    // ahead of its triangles, and only when some point may touch it are its triangles and new vertices asked
    // for then, its reused vertices one test ahead (unless its first group is lit already): on large meshes
    // these reads otherwise miss the cache one after another.
    void test_pending(Tile& t) const {
        Tile::Pending* p = t.pending;
        const uint32_t n = t.pending_count;
        sort_by_near(p, n);
        auto prefetch_triangles = [&](uint32_t i, int step) {  // lit::prefetch's step, unless lit already
            if (t.cache && t.cache->lit.holds(this, p[i].cluster, 0)) return;
            lit::prefetch(*view_, *mesh_, view_->fine[mesh_->first_fine + p[i].cluster], step);
        };
        auto test_box = [&](uint32_t i) {  // into the entry's points
            if (i >= n) return;
            p[i].points = fine_box_points(p[i].cluster, p[i].points & t.alive, t);
            if (p[i].points) prefetch_triangles(i, 0);
        };
        test_box(0);
        test_box(1);
        test_box(2);
        if (n && p[0].points) prefetch_triangles(0, 1);
        for (uint32_t i = 0; i < n && t.alive; ++i) {
            test_box(i + 3);
            if (i + 1 < n && (p[i + 1].points & t.alive)) prefetch_triangles(i + 1, 1);
            test_triangles(p[i].cluster, p[i].points, t);
        }
        t.pending_count = 0;
    }

    // The walk every traversal makes of a tile, given its own two searches: after start_tile, `find()`
    // looks for the coarse clusters the tile's pyramid meets (a tree walk may test clusters itself, and
    // puts the coarse ones on the entered list, add_entered), then the entered ones are walked with
    // `enter` (walk_entered) and the last pending clusters tested. Last, each point of `alone` (those the
    // tile did not take) answers on its own, `walk_alone(i)` true when it is in shadow. Returns the tile's
    // points in shadow.
    template <class Find, class Enter, class WalkAlone>
    uint64_t walk_tile(Tile& t, uint64_t alone, Find find, Enter enter, WalkAlone walk_alone) const {
        if (t.alive) {
            find();
            walk_entered(t, enter);
            test_pending(t);
        }
        for (uint64_t b = alone; b; b &= b - 1) {
            const uint32_t i = math::lowest_bit(b);
            if (walk_alone(i)) t.shadowed |= uint64_t(1) << i;
        }
        return t.shadowed;
    }

    // The entered coarse clusters, nearest first: `enter(id, points)` finds one's fine clusters for the
    // points still alive (add_pending), and those are tested before the next one is entered, so that farther
    // ones leave out the points already found in shadow.
    template <class Enter>
    void walk_entered(Tile& t, Enter enter) const {
        Tile::Entered* e = t.entered;
        const uint32_t count = t.entered_count;
        t.entered_count = 0;
        sort_by_near(e, count);
        for (uint32_t i = 0; i < count && t.alive; ++i) {
            const uint64_t in = e[i].points & t.alive;
            if (!in) continue;
            enter(e[i].id, in);
            test_pending(t);
        }
    }

    // A coarse cluster (or cluster node) entered by the points `points`, `near` its closing distance; a
    // full list is walked first (walk_entered with `enter`).
    template <class Enter>
    void add_entered(Tile& t, float near, uint32_t id, uint64_t points, Enter enter) const {
        if (t.entered_count == Tile::entered_capacity) walk_entered(t, enter);
        t.entered[t.entered_count++] = {near, id, points};
    }

    // A fine cluster whose volume the points `points` meet, to be tested in order of `near`; a full list is
    // tested first.
    void add_pending(Tile& t, float near, uint32_t f, uint64_t points) const {
        if (t.pending_count == Tile::pending_capacity) test_pending(t);
        t.pending[t.pending_count++] = {near, f, points};
    }

    // Fine cluster f's box: decoded already (`fine_obbs`, ScanBounds) or from the asset.
    Obb fine_obb(uint32_t f, const Obb* fine_obbs) const {
        return fine_obbs ? fine_obbs[f] : view_->fine_bounds.obb(mesh_->first_fine + f);
    }

    IndexRange coarse_triangles(uint32_t c) const { return coarse_triangle_range(*view_, *mesh_, c); }

    // One-sided: a cluster the light sees entirely from the front, with no double-sided triangle.
    bool skippable(const LevelBounds& bounds, uint32_t index, IndexRange triangles) const {
        return bounds.cones && light_in_front_cone(bounds.cone(index), light_) &&
            all_single_sided(*view_, *mesh_, triangles);
    }

    bool skippable_fine(uint32_t f) const {
        if (!one_sided_) return false;
        const FineCluster& r = view_->fine[mesh_->first_fine + f];
        return skippable(view_->fine_bounds, mesh_->first_fine + f, {r.first_triangle, r.triangle_count});
    }

    // A cluster's triangles, unless the segment certainly misses its box (a volume only says the point
    // is in the box's shadow cone, which a 4-plane outline makes wider than the box).
    bool test_cluster(uint32_t f, const Query& q) const {
        if (view_->fine_bounds.obbs &&
            !segment_may_touch_box(fine_obb(f, q.fine_obbs), q.p, light_, blocking_start(q.from)))
            return false;
        return cluster_blocks(*view_, *mesh_, f, q.p, q.from, light_, one_sided_, q.stats);
    }

    const AssetView* view_ = nullptr;
    const MeshRecord* mesh_ = nullptr;
    double inverse_[12] = {}, light_[3] = {}, world_light_[3] = {}, bias_ = 0;
    bool usable_ = false, one_sided_ = false;
    size_t skipped_ = 0, capsules_ = 0;
};

}  // namespace CB_LANES
}  // namespace cb
