// The sun's traversal: one instance's shadows for a light at infinity (cb_segment.h, "A sun"), given by the
// direction toward it. Every query ray runs along that one direction, so a cluster's shadow volume is a prism
// (its bounding sphere swept toward the sun's opposite) instead of a pyramid from a point, and a tile of
// points is a prism too: the rectangle that bounds their projections across the direction, from the lowest of
// them up toward the sun. A tile scans the coarse clusters' spheres (ScanBounds, made once per asset) against
// its prism, each point against the spheres that pass, then the fine spheres of the coarse clusters entered,
// nearest the sun first, each sphere's points against its box (all in float lanes), and tests the clusters
// found against the points still lit (cb_sun_triangles.h: a float line test, then ray_triangle exactly). When
// ShadowBuildOptions::traversal names a tree, the clusters whose volumes may hold a tile's points come from
// trees built per sun (cb_sun_trees.h) in place of the sphere scans, and the same box and triangle tests
// follow. The answers are those of occluded_sun_reference (cb_shadow.h) whatever the traversal. Header-only
// C++17, no exceptions; building allocates, queries do not. MIT licensed (runtime/LICENSE).
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
#include "cb_sun_trees.h"
#include "cb_sun_triangles.h"
#include "cb_tile.h"

namespace cb {
inline namespace CB_LANES {

class SunTraversal {
public:
    static constexpr uint32_t none = 0xffffffffu;

    // One mesh of the asset placed by the caller, for the sun in world direction `toward` (from the scene
    // toward the sun, any length above zero). options.traversal chooses how the clusters are found: the scan
    // (Traversal::scan), line trees over the boxes' prisms (top_two: a coarse tree whose leaves lead to their
    // fine clusters' trees; top_one: one tree over the fine clusters), or disc trees over the spheres' discs
    // (mtsv_two, mtsv_one). An asset without coarse boxes is answered point by point, as the reference walks
    // it.
    void build(const AssetView& view, Placement at, const double* toward, const ShadowBuildOptions& options) {
        view_ = &view;
        one_sided_ = options.one_sided;
        traversal_ = options.traversal;
        coarse_boxes_.clear();
        coarse_skipped_.clear();
        lines_.clear();
        discs_.clear();
        fine_roots_.clear();
        root_ = none;
        tree_stack_ = 0;
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
        coarse_skipped_.assign(mesh_->coarse_count, 0);
        if (boxes_small_)
            for (const Obb& box : s.coarse_obbs) coarse_boxes_.push_back(sun_box(box));
        for (uint32_t c = 0; c < mesh_->coarse_count; ++c) {
            if (one_sided_ &&
                faces_the_sun(view.coarse_bounds, mesh_->first_coarse + c, coarse_triangle_range(view, *mesh_, c))) {
                skipped_ += view.coarse[mesh_->first_coarse + c].count;
                coarse_skipped_[c] = 1;
            }
        }
        if (traversal_ != Traversal::scan) build_trees();
    }

    bool sun() const { return true; }
    const double* world_light() const { return world_toward_; }                 // the direction toward the sun
    size_t stack_size() const { return std::max<size_t>(4, 2 * tree_stack_); }  // a coarse walk, a fine one
    size_t node_count() const { return lines_.node_count() + discs_.node_count(); }
    size_t always_tested() const { return 0; }
    size_t skipped_clusters() const { return skipped_; }  // one-sided: fine clusters the sun sees from the front
    size_t capsules() const { return 0; }
    size_t memory_bytes() const {
        return own_bounds_.memory_bytes() + coarse_boxes_.capacity() * sizeof(SunBox) + coarse_skipped_.capacity() +
            lines_.memory_bytes() + discs_.memory_bytes() + fine_roots_.capacity() * sizeof(uint32_t);
    }

    // True when the ray from world point p toward the sun is blocked by this instance.
    bool occluded(const double* world_p, uint32_t* stack, QueryStats* stats = nullptr) const {
        const uint32_t first = 0;
        return occluded_tile(world_p, &first, 1, 1, stack, stats) != 0;
    }

    // Of the `count` world points points + 3 * index[i] (xyz doubles), those set in `alive` that this
    // instance shadows, as a mask; the same answers as occluded() point by point. `stack` holds stack_size()
    // entries.
    uint64_t occluded_tile(const double* points, const uint32_t* index, uint32_t count, uint64_t alive, uint32_t* stack,
                           QueryStats* stats = nullptr, TileCache* cache = nullptr) const {
        if (!usable_ || !alive) return 0;
        Tile t;
        t.stats = stats;
        t.cache = cache;
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
            t.u[i] = math::dot3(q, frame_[1]);
            t.v[i] = math::dot3(q, frame_[2]);
            t.w[i] = math::dot3(q, frame_[0]);
            if (!(std::fabs(t.u[i]) + std::fabs(t.v[i]) + std::fabs(t.w[i]) < 1e30)) {
                alone |= uint64_t(1) << i;
                continue;
            }
            t.alive |= uint64_t(1) << i;
        }
        t.size = 0;
        // The float lanes of the groups the live points span: every lane test reads no others.
        uint32_t begin = 0, end = 0;
        if (t.alive) simd::lane_span(t.alive, begin, end);
        for (uint32_t i = begin; i < end; ++i) {
            const bool in = t.alive >> i & 1;
            t.x[i] = in ? float(t.p[i][0] - s.origin[0]) : 0.0f;
            t.y[i] = in ? float(t.p[i][1] - s.origin[1]) : 0.0f;
            t.z[i] = in ? float(t.p[i][2] - s.origin[2]) : 0.0f;
            t.fu[i] = in ? float(t.u[i]) : 0.0f;
            t.fv[i] = in ? float(t.v[i]) : 0.0f;
            t.fw[i] = in ? float(t.w[i]) : 0.0f;
            t.size = std::max(t.size, std::fabs(t.x[i]) + std::fabs(t.y[i]) + std::fabs(t.z[i]));
        }
        t.small = t.size < float_safe && boxes_small_;
        if (t.alive) {
            find_coarse(t, stack);
            walk_entered(t, stack);
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
        alignas(64) float x[tile_capacity], y[tile_capacity], z[tile_capacity];     // p from the bounds' origin
        alignas(64) float fu[tile_capacity], fv[tile_capacity], fw[tile_capacity];  // u, v, w in float
        float size;  // the largest |x|_1 + |y|_1 + |z|_1 of the tile's points (boxes' float margins)
        bool small;  // every coordinate and box within float_safe: the float box filter applies
        struct Entry {
            double near;  // how far below the highest sphere the list may hold: the sun's side first
            uint32_t id;
            uint64_t points;
            uint64_t unsure;  // pending: the points whose box test is to be done again in double
        };
        static constexpr uint32_t entered_capacity = 64, pending_capacity = 128;
        Entry entered[entered_capacity], pending[pending_capacity];
        uint32_t entered_count, pending_count;
        QueryStats* stats;
        TileCache* cache;  // kept between tiles (may be null)
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

    // The prism of some points (SunPrism): its margin is far above the rounding of the projections (a few
    // 1e-16 of the sizes) and of the frame's departure from the ray's direction (1e-16 of the distance covered).
    using Prism = SunPrism;

    // The prism of the points `which`.
    static Prism make_prism(const Tile& t, uint64_t which, double extent) {
        Prism P{{INFINITY, INFINITY}, {-INFINITY, -INFINITY}, INFINITY, 0, 0};
        for (uint64_t b = which; b; b &= b - 1) {
            const uint32_t i = math::lowest_bit(b);
            P.lo[0] = std::min(P.lo[0], t.u[i]);
            P.hi[0] = std::max(P.hi[0], t.u[i]);
            P.lo[1] = std::min(P.lo[1], t.v[i]);
            P.hi[1] = std::max(P.hi[1], t.v[i]);
            P.low = std::min(P.low, t.w[i]);
            P.size = std::max(P.size, std::fabs(t.u[i]) + std::fabs(t.v[i]) + std::fabs(t.w[i]));
        }
        P.margin = 1e-9 * (extent + P.size);
        return P;
    }

    // The points of `in` whose ray may meet sphere s: the ray passes within its radius (grown by `margin`)
    // across the direction, and the sphere reaches above the point. Every ray runs along w, so both are
    // comparisons of coordinates.
    static uint64_t sphere_points(const Sphere& s, uint64_t in, const Tile& t, double margin) {
        const double r = s.r + margin;
        return sun_disc_points(s.u, s.v, r, s.w + r, in, t.u, t.v, t.w);
    }

    // Whether sphere s may meet prism P at all.
    static bool meets_prism(const Sphere& s, const Prism& P) {
        const double r = s.r + P.margin;
        return s.u + r >= P.lo[0] && s.u - r <= P.hi[0] && s.v + r >= P.lo[1] && s.v - r <= P.hi[1] && s.w + r >= P.low;
    }

    // The spheres [first, first + count) of bounds() that may meet the rays of the points `in`, each to
    // pass(i, sphere, points) with those points whose ray may meet it. On a small tile in float: the prism's
    // five planes (its four sides across the direction and its bottom) against a vector of spheres at once,
    // then each sphere kept against a vector of points (sun_sphere_points, cb_tile.h). The margin, 1e-6 of the
    // spheres' extent and the points' sizes, is far above the float products' errors (a few 1e-7 of them)
    // and the rounding of the frame to float (6e-8).
    template <class Pass>
    void scan_spheres(uint32_t first_sphere, uint32_t count, uint64_t in, const Tile& t, Pass pass) const {
        const ScanBounds& s = bounds();
        const Prism P = make_prism(t, in, s.extent);
        const double slack = 1e-6 * (s.extent + P.size);
        const uint32_t stop = first_sphere + count;
        if (!t.small || !(slack > 1e-15)) {  // float could overflow, or its squares fall to subnormals
            for (uint32_t i = first_sphere; i < stop; ++i) {
                const Sphere sphere = across(i);
                if (!meets_prism(sphere, P)) continue;
                const uint64_t points = sphere_points(sphere, in, t, P.margin);
                if (points) pass(i, sphere, points);
            }
            return;
        }
        const double bound[5] = {P.lo[0], -P.hi[0], P.lo[1], -P.hi[1], P.low};
        const double* axis[5] = {frame_[1], frame_[1], frame_[2], frame_[2], frame_[0]};
        SpherePlanes planes;
        for (int q = 0; q < 5; ++q) {
            const double sign = q == 1 || q == 3 ? -1 : 1;
            planes.nx[q] = float(sign * axis[q][0]);
            planes.ny[q] = float(sign * axis[q][1]);
            planes.nz[q] = float(sign * axis[q][2]);
            planes.side[q] = math::round_down(bound[q] - slack);
        }
        for (uint32_t first = first_sphere; first < stop; first += 64) {
            // bit j: sphere first + j may meet the prism
            for (uint64_t keep = spheres_passing(s, first, std::min<uint32_t>(64, stop - first), planes); keep;
                 keep &= keep - 1) {
                const uint32_t i = first + math::lowest_bit(keep);
                const Sphere sphere = across(i);
                const uint64_t points =
                    sun_sphere_points(sphere.u, sphere.v, sphere.w, sphere.r, slack, in, t.fu, t.fv, t.fw);
                if (points) pass(i, sphere, points);
            }
        }
    }

    // Box axis k as the sun's separating-axis tests take it (sun_box in float, double_box_points in double):
    // the axis, the way the ray heads along it (sign; 0 where it runs nearly across it: no test there), how
    // far along it the ray has gone at blocking_start (lift), and the axis z x a across the ray (w).
    struct RayAxis {
        double a[3], sign, lift, w[3];
    };
    RayAxis ray_axis(const Obb& box, int k) const {
        RayAxis r;
        for (int j = 0; j < 3; ++j) r.a[j] = box.axis[k][j];
        const double zk = math::dot3(r.a, frame_[0]);
        r.sign = zk > 1e-6 ? 1 : zk < -1e-6 ? -1 : 0;
        r.lift = start_ * zk;
        math::cross3(frame_[0], r.a, r.w);
        return r;
    }

    // A cluster's box set up for box_points (SunBox, cb_tile.h).
    SunBox sun_box(const Obb& box) const {
        SunBox b;
        const ScanBounds& s = bounds();
        double h[3];
        padded_halves(box, h);
        double scale = h[0] + h[1] + h[2];
        for (int k = 0; k < 3; ++k) {
            const double c = box.center[k] - s.origin[k];
            b.c[k] = float(c);
            scale += std::fabs(c);
            const RayAxis r = ray_axis(box, k);
            for (int j = 0; j < 3; ++j) b.a[k][j] = box.axis[k][j];
            b.sign[k] = float(r.sign);
            b.h[k] = r.sign != 0 ? float(h[k]) : INFINITY;
            b.lift[k] = float(r.lift);
            for (int j = 0; j < 3; ++j) b.w[k][j] = float(r.w[j]);
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
    // them each) and the float direction's departure from the ray's (6e-8 of the way to the box). `unsure`
    // gets the points kept that would not be with the margin taken off instead (whose ray may miss the box).
    static uint64_t box_points(const SunBox& b, uint64_t subset, const Tile& t, uint64_t& unsure) {
        using simd::Floats;
        uint32_t begin, end;
        unsure = subset;
        if (!subset) return 0;
        simd::lane_span(subset, begin, end);
        if (!(b.scale + t.size > 1e-30f)) return subset;  // a margin that float's subnormals could swallow
        const Floats m = simd::splat(1e-6f * (b.scale + t.size)), zero = simd::splat(0.0f), m2 = m + m;
        uint64_t keep = 0, sure = 0;
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
            sure |= uint64_t(simd::bits(worst >= m2)) << i;
        }
        unsure = subset & keep & ~sure;
        return subset & keep;
    }

    // Fine cluster f's box set up for box_points, from the batch's cache when it holds it (and left there).
    const SunBox& fine_sun_box(uint32_t f, TileCache* cache, SunBox& own) const {
        if (!cache) return own = sun_box(bounds().fine_obbs[f]);
        const uint32_t slot = TileCache::box_slot(this, f);
        if (cache->box_owner[slot] != this || cache->box_cluster[slot] != f) {
            cache->sun_box[slot] = sun_box(bounds().fine_obbs[f]);
            cache->box_owner[slot] = this;
            cache->box_cluster[slot] = f;
        }
        return cache->sun_box[slot];
    }

    // The points of `subset` whose ray, from blocking_start on, may touch `box`: box_points' separating axes
    // in double, point by point, without a division. Along a box axis the stored box is its slab (cb_asset.h),
    // so half[k] bounds it exactly; across the ray, the padded halves. The margin, 1e-9 of the sizes involved,
    // is far above double's rounding and the frame's departure from the ray's direction (1e-16 of the way to
    // the box), and far below a bias: a point on a flat cluster, whose ray leaves its thin box as it starts to
    // count, is settled here (the float test cannot).
    uint64_t double_box_points(const Obb& box, uint64_t subset, const Tile& t) const {
        if (!subset) return 0;
        double h[3], support[3];
        padded_halves(box, h);
        const RayAxis r[3] = {ray_axis(box, 0), ray_axis(box, 1), ray_axis(box, 2)};
        for (int k = 0; k < 3; ++k)
            support[k] = h[0] * std::fabs(math::dot3(r[k].w, r[0].a)) + h[1] * std::fabs(math::dot3(r[k].w, r[1].a)) +
                h[2] * std::fabs(math::dot3(r[k].w, r[2].a));
        const double extent = h[0] + h[1] + h[2] + start_;
        for (uint64_t b = subset; b; b &= b - 1) {
            const uint32_t i = math::lowest_bit(b);
            const double q[3] = {t.p[i][0] - box.center[0], t.p[i][1] - box.center[1], t.p[i][2] - box.center[2]};
            const double margin = 1e-9 * (std::fabs(q[0]) + std::fabs(q[1]) + std::fabs(q[2]) + extent);
            bool apart = false;  // NaN or infinity anywhere: kept
            for (int k = 0; k < 3; ++k)
                apart = apart || r[k].sign * (math::dot3(q, r[k].a) + r[k].lift) > double(box.half[k]) + margin ||
                    std::fabs(math::dot3(q, r[k].w)) > support[k] + margin;
            if (apart) subset &= ~(uint64_t(1) << i);
        }
        return subset;
    }

    // The points of `subset` whose ray may touch fine cluster f's box: in float when the tile allows (`unsure`
    // gets those the float test could not settle), else in double.
    uint64_t fine_box_points(uint32_t f, uint64_t subset, const Tile& t, uint64_t& unsure) const {
        unsure = 0;
        if (!subset) return 0;
        SunBox own;
        if (t.small) return box_points(fine_sun_box(f, t.cache, own), subset, t, unsure);
        return double_box_points(bounds().fine_obbs[f], subset, t);
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

    bool disc_trees() const { return traversal_ == Traversal::mtsv_one || traversal_ == Traversal::mtsv_two; }
    bool two_levels() const { return traversal_ == Traversal::top_two || traversal_ == Traversal::mtsv_two; }

    // Sphere i of bounds() as a disc across the direction, for cluster `id`.
    SunDisc disc(uint32_t i, uint32_t id) const {
        const Sphere s = across(i);
        return {s.u, s.v, s.r, s.w + s.r, id};
    }

    // The trees options.traversal names, over the clusters the sun may not see entirely from the front.
    void build_trees() {
        const ScanBounds& s = bounds();
        std::vector<uint32_t> order;
        std::vector<SunDisc> discs;
        // One tree over clusters [first, first + count) of one level, whose boxes are `boxes` (indexed by
        // cluster) and spheres those of bounds() from `first_sphere` on; those `skip` names are left out.
        // Returns its root.
        auto tree = [&](uint32_t first, uint32_t count, const Obb* boxes, uint32_t first_sphere, auto skip) {
            if (disc_trees()) {
                discs.clear();
                for (uint32_t i = 0; i < count; ++i)
                    if (!skip(first + i)) discs.push_back(disc(first_sphere + i, first + i));
                return discs_.build(discs.data(), uint32_t(discs.size()));
            }
            uint32_t root = none;
            insertion_order(count, order);
            for (uint32_t i : order)
                if (!skip(first + i)) lines_.insert(root, sun_box_prism(boxes[first + i], s.origin, frame_), first + i);
            return root;
        };
        auto fine_skipped = [&](uint32_t f) { return fine_faces_the_sun(f); };
        if (!two_levels()) {
            root_ = tree(0, mesh_->fine_count, s.fine_obbs.data(), 0, fine_skipped);
        } else {
            fine_roots_.assign(mesh_->coarse_count, none);
            for (uint32_t c = 0; c < mesh_->coarse_count; ++c) {
                const ClusterRange& r = view_->coarse[mesh_->first_coarse + c];
                if (!coarse_skipped_[c])
                    fine_roots_[c] = tree(r.first, r.count, s.fine_obbs.data(), r.first, fine_skipped);
            }
            root_ = tree(0, mesh_->coarse_count, s.coarse_obbs.data(), s.coarse_first,
                         [&](uint32_t c) { return coarse_skipped_[c] != 0; });
        }
        tree_stack_ = disc_trees() ? 0 : lines_.stack_size();
    }

    // The walk of the tree at `root` by the points `in`: pass(id, top, points) for each volume that may hold
    // some of them still alive.
    template <class Pass>
    void walk_tree(uint32_t root, uint64_t in, Tile& t, uint32_t* stack, Pass pass) const {
        const Prism P = make_prism(t, in, bounds().extent);
        if (disc_trees())
            discs_.walk(root, in, t.alive, t.u, t.v, t.w, P, pass);
        else
            lines_.walk(root, in, t.alive, t.u, t.v, t.w, P, stack, pass);
    }

    // Fine cluster f for the points `points` whose ray may meet its volume, whose top is `top`: its box in
    // float, then the pending list.
    void add_pending(uint32_t f, double top, uint64_t points, Tile& t) const {
        uint64_t unsure;
        points = fine_box_points(f, points & t.alive, t, unsure);
        if (!points) return;
        if (t.pending_count == Tile::pending_capacity) test_pending(t);
        t.pending[t.pending_count++] = {-top, f, points, unsure};
    }

    // The coarse clusters whose volumes the tile's points may meet, with those points, onto the entered list
    // (one tree: the fine clusters, onto the pending list). The coarse walk takes the stack's first half.
    void find_coarse(Tile& t, uint32_t* stack) const {
        auto enter = [&](uint32_t c, double top, uint64_t points) {
            points &= t.alive;  // less once the entered list filled up and was walked
            if (coarse_skipped_[c] || !points) return;
            uint64_t unsure;  // coarse boxes are not tested again
            points = t.small ? box_points(coarse_boxes_[c], points, t, unsure)
                             : double_box_points(bounds().coarse_obbs[c], points, t);
            if (!points) return;
            if (t.entered_count == Tile::entered_capacity) walk_entered(t, stack);
            t.entered[t.entered_count++] = {-top, c, points, 0};
        };
        if (traversal_ == Traversal::scan) {
            const uint32_t first = bounds().coarse_first;
            scan_spheres(first, mesh_->coarse_count, t.alive, t,
                         [&](uint32_t i, const Sphere& s, uint64_t points) { enter(i - first, s.w + s.r, points); });
        } else if (two_levels()) {
            walk_tree(root_, t.alive, t, stack, enter);
        } else {
            walk_tree(root_, t.alive, t, stack,
                      [&](uint32_t f, double top, uint64_t points) { add_pending(f, top, points, t); });
        }
    }

    // The entered coarse clusters, the sun's side first: their fine clusters found (scan or tree, on the
    // stack's second half), each one's tested before the next coarse cluster's.
    void walk_entered(Tile& t, uint32_t* stack) const {
        const uint32_t count = t.entered_count;
        t.entered_count = 0;
        sort_by_near(t.entered, count);
        for (uint32_t e = 0; e < count && t.alive; ++e) {
            const uint64_t in = t.entered[e].points & t.alive;
            if (!in) continue;
            const uint32_t c = t.entered[e].id;
            if (traversal_ == Traversal::scan) {
                const ClusterRange& r = view_->coarse[mesh_->first_coarse + c];
                scan_spheres(r.first, r.count, in, t, [&](uint32_t f, const Sphere& sphere, uint64_t points) {
                    if (!fine_faces_the_sun(f)) add_pending(f, sphere.w + sphere.r, points, t);
                });
            } else {
                walk_tree(fine_roots_[c], in, t, stack + tree_stack_,
                          [&](uint32_t f, double top, uint64_t points) { add_pending(f, top, points, t); });
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
        for (uint32_t e = 0; e < count && t.alive; ++e) {
            const uint32_t f = t.pending[e].id;
            uint64_t points = t.pending[e].points & t.alive;
            // The box again in double for the points the float test did not settle: its margin lets through
            // the cluster a point lies on, whose ray leaves the thin box soon after it starts to count; its
            // triangles cost far more.
            const uint64_t unsure = points & t.pending[e].unsure;
            points = (points & ~unsure) | double_box_points(bounds().fine_obbs[f], unsure, t);
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
    Traversal traversal_ = Traversal::scan;
    double inverse_[12] = {}, toward_[3] = {}, world_toward_[3] = {}, frame_[3][3] = {}, from_ = 0;
    double start_ = 0;  // blocking_start(from_) along the unit direction frame_[0]
    bool usable_ = false, one_sided_ = false, spheres_ = false, boxes_small_ = false;
    const ScanBounds* shared_bounds_ = nullptr;
    ScanBounds own_bounds_;
    std::vector<SunBox> coarse_boxes_;     // the coarse boxes set up for box_points (when boxes_small_)
    std::vector<uint8_t> coarse_skipped_;  // one-sided: coarse clusters the sun sees from the front
    SunLineTree lines_;                    // Traversal::top_two and top_one
    SunDiscTree discs_;                    // Traversal::mtsv_one and mtsv_two
    uint32_t root_ = none;                 // the coarse tree (one tree: the fine tree)
    std::vector<uint32_t> fine_roots_;     // two levels: each coarse cluster's fine tree
    size_t tree_stack_ = 0;                // stack entries a line tree's walk needs
    size_t skipped_ = 0;
};

}  // namespace CB_LANES
}  // namespace cb
