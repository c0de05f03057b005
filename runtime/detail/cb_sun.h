// The sun's traversal: one instance's shadows for a light at infinity (cb_segment.h, "A sun"), given by the
// direction toward it. Every query ray runs along that one direction, so a cluster's shadow volume is a prism
// (its bounding sphere swept toward the sun's opposite) instead of a pyramid from a point, and a tile of
// points is a prism too: the rectangle that bounds their projections across the direction, from the lowest of
// them up toward the sun. A tile scans the coarse clusters' spheres (ScanBounds, made once per asset) against
// its prism, each point against the spheres that pass, then the fine spheres of the coarse clusters entered,
// nearest the sun first, and tests the clusters found for each point still lit: the ray against the cluster's
// box, then its triangles exactly (ray_triangle). The answers are those of occluded_sun_reference
// (cb_shadow.h). Header-only C++17, no exceptions; building allocates, queries do not. MIT licensed
// (runtime/LICENSE).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "../cb_asset.h"
#include "../cb_scan_bounds.h"
#include "../cb_segment.h"
#include "../cb_shadow.h"
#include "cb_math.h"
#include "cb_tile.h"

namespace cb {
inline namespace CB_LANES {

class SunTraversal {
public:
    static constexpr uint32_t none = 0xffffffffu;

    // One mesh of the asset placed by the caller, for the sun in world direction `toward` (from the scene
    // toward the sun, any length above zero). options.traversal is not read: a sun has this traversal only.
    void build(const AssetView& view, Placement at, const double* toward, const ShadowBuildOptions& options) {
        view_ = &view;
        one_sided_ = options.one_sided;
        coarse_.clear();
        for (int k = 0; k < 3; ++k) world_toward_[k] = toward[k];
        const double bias = options.bias > 0 ? options.bias : default_shadow_bias(asset_world_size(view));
        from_ = finite3(toward) ? sun_from(toward, bias) : NAN;
        usable_ = from_ < INFINITY && invert_instance(at.transform, inverse_);  // NaN: unusable
        if (!usable_) return;
        mesh_ = &view.meshes[at.mesh];
        apply_linear(inverse_, toward, toward_);
        if (!direction_frame(toward_, frame_)) {  // flattened to no length by rounding: the reference's way
            spheres_ = false;
            return;
        }
        const ScanBounds* shared = options.bounds;
        shared_bounds_ = shared && shared[at.mesh].made_from(view, *mesh_) ? &shared[at.mesh] : nullptr;
        if (!shared_bounds_) own_bounds_.make(view, at.mesh);
        const ScanBounds& s = bounds();
        spheres_ = s.source_fine != nullptr && s.extent < INFINITY;
        if (!spheres_) return;
        coarse_.resize(mesh_->coarse_count);
        for (uint32_t c = 0; c < mesh_->coarse_count; ++c) coarse_[c] = across(s.coarse_first + c);
    }

    bool sun() const { return true; }
    const double* world_light() const { return world_toward_; }  // the direction toward the sun
    size_t stack_size() const { return 4; }                      // no tree: the stack is passed along only
    size_t node_count() const { return 0; }
    size_t always_tested() const { return 0; }
    size_t skipped_clusters() const { return 0; }
    size_t capsules() const { return 0; }
    size_t memory_bytes() const { return own_bounds_.memory_bytes() + coarse_.capacity() * sizeof(Sphere); }

    // True when the ray from world point p toward the sun is blocked by this instance.
    bool occluded(const double* world_p, uint32_t* stack, QueryStats* stats = nullptr) const {
        const uint32_t first = 0;
        return occluded_tile(world_p, &first, 1, 1, stack, stats) != 0;
    }

    // Of the `count` world points points + 3 * index[i] (xyz doubles), those set in `alive` that this
    // instance shadows, as a mask; the same answers as occluded() point by point.
    uint64_t occluded_tile(const double* points, const uint32_t* index, uint32_t count, uint64_t alive, uint32_t*,
                           QueryStats* stats = nullptr, TileCache* = nullptr) const {
        if (!usable_ || !alive) return 0;
        Tile t;
        t.stats = stats;
        t.alive = t.shadowed = 0;
        t.entered_count = t.pending_count = 0;
        uint64_t alone = 0;
        const ScanBounds& s = bounds();
        for (uint32_t i = 0; i < count; ++i) {
            if (!(alive >> i & 1)) continue;
            const double* world_p = points + size_t(index[i]) * 3;
            if (!finite3(world_p)) continue;  // never in shadow
            apply_instance(inverse_, world_p, t.p[i]);
            if (!spheres_) {
                alone |= uint64_t(1) << i;
                continue;
            }
            const double q[3] = {t.p[i][0] - s.origin[0], t.p[i][1] - s.origin[1], t.p[i][2] - s.origin[2]};
            t.u[i] = math::dot3(q, frame_[1]), t.v[i] = math::dot3(q, frame_[2]), t.w[i] = math::dot3(q, frame_[0]);
            if (!(std::fabs(t.u[i]) + std::fabs(t.v[i]) + std::fabs(t.w[i]) < 1e30)) {
                alone |= uint64_t(1) << i;
                continue;
            }
            t.alive |= uint64_t(1) << i;
        }
        if (t.alive) {
            scan_coarse(t);
            walk_entered(t);
            test_pending(t);
        }
        for (uint64_t b = alone; b; b &= b - 1) {
            const uint32_t i = math::lowest_bit(b);
            if (walk_alone(t.p[i], stats)) t.shadowed |= uint64_t(1) << i;
        }
        return t.shadowed;
    }

private:
    // A sphere in the sun's frame: across the direction (u, v), along it (w, up toward the sun), its radius.
    struct Sphere {
        double u, v, w, r;
    };
    struct Tile {
        uint64_t alive, shadowed;
        double p[tile_capacity][3];                                   // in the mesh's frame
        double u[tile_capacity], v[tile_capacity], w[tile_capacity];  // in the sun's frame, from the bounds' origin
        double lo[2], hi[2], low, margin;                             // the prism of the points walking now
        struct Entry {
            double near;  // how far below the highest sphere the list may hold: the sun's side first
            uint32_t id;
            uint64_t points;
        };
        static constexpr uint32_t entered_capacity = 64, pending_capacity = 128;
        Entry entered[entered_capacity], pending[pending_capacity];
        uint32_t entered_count, pending_count;
        QueryStats* stats;
    };

    const ScanBounds& bounds() const { return shared_bounds_ ? *shared_bounds_ : own_bounds_; }

    // Sphere i of bounds() in the sun's frame.
    Sphere across(uint32_t i) const {
        const ScanBounds& s = bounds();
        const double c[3] = {s.x[i], s.y[i], s.z[i]};
        return {math::dot3(c, frame_[1]), math::dot3(c, frame_[2]), math::dot3(c, frame_[0]), double(s.r[i])};
    }

    // The prism of the points `which`: the rectangle bounding their projections, the lowest along the
    // direction, and a margin far above the rounding of the projections (a few 1e-16 of the sizes) and of the
    // frame's departure from the ray's direction (1e-16 of the distance covered).
    static void make_prism(Tile& t, uint64_t which, double extent) {
        t.lo[0] = t.lo[1] = t.low = INFINITY;
        t.hi[0] = t.hi[1] = -INFINITY;
        double size = 0;
        for (uint64_t b = which; b; b &= b - 1) {
            const uint32_t i = math::lowest_bit(b);
            t.lo[0] = std::min(t.lo[0], t.u[i]), t.hi[0] = std::max(t.hi[0], t.u[i]);
            t.lo[1] = std::min(t.lo[1], t.v[i]), t.hi[1] = std::max(t.hi[1], t.v[i]);
            t.low = std::min(t.low, t.w[i]);
            size = std::max(size, std::fabs(t.u[i]) + std::fabs(t.v[i]) + std::fabs(t.w[i]));
        }
        t.margin = 1e-9 * (extent + size);
    }

    // The points of `in` whose ray may meet sphere s: the ray passes within its radius across the direction,
    // and the sphere reaches above the point. Every ray runs along w, so both are comparisons of coordinates.
    static uint64_t sphere_points(const Sphere& s, uint64_t in, const Tile& t) {
        const double r = s.r + t.margin, r2 = r * r, top = s.w + r;
        uint64_t keep = 0;
        for (uint64_t b = in; b; b &= b - 1) {
            const uint32_t i = math::lowest_bit(b);
            const double du = s.u - t.u[i], dv = s.v - t.v[i];
            if (du * du + dv * dv <= r2 && t.w[i] <= top) keep |= uint64_t(1) << i;
        }
        return keep;
    }

    // Whether sphere s may meet the prism at all.
    static bool meets_prism(const Sphere& s, const Tile& t) {
        const double r = s.r + t.margin;
        return s.u + r >= t.lo[0] && s.u - r <= t.hi[0] && s.v + r >= t.lo[1] && s.v - r <= t.hi[1] && s.w + r >= t.low;
    }

    // Sorts a list by `near`, ties in list order (insertion: the lists are short).
    static void sort_by_near(Tile::Entry* a, uint32_t n) {
        for (uint32_t i = 1; i < n; ++i) {
            const Tile::Entry e = a[i];
            uint32_t j = i;
            for (; j > 0 && a[j - 1].near > e.near; --j) a[j] = a[j - 1];
            a[j] = e;
        }
    }

    void scan_coarse(Tile& t) const {
        make_prism(t, t.alive, bounds().extent);
        for (uint32_t c = 0; c < mesh_->coarse_count && t.alive; ++c) {
            const Sphere& s = coarse_[c];
            if (!meets_prism(s, t)) continue;
            const uint64_t points = sphere_points(s, t.alive, t);
            if (!points) continue;
            if (t.entered_count == Tile::entered_capacity) walk_entered(t);
            t.entered[t.entered_count++] = {-(s.w + s.r), c, points};
        }
    }

    // The entered coarse clusters, the sun's side first: their fine spheres scanned, each one's clusters
    // tested before the next coarse cluster's.
    void walk_entered(Tile& t) const {
        const uint32_t count = t.entered_count;
        t.entered_count = 0;
        sort_by_near(t.entered, count);
        for (uint32_t e = 0; e < count && t.alive; ++e) {
            const uint64_t in = t.entered[e].points & t.alive;
            if (!in) continue;
            const ClusterRange& r = view_->coarse[mesh_->first_coarse + t.entered[e].id];
            for (uint32_t f = r.first; f < r.first + r.count; ++f) {
                const Sphere sphere = across(f);
                const uint64_t points = sphere_points(sphere, in & t.alive, t);
                if (!points) continue;
                if (t.pending_count == Tile::pending_capacity) test_pending(t);
                t.pending[t.pending_count++] = {-(sphere.w + sphere.r), f, points};
            }
            test_pending(t);
        }
    }

    // The pending fine clusters, the sun's side first: for each point still lit, the ray against the box, then
    // the triangles exactly.
    void test_pending(Tile& t) const {
        const uint32_t count = t.pending_count;
        t.pending_count = 0;
        sort_by_near(t.pending, count);
        const std::vector<Obb>& boxes = bounds().fine_obbs;
        for (uint32_t e = 0; e < count && t.alive; ++e) {
            const uint32_t f = t.pending[e].id;
            for (uint64_t b = t.pending[e].points & t.alive; b; b &= b - 1) {
                const uint32_t i = math::lowest_bit(b);
                if (!ray_may_touch_box(boxes[f], t.p[i], toward_, blocking_start(from_))) continue;
                if (cluster_blocks_sun(*view_, *mesh_, f, t.p[i], toward_, from_, one_sided_, t.stats, nullptr)) {
                    t.shadowed |= uint64_t(1) << i;
                    t.alive &= ~(uint64_t(1) << i);
                }
            }
        }
    }

    // One point in the mesh's frame, as the reference walks it: every fine cluster whose box the ray may touch.
    bool walk_alone(const double* p, QueryStats* stats) const {
        for (uint32_t f = 0; f < mesh_->fine_count; ++f) {
            if (view_->fine_bounds.obbs &&
                !ray_may_touch_box(view_->fine_bounds.obb(mesh_->first_fine + f), p, toward_, blocking_start(from_)))
                continue;
            if (cluster_blocks_sun(*view_, *mesh_, f, p, toward_, from_, one_sided_, stats, nullptr)) return true;
        }
        return false;
    }

    const AssetView* view_ = nullptr;
    const MeshRecord* mesh_ = nullptr;
    double inverse_[12] = {}, toward_[3] = {}, world_toward_[3] = {}, frame_[3][3] = {}, from_ = 0;
    bool usable_ = false, one_sided_ = false, spheres_ = false;
    const ScanBounds* shared_bounds_ = nullptr;
    ScanBounds own_bounds_;
    std::vector<Sphere> coarse_;  // the coarse spheres in the sun's frame
};

}  // namespace CB_LANES
}  // namespace cb
