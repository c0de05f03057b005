// The sun's traversal: one instance's shadows for a light at infinity (cb_segment.h, "A sun"), given by the
// direction toward it. Every query ray runs along that one direction, so a cluster's shadow volume is a prism
// (its bounding sphere swept toward the sun's opposite) instead of a pyramid from a point, and a tile of
// points is a prism too: the rectangle that bounds their projections across the direction, from the lowest of
// them up toward the sun. A tile scans the coarse clusters' spheres (ScanBounds, made once per asset) against
// its prism, each point against the spheres that pass, then the fine spheres of the coarse clusters entered,
// nearest the sun first, each sphere's points against its box in float, and tests the clusters found against
// the points still lit (cb_sun_triangles.h: a float line test, then ray_triangle exactly). The answers are
// those of occluded_sun_reference (cb_shadow.h). Header-only C++17, no exceptions; building allocates,
// queries do not. MIT licensed (runtime/LICENSE).
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
#include "cb_sun_triangles.h"
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
        coarse_skipped_.clear();
        skipped_ = 0;
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
        // blocking_start along the unit direction, lowered by 1e-6 of itself: the float filter then tests a
        // little more of each ray, never less.
        start_ = blocking_start(from_) * std::sqrt(math::dot3(toward_, toward_)) * (1 - 1e-6);
        boxes_small_ = s.extent < float_safe && start_ < float_safe;
        coarse_.resize(mesh_->coarse_count);
        coarse_skipped_.assign(mesh_->coarse_count, 0);
        for (uint32_t c = 0; c < mesh_->coarse_count; ++c) {
            coarse_[c] = across(s.coarse_first + c);
            if (one_sided_ &&
                faces_the_sun(view.coarse_bounds, mesh_->first_coarse + c, coarse_triangle_range(view, *mesh_, c)))
                skipped_ += view.coarse[mesh_->first_coarse + c].count, coarse_skipped_[c] = 1;
        }
    }

    bool sun() const { return true; }
    const double* world_light() const { return world_toward_; }  // the direction toward the sun
    size_t stack_size() const { return 4; }                      // no tree: the stack is passed along only
    size_t node_count() const { return 0; }
    size_t always_tested() const { return 0; }
    size_t skipped_clusters() const { return skipped_; }  // one-sided: fine clusters the sun sees from the front
    size_t capsules() const { return 0; }
    size_t memory_bytes() const {
        return own_bounds_.memory_bytes() + coarse_.capacity() * sizeof(Sphere) + coarse_skipped_.capacity();
    }

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
        t.size = 0;
        for (uint32_t i = 0; i < tile_capacity; ++i) {
            const bool in = t.alive >> i & 1;
            t.x[i] = in ? float(t.p[i][0] - s.origin[0]) : 0.0f, t.y[i] = in ? float(t.p[i][1] - s.origin[1]) : 0.0f,
            t.z[i] = in ? float(t.p[i][2] - s.origin[2]) : 0.0f;
            t.size = std::max(t.size, std::fabs(t.x[i]) + std::fabs(t.y[i]) + std::fabs(t.z[i]));
        }
        t.small = t.size < float_safe && boxes_small_;
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
        alignas(64) float x[tile_capacity], y[tile_capacity], z[tile_capacity];  // p from the bounds' origin
        float size;  // the largest |x|_1 + |y|_1 + |z|_1 of the tile's points (boxes' float margins)
        bool small;  // every coordinate and box within float_safe: the float box filter applies
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

    // One-sided: a cluster the sun sees entirely from the front, with no double-sided triangle.
    bool faces_the_sun(const LevelBounds& b, uint32_t index, IndexRange triangles) const {
        return b.cones && sun_in_front_cone(b.cone(index), toward_) && all_single_sided(*view_, *mesh_, triangles);
    }
    bool fine_faces_the_sun(uint32_t f) const {
        if (!one_sided_) return false;
        const FineCluster& r = view_->fine[mesh_->first_fine + f];
        return faces_the_sun(view_->fine_bounds, mesh_->first_fine + f, {r.first_triangle, r.triangle_count});
    }

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

    // A cluster's box set up for the float test of box_points: its centre from the bounds' origin, its axes,
    // each axis's padded half extent (infinite where the ray runs nearly across it: no test there) with the
    // side the ray heads to (sign) and how far along the axis it has gone at blocking_start (lift), and the
    // axes z x a_k with the box's support on them.
    struct SunBox {
        float c[3], a[3][3], h[3], sign[3], lift[3], w[3][3], support[3], scale;
    };

    SunBox sun_box(const Obb& box) const {
        SunBox b;
        const ScanBounds& s = bounds();
        double h[3];
        padded_halves(box, h);
        const double* z = frame_[0];
        double scale = h[0] + h[1] + h[2];
        for (int k = 0; k < 3; ++k) {
            const double a[3] = {box.axis[k][0], box.axis[k][1], box.axis[k][2]}, c = box.center[k] - s.origin[k];
            b.c[k] = float(c), scale += std::fabs(c);
            for (int j = 0; j < 3; ++j) b.a[k][j] = box.axis[k][j];
            const double zk = math::dot3(a, z);
            b.sign[k] = zk > 1e-6 ? 1.0f : zk < -1e-6 ? -1.0f : 0.0f;
            b.h[k] = b.sign[k] != 0 ? float(h[k]) : INFINITY;
            b.lift[k] = float(start_ * zk);
            double w[3];
            math::cross3(z, a, w);
            for (int j = 0; j < 3; ++j) b.w[k][j] = float(w[j]);
        }
        for (int k = 0; k < 3; ++k) {
            const double w[3] = {b.w[k][0], b.w[k][1], b.w[k][2]};
            double support = 0;
            for (int j = 0; j < 3; ++j) {
                const double a[3] = {box.axis[j][0], box.axis[j][1], box.axis[j][2]};
                support += h[j] * std::fabs(math::dot3(w, a));
            }
            b.support[k] = float(support);
        }
        b.scale = float(scale);
        return b;
    }

    // The points of `subset` whose ray, from blocking_start on, may touch box b: separating axes in float over
    // the subset's lanes, the box's three axes (the ray, from where it starts to count, heads one way along
    // each: it must start on the box's near side of its far face) and z x each (the ray projects to one value
    // there). The margin, 1e-6 of the coordinates' and the box's sizes, holds the float roundings (below 1e-7 of
    // them each) and the float direction's departure from the ray's (6e-8 of the way to the box).
    static uint64_t box_points(const SunBox& b, uint64_t subset, const Tile& t) {
        using simd::Floats;
        uint32_t begin, end;
        simd::lane_span(subset, begin, end);
        if (!(b.scale + t.size > 1e-30f)) return subset;  // a margin that float's subnormals could swallow
        const Floats m = simd::splat(1e-6f * (b.scale + t.size)), zero = simd::splat(0.0f);
        uint64_t keep = 0;
        for (uint32_t i = begin; i < end; i += simd::width) {
            if (!simd::group(subset, i)) continue;
            const Floats qx = simd::load(t.x + i) - simd::splat(b.c[0]), qy = simd::load(t.y + i) - simd::splat(b.c[1]),
                         qz = simd::load(t.z + i) - simd::splat(b.c[2]);
            Floats worst = simd::splat(INFINITY);
            for (int k = 0; k < 3; ++k) {
                const Floats g = simd::dot(qx, qy, qz, b.a[k][0], b.a[k][1], b.a[k][2]) + simd::splat(b.lift[k]);
                worst = simd::min(worst, (simd::splat(b.h[k]) + m) - simd::splat(b.sign[k]) * g);
                const Floats across = simd::abs(simd::dot(qx, qy, qz, b.w[k][0], b.w[k][1], b.w[k][2]));
                worst = simd::min(worst, (simd::splat(b.support[k]) + m) - across);
            }
            keep |= uint64_t(simd::bits(worst >= zero)) << i;
        }
        return subset & keep;
    }

    // The points of `subset` whose ray may touch `box`: in float when the tile allows, else in double.
    uint64_t points_near_box(const Obb& box, uint64_t subset, const Tile& t) const {
        if (!subset) return 0;
        if (t.small) return box_points(sun_box(box), subset, t);
        for (uint64_t b = subset; b; b &= b - 1) {
            const uint32_t i = math::lowest_bit(b);
            if (!ray_may_touch_box(box, t.p[i], toward_, blocking_start(from_))) subset &= ~(uint64_t(1) << i);
        }
        return subset;
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
            if (coarse_skipped_[c] || !meets_prism(s, t)) continue;
            const uint64_t points = points_near_box(bounds().coarse_obbs[c], sphere_points(s, t.alive, t), t);
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
                if (!meets_prism(sphere, t) || fine_faces_the_sun(f)) continue;
                const uint64_t points =
                    points_near_box(bounds().fine_obbs[f], sphere_points(sphere, in & t.alive, t), t);
                if (!points) continue;
                if (t.pending_count == Tile::pending_capacity) test_pending(t);
                t.pending[t.pending_count++] = {-(sphere.w + sphere.r), f, points};
            }
            test_pending(t);
        }
    }

    // The pending fine clusters, the sun's side first: the points still lit against their triangles, set up
    // once per cluster (cluster_blocks_sun_points).
    void test_pending(Tile& t) const {
        const uint32_t count = t.pending_count;
        t.pending_count = 0;
        sort_by_near(t.pending, count);
        const std::vector<Obb>& boxes = bounds().fine_obbs;
        for (uint32_t e = 0; e < count && t.alive; ++e) {
            const uint32_t f = t.pending[e].id;
            uint64_t points = t.pending[e].points & t.alive;
            // The box again, in double: the float filter's margin lets through the cluster a point lies on,
            // whose ray leaves the thin box soon after it starts to count; its triangles cost far more.
            for (uint64_t b = t.small ? points : 0; b; b &= b - 1) {
                const uint32_t i = math::lowest_bit(b);
                if (!ray_may_touch_box(boxes[f], t.p[i], toward_, blocking_start(from_))) points &= ~(uint64_t(1) << i);
            }
            if (!points) continue;
            const uint64_t blocked = cluster_blocks_sun_points(*view_, *mesh_, f, t.p, points, toward_, frame_[0],
                                                               from_, one_sided_, t.stats);
            t.shadowed |= blocked;
            t.alive &= ~blocked;
        }
    }

    // One point in the mesh's frame, as the reference walks it.
    bool walk_alone(const double* p, QueryStats* stats) const {
        return mesh_occludes_reference(*view_, *mesh_, p, toward_, true, from_, one_sided_, stats, nullptr);
    }

    const AssetView* view_ = nullptr;
    const MeshRecord* mesh_ = nullptr;
    double inverse_[12] = {}, toward_[3] = {}, world_toward_[3] = {}, frame_[3][3] = {}, from_ = 0;
    double start_ = 0;  // blocking_start(from_) along the unit direction frame_[0]
    bool usable_ = false, one_sided_ = false, spheres_ = false, boxes_small_ = false;
    static constexpr double float_safe = 1e9;  // sizes below which the float box filter cannot overflow
    const ScanBounds* shared_bounds_ = nullptr;
    ScanBounds own_bounds_;
    std::vector<Sphere> coarse_;           // the coarse spheres in the sun's frame
    std::vector<uint8_t> coarse_skipped_;  // one-sided: coarse clusters the sun sees from the front
    size_t skipped_ = 0;
};

}  // namespace CB_LANES
}  // namespace cb
