// The scan traversal (Traversal::scan, the default): no tree. A cluster's shadow volume is taken as the cone
// from the light around its bounding sphere (about its box). A batch's tile of points checks every coarse
// cluster's sphere against the pyramid from the light that holds the tile's directions, its points against
// the boxes of those that pass, then the fine spheres of the coarse clusters entered, a vector of spheres an
// instruction. The spheres and decoded boxes do not depend on the light (ScanBounds, made once per asset),
// so a light's build only sets up the coarse boxes: a linear pass over a few thousand coarse spheres per
// tile costs less than building and walking a tree over their volumes every frame (docs/PERFORMANCE.md).
// Header-only C++17, no exceptions; building allocates, queries do not. MIT licensed (runtime/LICENSE).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "../cb_asset.h"
#include "cb_math.h"
#include "../cb_scan_bounds.h"
#include "cb_simd.h"
#include "cb_tile.h"

namespace cb {
inline namespace CB_LANES {

class ScanTraversal : public TraversalBase {
public:
    // One instance of the asset's meshes, for one light given in world space (options.traversal is not read:
    // the asset must have coarse boxes, otherwise the clusters are found by TopTreeTraversal).
    void build(const AssetView& view, uint32_t instance, const double* world_light, const ShadowBuildOptions& options) {
        build(view, placement_of(view, instance), world_light, options);
    }
    // The same for a mesh of the asset placed by the caller (a runtime scene's instance).
    void build(const AssetView& view, Placement at, const double* world_light, const ShadowBuildOptions& options) {
        shared_bounds_ = nullptr;
        coarse_boxes_.clear();
        coarse_skipped_.clear();
        if (!set_instance(view, at, world_light, options.one_sided, options.bias)) return;
        const uint32_t coarse_count = mesh_->coarse_count;
        const uint32_t m = at.mesh;
        const ScanBounds* bounds = options.bounds;
        shared_bounds_ = bounds && bounds[m].made_from(view, *mesh_) ? &bounds[m] : nullptr;
        if (!shared_bounds_) own_bounds_.make(view, m);
        const ScanBounds& s = scan_bounds();
        for (int k = 0; k < 3; ++k) light_from_origin_[k] = light_[k] - s.origin[k];
        spheres_small_ = s.extent + math::l1(light_from_origin_) < float_safe;
        coarse_boxes_.resize(coarse_count);
        coarse_skipped_.assign(coarse_count, 0);
        for (uint32_t c = 0; c < coarse_count; ++c) {
            coarse_boxes_[c] =
                box_filter(s.coarse_obbs.empty() ? view.coarse_bounds.obb(mesh_->first_coarse + c) : s.coarse_obbs[c]);
            if (one_sided_ && skippable(view.coarse_bounds, mesh_->first_coarse + c, coarse_triangles(c))) {
                skipped_ += view.coarse[mesh_->first_coarse + c].count;
                coarse_skipped_[c] = 1;
            }
        }
    }

    // The scan walks no tree: the stack is passed along only.
    size_t stack_size() const { return 4; }

    // True when the segment from world point p to the light is blocked by this instance: a tile of one point
    // (which goes alone when it must, see occluded_tile); a batch is far faster per point.
    bool occluded(const double* world_p, uint32_t* stack, QueryStats* stats = nullptr) const {
        if (!usable_ || !finite3(world_p)) return false;  // a point that is not finite is never in shadow
        const uint32_t first = 0;
        return occluded_tile(world_p, &first, 1, 1, stack, stats) != 0;
    }

    // Of the `count` world points points + 3 * index[i] (xyz doubles), those set in `alive` that this
    // instance shadows, as a mask; the same answers as occluded() point by point. Points over 60 degrees off
    // the tile's mean direction make tiles of one; points at the light, not finite or beyond 1e30 go alone,
    // past every sphere in double. Uses about 13 KB of the thread's stack, twice that for a tile of one
    // inside (and a cluster test's, docs/RUNTIME.md).
    uint64_t occluded_tile(const double* points, const uint32_t* index, uint32_t count, uint64_t alive, uint32_t* stack,
                           QueryStats* stats = nullptr, TileCache* cache = nullptr) const {
        if (!usable_ || alive == 0) return 0;
        Tile t;
        uint64_t alone;
        const uint64_t off = start_tile(t, points, index, count, alive, stats, cache, fine_obbs(), alone);
        // The points over 60 degrees off the tile's mean direction make tiles of one; the others that go
        // alone walk every sphere in double.
        return walk_tile(
            t, alone | off, [&] { scan_coarse(t); }, [&](uint32_t c, uint64_t in) { enter_coarse(c, in, t); },
            [&](uint32_t i) {
                return off >> i & 1 ? occluded_tile(points, index + i, 1, 1, stack, stats, cache) != 0
                                    : walk_alone(points + size_t(index[i]) * 3, stats);
            });
    }

    size_t node_count() const { return 0; }
    size_t always_tested() const { return 0; }
    // Bytes this traversal holds (the asset and shared ScanBounds it reads are not counted).
    size_t memory_bytes() const {
        return own_bounds_.memory_bytes() + coarse_boxes_.capacity() * sizeof(BoxFilter) + coarse_skipped_.capacity();
    }

private:
    const ScanBounds& scan_bounds() const { return shared_bounds_ ? *shared_bounds_ : own_bounds_; }
    const Obb* fine_obbs() const { return scan_bounds().fine_obbs.empty() ? nullptr : scan_bounds().fine_obbs.data(); }

    // One point on its own, in double, against every sphere (for the points a tile cannot take: beside the
    // light or beyond float's range).
    bool walk_alone(const double* world_p, QueryStats* stats) const {
        if (!usable_ || !finite3(world_p)) return false;
        const Query q = make_query(world_p, stats, fine_obbs());
        if (!may_block(q.from)) return false;  // within the bias of the light
        if (!(q.dist > 0)) return false;       // at the light: the segment is a point, which blocks nothing
        const ScanBounds& s = scan_bounds();
        const bool spheres = s.source_fine != nullptr;  // none without fine boxes: every cluster is tested
        for (uint32_t c = 0; c < mesh_->coarse_count; ++c) {
            if ((one_sided_ && coarse_skipped_[c]) || (spheres && !segment_may_touch_sphere(s.coarse_first + c, q)))
                continue;
            const ClusterRange& r = view_->coarse[mesh_->first_coarse + c];
            for (uint32_t f = r.first; f < r.first + r.count; ++f)
                if ((!spheres || segment_may_touch_sphere(f, q)) && !skippable_fine(f) && test_cluster(f, q))
                    return true;
        }
        return false;
    }

    // Coarse cluster c entered by the points `in`: its fine spheres scanned (walk_entered).
    void enter_coarse(uint32_t c, uint64_t in, Tile& t) const {
        const ClusterRange& r = view_->coarse[mesh_->first_coarse + c];
        if (r.count == 1 && float_tests(t)) {
            // Its only fine cluster holds the same triangles: the coarse sphere and box the points passed are
            // its own tests, near enough (its box comes next, in test_pending); scan_coarse tests the coarse
            // box only with the float tests, hence the condition.
            const uint32_t f = r.first;
            if (skippable_fine(f)) return;
            const double* axis = t.frame[0];
            prefetch(f);
            // (sphere f is fine cluster f's: the fine spheres come first in the scan bounds)
            add_pending(t, near_key(lit_sphere(f), float(axis[0]), float(axis[1]), float(axis[2])), f, in);
            return;
        }
        scan_fine({r.first, r.count}, in, t);
    }

    // Sphere i of scan_bounds() from the light, for the float tests of sphere_points: the centre in
    // float, the radius grown by 2e-5 of itself and of the distance (|d|_1 bounds it), far more than the
    // rounding of the centre to float (below 1e-7 of the distance) and the errors of the float tests (below
    // 1e-6). A sphere wholly within float_tiny of the light holds every point (float products of such sizes
    // could fall to subnormals).
    struct LitSphere {
        float x, y, z, r;
        bool everything;
    };
    LitSphere lit_sphere(uint32_t i) const {
        const ScanBounds& s = scan_bounds();
        const double x = double(s.x[i]) - light_from_origin_[0], y = double(s.y[i]) - light_from_origin_[1],
                     z = double(s.z[i]) - light_from_origin_[2];
        const double d1 = std::fabs(x) + std::fabs(y) + std::fabs(z), r = s.r[i], grown = r + 2e-5 * (r + d1);
        return {float(x), float(y), float(z), float(grown), d1 + grown < float_tiny};
    }

    // The key that orders sphere s's cluster by distance from the light: its nearest reach along the tile's
    // axis (ax, ay, az).
    static float near_key(const LitSphere& s, float ax, float ay, float az) {
        return s.x * ax + s.y * ay + s.z * az - s.r;
    }

    // Whether the float tests (the pyramid against spheres, spheres and boxes against the tile's points)
    // may run: the tile's coordinates and every sphere's, and the light's, within float_safe.
    bool float_tests(const Tile& t) const { return t.small && spheres_small_; }

    // Conservative, in double: the segment from the query point to the light may meet sphere i.
    bool segment_may_touch_sphere(uint32_t i, const Query& q) const {
        const ScanBounds& s = scan_bounds();
        const double c[3] = {double(s.x[i]) - light_from_origin_[0], double(s.y[i]) - light_from_origin_[1],
                             double(s.z[i]) - light_from_origin_[2]};
        const double r = s.r[i];
        double t = (c[0] * q.e[0] + c[1] * q.e[1] + c[2] * q.e[2]) / q.dist;
        t = std::min(std::max(t, 0.0), q.dist);
        double d2 = 0;
        for (int k = 0; k < 3; ++k) {
            double x = c[k] - t * q.e[k] / q.dist;
            d2 += x * x;
        }
        double reach = r * (1 + 1e-9) + 1e-9 * (q.dist + math::l1(c));
        return d2 <= reach * reach;
    }

    // The points of `subset` whose segment to the light may meet sphere s (lit_sphere_points).
    uint64_t sphere_points(const LitSphere& s, uint64_t subset, const Tile& t) const {
        return lit_sphere_points(s.x, s.y, s.z, s.r, subset, t.ex, t.ey, t.ez, t.fd);
    }

    // Asks for fine cluster f's decoded box and record ahead of its test (pending clusters are
    // tested once the whole coarse cluster is scanned): on large meshes these reads otherwise miss the cache.
    void prefetch(uint32_t f) const {
        const std::vector<Obb>& boxes = scan_bounds().fine_obbs;
        if (!boxes.empty()) {
            const char* box = reinterpret_cast<const char*>(&boxes[f]);
            simd::prefetch(box);
            simd::prefetch(box + sizeof(Obb) - 1);  // it may straddle two lines
        }
        simd::prefetch(view_->fine + size_t(mesh_->first_fine) + f);
    }

    // The scan over spheres [first, first + count) of scan_bounds() for the tile's points `in`: those
    // that may meet the pyramid of these points, nearer the light than the farthest, go to
    // pass(sphere, points, key) with the points whose segment may meet them (every point of `in` when
    // `each_point` is false) and a key that orders them by distance from the light. When the float tests
    // could overflow, every sphere passes with every point.
    //
    // A sphere (centre c from the light, radius r) may meet the pyramid only if it reaches the inside of
    // each side plane, n . c + r >= 0, and of the plane across the tile's axis z at the farthest point's
    // distance, -z . c + r >= -dmax. The centres are stored from the spheres' origin o, so with c = s - l
    // (l the light from o), each test is n . s + r >= n . l (the right side once per scan, in double):
    // one instruction tests a whole vector of spheres. The right sides are lowered by 1e-6 of |s|_1 + |l|_1 +
    // dmax, above the float products' errors (3 float epsilons of |s|_1) and the rounding of n (the pyramid's
    // tolerance, which make_pyramid leaves for it).
    template <bool each_point, class Pass>
    void scan_spheres(uint32_t first_sphere, uint32_t count, uint64_t in, Tile& t, Pass pass) const {
        if (!float_tests(t)) {
            for (uint32_t i = first_sphere; i < first_sphere + count; ++i) pass(i, in, 0.0f);
            return;
        }
        const Pyramid whole = narrow_pyramid(t, in);
        const Pyramid& P = t.pyramid;
        const double* l = light_from_origin_;
        const double slack = 1e-6 * (scan_bounds().extent + math::l1(l) + P.dmax);
        SpherePlanes planes;
        float(&nx)[5] = planes.nx, (&ny)[5] = planes.ny, (&nz)[5] = planes.nz, (&side)[5] = planes.side;
        double sum[3] = {0, 0, 0};
        for (int r = 0; r < 4; ++r) {
            sum[0] += P.rx[r];
            sum[1] += P.ry[r];
            sum[2] += P.rz[r];
        }
        for (int r = 0; r < 4; ++r) {
            int q = (r + 1) & 3;
            double a[3] = {P.rx[r], P.ry[r], P.rz[r]}, b[3] = {P.rx[q], P.ry[q], P.rz[q]}, n[3];
            math::cross3(a, b, n);
            double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            if (math::dot3(n, sum) < 0) len = -len;
            if (!(len != 0)) {
                nx[r] = ny[r] = nz[r] = 0;
                side[r] = -INFINITY;
                continue;
            }
            const double inv = 1 / len;
            nx[r] = float(n[0] * inv);
            ny[r] = float(n[1] * inv);
            nz[r] = float(n[2] * inv);
            side[r] = math::round_down(nx[r] * l[0] + ny[r] * l[1] + nz[r] * l[2] - slack);
        }
        const double* axis = t.frame[0];
        nx[4] = float(-axis[0]);
        ny[4] = float(-axis[1]);
        nz[4] = float(-axis[2]);
        side[4] = math::round_down(nx[4] * l[0] + ny[4] * l[1] + nz[4] * l[2] - P.dmax - slack);
        const float ax = float(axis[0]), ay = float(axis[1]), az = float(axis[2]);
        const ScanBounds& s = scan_bounds();
        const uint32_t stop = first_sphere + count;
        for (uint32_t first = first_sphere; first < stop; first += 64) {
            // bit j: sphere first + j may meet the pyramid
            for (uint64_t keep = spheres_passing(s, first, std::min<uint32_t>(64, stop - first), planes); keep;
                 keep &= keep - 1) {
                const uint32_t i = first + math::lowest_bit(keep);
                const LitSphere lit = lit_sphere(i);
                const uint64_t points = lit.everything || !each_point ? in : sphere_points(lit, in, t);
                if (points) pass(i, points, near_key(lit, ax, ay, az));
            }
        }
        t.pyramid = whole;
    }

    // The coarse clusters whose spheres the tile's pyramid may meet, with the points whose segment may meet
    // their boxes (or spheres, where a box's float test could overflow), onto the entered list.
    void scan_coarse(Tile& t) const {
        const uint32_t first = scan_bounds().coarse_first;
        const bool narrow = float_tests(t);
        scan_spheres<false>(first, mesh_->coarse_count, t.alive, t, [&](uint32_t i, uint64_t points, float key) {
            const uint32_t c = i - first;
            if (one_sided_ && coarse_skipped_[c]) return;
            if (narrow) {
                const BoxFilter& b = coarse_boxes_[c];
                points = b.usable ? box_points(b, points, t) : sphere_points(lit_sphere(i), points, t);
                if (!points) return;
            }
            add_entered(t, key, c, points, [&](uint32_t id, uint64_t in) { enter_coarse(id, in, t); });
        });
    }

    // The fine clusters `range` of an entered coarse cluster whose spheres may meet the segments of the
    // points `in`, onto the pending list.
    void scan_fine(IndexRange range, uint64_t in, Tile& t) const {
        scan_spheres<true>(range.first, range.count, in, t, [&](uint32_t f, uint64_t points, float key) {
            if (skippable_fine(f)) return;
            prefetch(f);
            add_pending(t, key, f, points);
        });
    }

    // The scan bounds (shared, or the traversal's own), the light from their origin, the coarse boxes set up
    // for this light, and which coarse clusters one-sided mode leaves out.
    const ScanBounds* shared_bounds_ = nullptr;
    ScanBounds own_bounds_;
    double light_from_origin_[3] = {};
    std::vector<BoxFilter> coarse_boxes_;
    std::vector<uint8_t> coarse_skipped_;
    bool spheres_small_ = false;  // every sphere's coordinates and radius, and the light's, below float_safe
};

}  // namespace CB_LANES
}  // namespace cb
