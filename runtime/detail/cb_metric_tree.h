// The metric-tree traversal (Traversal::mtsv_one and Traversal::mtsv_two, the thesis's chapter 3): shadow
// volumes partitioned by their angular distance from each other as seen from the light, rather than by
// planes. Each fine cluster's volume is a sphere or a capsule; seen from the light a sphere is a cone (the
// directions within alpha = asin(r / |c - light|) of its centre) and a capsule a capsule-cone (the
// directions within alpha of the arc its segment spans, alpha taken where the segment is nearest the light,
// so the widest). One node per volume (a TOP-tree needs four plane nodes and a cluster node).
//
// A node's pivot splits the volumes below it by s(u) = angle(u, pivot's centre) - pivot's alpha, the
// angular distance of a direction u outside the pivot's cone: the near child holds volumes whose every
// direction has s <= delta, the far child those whose every direction has s > delta, the overlap child the
// rest; each child keeps the range of s over its volumes (the overlap child [min, max], the near child its
// least, the far child its most). A query direction u in a volume below a node satisfies
// that child's bound, so the walk skips the others; it tests the cluster of every volume that holds u,
// then its slab (two planes across its normal cone's axis, when the asset has slabs), its box (when it
// has boxes) and its triangles, exactly (cb_lit_triangles.h): the answers are occluded_reference's.
//
// Two builds (ShadowBuildOptions::metric_build, cb_metric_build.h): the thesis's heuristic inserts the volumes one
// by one in a shuffled order (fixed seed), each carrying a split distance that starts at the angle of the cone
// holding the whole scene and halves on each near step, and becomes its delta when it reaches a leaf; the reference
// picks as pivot the sampled volume farthest from the others and splits at the median distance (slower, to measure
// the heuristic against). Every node keeps the smallest light distance of its subtree: a point nearer the light
// skips it. Traversal::mtsv_two walks a tree over the coarse clusters' volumes whose nodes enter a tree over their
// fine clusters; Traversal::mtsv_one one tree over all fine clusters.
//
// Volumes: the asset's spheres and capsules when it has them (bake --bounds all), otherwise the sphere and
// capsule about each box. A capsule is used when its length (with its caps) is at least capsule_aspect
// times its width. Angles are worked out in double from the stored floats; every stored angle is rounded
// outward with a margin for the directions' rounding to float, and every comparison of the walk has a
// tolerance of 1e-7 radians, so a volume is never skipped for a point it could block. Header-only C++17,
// no exceptions; building allocates (std::vector), queries do not. MIT licensed (runtime/LICENSE).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "../cb_asset.h"
#include "cb_math.h"
#include "cb_metric_build.h"
#include "cb_tile.h"

namespace cb {
inline namespace CB_LANES {

class MetricTreeTraversal : public TraversalBase {
public:
    using Node = metric_tree::Node;

    // One instance of the asset's meshes, for one light given in world space: two levels when
    // options.traversal is Traversal::mtsv_two and the asset has coarse volumes, else one tree.
    void build(const AssetView& view, uint32_t instance, const double* world_light, const ShadowBuildOptions& options) {
        build(view, placement_of(view, instance), world_light, options);
    }
    // The same for a mesh of the asset placed by the caller (a runtime scene's instance).
    void build(const AssetView& view, Placement at, const double* world_light, const ShadowBuildOptions& options) {
        nodes_.clear();
        always_fine_.clear();
        always_coarse_.clear();
        fine_roots_.clear();
        fine_always_.clear();
        coarse_boxes_.clear();
        root_ = none;
        depth_ = 0;
        capsules_ = 0;
        top_always_ = {};
        if (!set_instance(view, at, world_light, options.one_sided, options.bias)) return;
        capsule_aspect_ = options.capsule_aspect;
        build_ = options.metric_build;
        slabs_ = view.fine_bounds.slabs != nullptr;
        const bool two = options.traversal == Traversal::mtsv_two &&
            (view.coarse_bounds.spheres || view.coarse_bounds.obbs) && mesh_->coarse_count > 0;
        metric_tree::Work& w = work_;
        w.built.clear();
        if (!two) {
            std::vector<uint32_t> fine(mesh_->fine_count);
            for (uint32_t f = 0; f < mesh_->fine_count; ++f) fine[f] = f;
            uint32_t depth = 0;
            root_ = build_level(view.fine_bounds, mesh_->first_fine, fine, false, always_fine_, depth);
            top_always_ = {0, uint32_t(always_fine_.size())};
            depth_ = depth;
        } else {
            const uint32_t coarse_count = mesh_->coarse_count;
            fine_roots_.assign(coarse_count, none);
            fine_always_.assign(coarse_count, {});
            // The coarse boxes set up for this light: a coarse cone is loose (a sphere about a large cluster),
            // so the points that enter it are kept to those whose segment may meet its box.
            if (view.coarse_bounds.obbs) {
                coarse_boxes_.resize(coarse_count);
                for (uint32_t c = 0; c < coarse_count; ++c)
                    coarse_boxes_[c] = box_filter(view.coarse_bounds.obb(mesh_->first_coarse + c));
            }
            std::vector<uint32_t> coarse, fine;
            uint32_t fine_depth = 0;
            for (uint32_t c = 0; c < coarse_count; ++c) {
                const ClusterRange& r = view.coarse[mesh_->first_coarse + c];
                if (one_sided_ && skippable(view.coarse_bounds, mesh_->first_coarse + c, coarse_triangles(c))) {
                    skipped_ += r.count;
                    continue;
                }
                coarse.push_back(c);
                fine.resize(r.count);
                for (uint32_t k = 0; k < r.count; ++k) fine[k] = r.first + k;
                uint32_t first = uint32_t(always_fine_.size()), depth = 0;
                fine_roots_[c] = build_level(view.fine_bounds, mesh_->first_fine, fine, false, always_fine_, depth);
                fine_always_[c] = {first, uint32_t(always_fine_.size()) - first};
                fine_depth = std::max(fine_depth, depth);
            }
            uint32_t coarse_depth = 0;
            std::vector<uint32_t> around;  // coarse clusters whose volumes hold the light
            root_ = build_level(view.coarse_bounds, mesh_->first_coarse, coarse, true, around, coarse_depth);
            always_coarse_ = around;
            depth_ = coarse_depth + fine_depth + 1;
        }
        renumber_in_walk_order();
    }

    // Entries the query stack needs: pending siblings along the deepest path through both levels (a walk
    // that enters a coarse cluster leaves up to three of its node's children waiting while its fine tree is
    // walked).
    size_t stack_size() const { return size_t(depth_) * 3 + 6; }

    // True when the segment from world point p to the light is blocked by this instance. `stack` holds
    // stack_size() entries.
    bool occluded(const double* world_p, uint32_t* stack, QueryStats* stats = nullptr) const {
        if (!usable_ || !finite3(world_p)) return false;  // a point that is not finite is never in shadow
        return walk_alone(world_p, stack, stats);
    }

    // The tile walk: of the `count` world points points + 3 * index[i] (xyz doubles), those set in `alive`
    // that this instance shadows, as a mask; the same answers as occluded() point by point. The tree is
    // walked once with the cone from the light about the tile's mean direction that holds every point's
    // direction: a node is skipped only when no direction in that cone could reach it. Each point is then
    // tested against the volumes the walk meets. Points over 60 degrees off the mean, at the light, not
    // finite or beyond 1e30 walk alone. `stack` holds stack_size() entries.
    uint64_t occluded_tile(const double* points, const uint32_t* index, uint32_t count, uint64_t alive, uint32_t* stack,
                           QueryStats* stats = nullptr, TileCache* cache = nullptr) const {
        if (!usable_ || alive == 0) return 0;
        Tile t;
        uint64_t alone;
        const uint64_t off = start_tile(t, points, index, count, alive, stats, cache, nullptr, alone);
        Directions d;
        auto find = [&] {
            set_directions(t, d);
            for (uint32_t i = top_always_.first; i < top_always_.first + top_always_.count && t.alive; ++i)
                test_points(always_fine_[i], slab_points(always_fine_[i], t.alive, t), t);
            for (uint32_t c : always_coarse_)
                if (t.alive) enter_coarse(c, t.alive, t, d, stack);
            if (root_ != none && t.alive) tile_walk(root_, t.alive, t, d, stack);
        };
        return walk_tile(
            t, alone | off, find, [&](uint32_t c, uint64_t in) { enter_coarse(c, in, t, d, stack); },
            [&](uint32_t i) { return walk_alone(points + size_t(index[i]) * 3, stack, stats); });
    }

    size_t node_count() const { return nodes_.size(); }
    const std::vector<Node>& nodes() const { return nodes_; }  // in walk order; the roots are not marked
    // Bytes this traversal holds (the asset it reads, and the build's working arrays, are not counted).
    size_t memory_bytes() const {
        return nodes_.capacity() * sizeof(Node) +
            (always_fine_.capacity() + always_coarse_.capacity() + fine_roots_.capacity()) * sizeof(uint32_t) +
            fine_always_.capacity() * sizeof(IndexRange) + coarse_boxes_.capacity() * sizeof(BoxFilter);
    }
    size_t always_tested() const { return always_fine_.size(); }
    uint32_t depth() const { return depth_; }

private:
    using Central = metric_tree::Central;
    using Element = metric_tree::Element;
    static constexpr uint32_t coarse_bit = metric_tree::coarse_bit;
    static constexpr double tol = metric_tree::tolerance;

    // The tile's unit directions from the light, and each one's angle from the tile's mean direction (or more).
    struct Directions {
        double u[tile_capacity][3];
        double off[tile_capacity];
        double z[3];
    };

    void set_directions(const Tile& t, Directions& d) const {
        for (int k = 0; k < 3; ++k) d.z[k] = t.frame[0][k];
        metric_tree::normalize(d.z);
        for (uint64_t w = t.alive; w; w &= w - 1) {
            const uint32_t i = math::lowest_bit(w);
            const double inv = 1 / t.dist[i];
            for (int k = 0; k < 3; ++k) d.u[i][k] = t.e[k][i] * inv;
            d.off[i] = metric_tree::angle_above(d.u[i], d.z);
        }
    }

    // ---- building

    // The sphere and, where it is long enough, the capsule of cluster `index` of `level`, in the mesh's
    // frame; false when the level has no volume to take them from.
    bool volume_of(const LevelBounds& level, uint32_t index, double* a, double* b, double& r) const {
        double sr = 0, sc[3], ca[3], cb[3], cr = 0;
        bool capsule = false;
        if (level.spheres) {
            const Sphere& s = level.spheres[index];
            for (int k = 0; k < 3; ++k) sc[k] = s.center[k];
            sr = s.radius;
            if (level.capsules) {
                const Capsule& c = level.capsules[index];
                capsule = c.a[0] != c.b[0] || c.a[1] != c.b[1] || c.a[2] != c.b[2];
                for (int k = 0; k < 3; ++k) {
                    ca[k] = c.a[k];
                    cb[k] = c.b[k];
                }
                cr = c.radius;
            }
        } else if (level.obbs) {
            // About the box: the sphere through its corners, and the capsule along its longest axis whose
            // radius reaches the corners of its cross-section; 1e-6 more than the axes' departure from unit
            // and orthogonal (about 1e-7).
            const Obb box = level.obb(index);
            double h[3];
            padded_halves(box, h);
            const int l = h[0] >= h[1] && h[0] >= h[2] ? 0 : h[1] >= h[2] ? 1 : 2, j = (l + 1) % 3, m = (l + 2) % 3;
            const double pad = 1e-6 * (h[0] + h[1] + h[2]);
            for (int k = 0; k < 3; ++k) {
                sc[k] = box.center[k];
                ca[k] = box.center[k] - h[l] * box.axis[l][k];
                cb[k] = box.center[k] + h[l] * box.axis[l][k];
            }
            sr = std::sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]) + pad;
            cr = std::sqrt(h[j] * h[j] + h[m] * h[m]) + pad;
            capsule = true;
        } else {
            return false;
        }
        if (capsule) {
            const double d[3] = {cb[0] - ca[0], cb[1] - ca[1], cb[2] - ca[2]};
            const double length = std::sqrt(math::dot3(d, d));
            capsule = cr > 0 && length + 2 * cr >= capsule_aspect_ * 2 * cr;
        }
        if (capsule) {
            for (int k = 0; k < 3; ++k) {
                a[k] = ca[k];
                b[k] = cb[k];
            }
            r = cr;
        } else {
            for (int k = 0; k < 3; ++k) a[k] = b[k] = sc[k];
            r = sr;
        }
        return true;
    }

    // Cluster `index` of `level` seen from the light, as an element; false when it has no cone: no volume,
    // or one that holds the light (its cluster is then tested by every point that gets that far).
    bool element_of(const LevelBounds& level, uint32_t index, uint32_t cluster, Element& e) const {
        double pa[3], pb[3], r;
        if (!volume_of(level, index, pa, pb, r)) return false;
        double A[3], B[3], AB[3];
        for (int k = 0; k < 3; ++k) {
            A[k] = pa[k] - light_[k];
            B[k] = pb[k] - light_[k];
            AB[k] = B[k] - A[k];
        }
        // The segment's nearest point to the light.
        const double ab2 = math::dot3(AB, AB);
        double t = ab2 > 0 ? -math::dot3(A, AB) / ab2 : 0;
        t = std::min(1.0, std::max(0.0, t));
        double X[3];
        for (int k = 0; k < 3; ++k) X[k] = A[k] + t * AB[k];
        const double dist = std::sqrt(math::dot3(X, X));
        // Rounding of the differences from the light: 1e-15 of the coordinates.
        const double err = 1e-15 * (math::l1(pa) + math::l1(pb) + 2 * math::l1(light_)) + 1e-9 * r;
        if (!(dist > (r + err) * (1 + 1e-9)) || !(dist < 1e30)) return false;
        double alpha = std::asin(std::min(1.0, (r + err) / dist));
        double ua[3] = {A[0], A[1], A[2]}, ub[3] = {B[0], B[1], B[2]};
        metric_tree::normalize(ua);
        if (ab2 > 0) metric_tree::normalize(ub);  // a sphere needs only ua
        const double arc = ab2 > 0 ? metric_tree::angle(ua, ub) : 0;
        Node& n = e.node;
        if (ab2 == 0) {  // a sphere: the cone about its centre's direction
            for (int k = 0; k < 3; ++k) n.dir_a[k] = n.dir_b[k] = float(ua[k]);
        } else if (arc < 1e-5) {  // too short an arc for its plane to be well defined: the cone about its middle
            double m[3] = {ua[0] + ub[0], ua[1] + ub[1], ua[2] + ub[2]};
            metric_tree::normalize(m);
            alpha += std::max(metric_tree::angle(m, ua), metric_tree::angle(m, ub));
            for (int k = 0; k < 3; ++k) n.dir_a[k] = n.dir_b[k] = float(m[k]);
        } else {
            for (int k = 0; k < 3; ++k) {
                n.dir_a[k] = float(ua[k]);
                n.dir_b[k] = float(ub[k]);
            }
            if (n.dir_a[0] == n.dir_b[0] && n.dir_a[1] == n.dir_b[1] && n.dir_a[2] == n.dir_b[2])
                n.dir_b[0] = math::next_float(n.dir_b[0], true);
        }
        // A float direction is within 1.1e-7 radians of the one rounded; 4e-7 more, and a relative 1e-9.
        n.alpha = math::round_up(alpha * (1 + 1e-9) + 4e-7);
        n.delta = 0;
        n.overlap_min = n.near_child_min = INFINITY;
        n.overlap_max = n.far_child_max = -INFINITY;
        n.near = math::round_down((dist - r - err) * (1 - 1e-9));
        n.near_min = n.near;
        for (uint32_t& c : n.child) c = none;
        n.cluster = cluster;
        // The disc on the sphere of directions that holds the element as stored.
        double da[3] = {n.dir_a[0], n.dir_a[1], n.dir_a[2]}, db[3] = {n.dir_b[0], n.dir_b[1], n.dir_b[2]};
        metric_tree::normalize(da);
        if (n.dir_a[0] == n.dir_b[0] && n.dir_a[1] == n.dir_b[1] &&
            n.dir_a[2] == n.dir_b[2]) {  // a point: the disc is the point
            for (int k = 0; k < 3; ++k) e.m[k] = da[k];
            e.half = 0;
        } else {
            metric_tree::normalize(db);
            for (int k = 0; k < 3; ++k) e.m[k] = da[k] + db[k];
            metric_tree::normalize(e.m);
            e.half = std::max(metric_tree::angle(e.m, da), metric_tree::angle(e.m, db));
        }
        e.delta = 0;
        return true;
    }

    // A tree over the clusters `ids` (indices local to the level's range starting at `first`) of one level;
    // those without a cone go to `always`. Returns the root; `depth` the longest path.
    uint32_t build_level(const LevelBounds& level, uint32_t first, const std::vector<uint32_t>& ids, bool coarse,
                         std::vector<uint32_t>& always, uint32_t& depth) {
        std::vector<Element>& elements = work_.elements;
        elements.clear();
        for (uint32_t id : ids) {
            if (!coarse && skippable_fine(id)) {
                ++skipped_;
                continue;
            }
            Element e;
            if (!element_of(level, first + id, coarse ? id | coarse_bit : id, e)) {
                always.push_back(id);
                continue;
            }
            capsules_ += e.node.dir_a[0] != e.node.dir_b[0] || e.node.dir_a[1] != e.node.dir_b[1] ||
                e.node.dir_a[2] != e.node.dir_b[2];
            elements.push_back(e);
        }
        if (elements.empty()) return none;
        return build_ == MetricBuild::reference ? metric_tree::build_reference(work_, depth)
                                                : metric_tree::build_heuristic(work_, depth);
    }

    // Lays the built nodes out in the order a walk meets them (depth first, near child next), into nodes_.
    void renumber_in_walk_order() {
        const std::vector<Node>& built = work_.built;
        std::vector<uint32_t>& to = work_.to;
        std::vector<uint32_t>& todo = work_.todo;
        to.assign(built.size(), none);
        nodes_.clear();
        nodes_.reserve(built.size());
        auto visit = [&](uint32_t start) {
            todo.clear();
            todo.push_back(start);
            while (!todo.empty()) {
                const uint32_t ref = todo.back();
                todo.pop_back();
                if (ref == none) continue;
                to[ref] = uint32_t(nodes_.size());
                nodes_.push_back(built[ref]);
                const Node& n = built[ref];
                todo.push_back(n.child[2]);
                todo.push_back(n.child[1]);
                todo.push_back(n.child[0]);
                if (n.cluster & coarse_bit) todo.push_back(fine_roots_[n.cluster & ~coarse_bit]);
            }
        };
        visit(root_);
        for (uint32_t c : always_coarse_) visit(fine_roots_[c]);
        for (uint32_t& r : fine_roots_)
            if (r != none && to[r] == none) visit(r);  // coarse clusters not in the tree (none now; kept safe)
        auto map = [&](uint32_t ref) { return ref == none ? none : to[ref]; };
        for (Node& n : nodes_)
            for (uint32_t& c : n.child) c = map(c);
        root_ = map(root_);
        for (uint32_t& r : fine_roots_) r = map(r);
    }

    // ---- walking

    // The points of `subset` whose segment to the light may cross fine cluster f's slab: the segment's
    // extent along the slab's axis meets [low, high], with a tolerance far above double's rounding.
    uint64_t slab_points(uint32_t f, uint64_t subset, const Tile& t) const {
        if (!slabs_ || !subset) return subset;
        const Slab& s = view_->fine_bounds.slabs[mesh_->first_fine + f];
        const double ax[3] = {s.axis[0], s.axis[1], s.axis[2]};
        const double at_light = math::dot3(light_, ax);
        if (t.small) {
            // In float from the light: the segment's extent along the axis, [min(0, e . axis), max(0, e . axis)],
            // must meet the slab's, [low, high] - light . axis. The float products err by under 3e-7 of
            // |e| + their size; 2e-6 of both to spare.
            using simd::Floats;
            const double lo = double(s.low) - at_light, hi = double(s.high) - at_light;
            const float spare = float(2e-6 * (std::fabs(lo) + std::fabs(hi)));
            const Floats low = simd::splat(math::round_down(lo) - spare),
                         high = simd::splat(math::round_up(hi) + spare), zero = simd::splat(0.0f),
                         margin = simd::splat(2e-6f);
            uint32_t begin, end;
            simd::lane_span(subset, begin, end);
            uint64_t keep = 0;
            for (uint32_t i = begin; i < end; i += simd::width) {
                if (!simd::group(subset, i)) continue;
                const Floats ex = simd::load(t.ex + i), ey = simd::load(t.ey + i), ez = simd::load(t.ez + i),
                             slack = simd::load(t.fd + i) * margin;
                const Floats along = simd::dot(ex, ey, ez, s.axis[0], s.axis[1], s.axis[2]);
                const simd::Mask meets =
                    (simd::max(along, zero) + slack >= low) & (simd::min(along, zero) - slack <= high);
                keep |= uint64_t(simd::bits(meets)) << i;
            }
            return subset & keep;
        }
        for (uint64_t w = subset; w; w &= w - 1) {
            const uint32_t i = math::lowest_bit(w);
            if (!segment_may_cross(s, t.p[i])) subset &= ~(uint64_t(1) << i);
        }
        return subset;
    }

    // In double: the segment from p to the light may cross slab s (its extent along the axis meets [low,
    // high], with a tolerance far above double's rounding).
    bool segment_may_cross(const Slab& s, const double* p) const {
        const double ax[3] = {s.axis[0], s.axis[1], s.axis[2]};
        const double at_light = math::dot3(light_, ax), at_p = math::dot3(p, ax);
        const double reach =
            1e-9 * (std::fabs(double(s.low)) + std::fabs(double(s.high)) + 2 * math::l1(light_) + math::l1(p)) + 1e-30;
        return !(std::max(at_p, at_light) < double(s.low) - reach || std::min(at_p, at_light) > double(s.high) + reach);
    }

    bool slab_may_cross(uint32_t f, const Query& q) const {
        return !slabs_ || segment_may_cross(view_->fine_bounds.slabs[mesh_->first_fine + f], q.p);
    }

    // The points of `subset` whose directions lie in the node's cone (or capsule-cone) and that are not nearer
    // the light than its volume. A tile within float_safe of the light is tested in float, one instruction for
    // a whole vector of points; otherwise in double, by cosines with a margin (1e-12) far above their rounding.
    uint64_t cone_points(const Node& node, const Central& c, uint64_t subset, const Tile& t,
                         const Directions& d) const {
        const double a = double(node.alpha) + tol;
        if (a >= 0.5 * metric_tree::pi) {  // so wide that the tests below would not hold: every point beyond near
            for (uint64_t w = subset; w; w &= w - 1) {
                const uint32_t i = math::lowest_bit(w);
                if (t.dist[i] < node.near) subset &= ~(uint64_t(1) << i);
            }
            return subset;
        }
        if (t.small) return cone_points_float(node, c, metric_tree::sine_above(a), subset, t);
        const double cos_a = std::cos(a) - 1e-12, sin_a = std::sin(a) + 1e-12;
        double ua[3] = {c.a[0], c.a[1], c.a[2]}, ub[3] = {c.b[0], c.b[1], c.b[2]};
        metric_tree::normalize(ua);
        metric_tree::normalize(ub);
        uint64_t in = 0;
        for (uint64_t w = subset; w; w &= w - 1) {
            const uint32_t i = math::lowest_bit(w);
            if (t.dist[i] < node.near) continue;
            const double* u = d.u[i];
            bool inside = math::dot3(u, ua) >= cos_a;
            if (!inside && c.arc) {
                double x[3];
                math::cross3(c.a, u, x);
                const double after_a = math::dot3(x, c.n);
                math::cross3(u, c.b, x);
                const double before_b = math::dot3(x, c.n);
                // In the lune over the arc (taken a little wider: the angle off the arc's plane is then at most
                // the angle to the arc), or near the far end.
                inside = (after_a >= -1e-12 && before_b >= -1e-12 && std::fabs(math::dot3(u, c.n)) <= sin_a) ||
                    math::dot3(u, ub) >= cos_a;
            }
            if (inside) in |= uint64_t(1) << i;
        }
        return in;
    }

    // cone_points in float over the tile's lanes, for alpha below pi / 2 (sin_a its sine). A direction e (its
    // length d) is within the angle of unit axis x when e . x >= 0 and |e x x| <= d sin(alpha); of an arc
    // (unit normal n) when it lies in the lune over the arc and |e . n| <= d sin(alpha). The float products
    // err by under 6e-7 of d (the directions to float: 1.2e-7 of an angle; e and d: 6e-8 each); every
    // comparison has 4e-6 of d to spare.
    uint64_t cone_points_float(const Node& node, const Central& c, double sin_a, uint64_t subset, const Tile& t) const {
        using simd::Floats;
        const float reach = float(sin_a + 4e-6), near = node.near;
        const Floats zero = simd::splat(0.0f), margin = simd::splat(4e-6f);
        float ends[2][3], side[2][3], n[3];
        int end_count = 1;
        for (int k = 0; k < 3; ++k) ends[0][k] = node.dir_a[k];
        if (c.arc) {
            end_count = 2;
            double p[3], q[3];
            math::cross3(c.n, c.a, p);  // e . p >= 0: on b's side of the plane through a and n
            math::cross3(c.b, c.n, q);  // e . q >= 0: on a's side of the plane through b and n
            for (int k = 0; k < 3; ++k) {
                ends[1][k] = node.dir_b[k];
                side[0][k] = float(p[k]);
                side[1][k] = float(q[k]);
                n[k] = float(c.n[k]);
            }
        }
        uint32_t begin, end;
        simd::lane_span(subset, begin, end);
        uint64_t in = 0;
        for (uint32_t i = begin; i < end; i += simd::width) {
            if (!simd::group(subset, i)) continue;
            const Floats ex = simd::load(t.ex + i), ey = simd::load(t.ey + i), ez = simd::load(t.ez + i),
                         dist = simd::load(t.fd + i);
            const Floats r = dist * simd::splat(reach), slack = dist * margin;
            const Floats r2 = r * r;
            uint32_t hit = 0;
            for (int k = 0; k < end_count; ++k) {
                const float* x = ends[k];
                const Floats along = simd::dot(ex, ey, ez, x[0], x[1], x[2]);
                const Floats cx = simd::fms(ey, simd::splat(x[2]), ez * simd::splat(x[1])),
                             cy = simd::fms(ez, simd::splat(x[0]), ex * simd::splat(x[2])),
                             cz = simd::fms(ex, simd::splat(x[1]), ey * simd::splat(x[0]));
                const Floats cross2 = simd::dot(cx, cy, cz, cx, cy, cz);
                hit |= simd::bits((along + slack >= zero) & (cross2 <= r2));
            }
            if (c.arc) {
                const Floats after = simd::dot(ex, ey, ez, side[0][0], side[0][1], side[0][2]) + slack,
                             before = simd::dot(ex, ey, ez, side[1][0], side[1][1], side[1][2]) + slack,
                             off = simd::abs(simd::dot(ex, ey, ez, n[0], n[1], n[2]));
                hit |= simd::bits((after >= zero) & (before >= zero) & (off <= r));
            }
            hit &= simd::bits(dist >= simd::splat(near));
            in |= uint64_t(hit) << i;
        }
        return in & subset;
    }

    // The points of `in` whose segment to the light may meet coarse cluster c's box (all of them without
    // boxes): in float where the box's set-up and the tile allow, otherwise in double.
    uint64_t coarse_box_points(uint32_t c, uint64_t in, const Tile& t) const {
        if (coarse_boxes_.empty() || !in) return in;
        const BoxFilter& b = coarse_boxes_[c];
        if (b.usable && t.small) return box_points(b, in, t);
        const Obb box = coarse_obb(c);  // decoded once for all the points
        for (uint64_t w = in; w; w &= w - 1) {
            const uint32_t i = math::lowest_bit(w);
            if (!segment_may_touch_box(box, t.p[i], light_, blocking_start(t.from[i]))) in &= ~(uint64_t(1) << i);
        }
        return in;
    }

    Obb coarse_obb(uint32_t c) const { return view_->coarse_bounds.obb(mesh_->first_coarse + c); }

    // The walk for a tile's points `subset` at once: directions within `spread` of d.z, none farther than
    // `far` from the light.
    void tile_walk(uint32_t start, uint64_t subset, Tile& t, const Directions& d, uint32_t* stack) const {
        double spread = 0, far = 0, close = INFINITY;
        for (uint64_t w = subset; w; w &= w - 1) {
            const uint32_t i = math::lowest_bit(w);
            spread = std::max(spread, d.off[i]);
            far = std::max(far, t.dist[i]);
            close = std::min(close, t.dist[i]);
        }
        spread += tol;
        size_t top = 0;
        stack[top++] = start;
        while (top && (subset & t.alive)) {
            const Node& node = nodes_[stack[--top]];
            if (t.stats) ++t.stats->nodes_visited;
            if (far < node.near_min) continue;
            const metric_tree::Central c = metric_tree::central_of(node);
            const double s = metric_tree::distance<true>(c, d.z) - double(node.alpha), lo = s - spread, hi = s + spread;
            // The far and overlap children lie away from this node in walk order: fetched while it is tested.
            if (node.child[2] != none && hi >= double(node.overlap_min) && lo <= double(node.overlap_max))
                simd::prefetch(&nodes_[stack[top++] = node.child[2]]);
            if (node.child[1] != none && hi > double(node.delta) && lo <= double(node.far_child_max))
                simd::prefetch(&nodes_[stack[top++] = node.child[1]]);
            if (node.child[0] != none && lo <= double(node.delta) && hi >= double(node.near_child_min))
                stack[top++] = node.child[0];
            if (lo > 0 || far < node.near) continue;
            // The tile's whole cone inside the node's, and no point nearer the light: no point to test.
            const uint64_t in =
                hi <= 0 && close >= node.near ? subset & t.alive : cone_points(node, c, subset & t.alive, t, d);
            if (!in) continue;
            if (node.cluster & coarse_bit) {
                const uint32_t c = node.cluster & ~coarse_bit;
                const uint64_t meeting = coarse_box_points(c, in, t);
                if (!meeting) continue;
                uint32_t* rest = stack + top;  // the stack above this walk's entries
                add_entered(t, node.near, c, meeting,
                            [&](uint32_t id, uint64_t points) { enter_coarse(id, points, t, d, rest); });
            } else {
                const uint64_t crossing = slab_points(node.cluster, in, t);
                if (!crossing) continue;
                add_pending(t, node.near, node.cluster, crossing);
            }
        }
    }

    // A coarse cluster entered by the points `in`: its fine clusters without a cone, then its fine tree.
    void enter_coarse(uint32_t c, uint64_t in, Tile& t, const Directions& d, uint32_t* stack) const {
        const IndexRange r = fine_always_[c];
        for (uint32_t k = r.first; k < r.first + r.count && (in & t.alive); ++k)
            test_points(always_fine_[k], slab_points(always_fine_[k], in & t.alive, t), t);
        if (fine_roots_[c] != none && (in & t.alive)) tile_walk(fine_roots_[c], in & t.alive, t, d, stack);
    }

    // One point on its own, in double: the tree walk, testing each cluster as its volume is met.
    bool walk_alone(const double* world_p, uint32_t* stack, QueryStats* stats) const {
        if (!usable_ || !finite3(world_p)) return false;
        const Query q = make_query(world_p, stats, nullptr);
        if (!may_block(q.from)) return false;  // within the bias of the light
        if (!(q.dist > 0)) return false;       // at the light: the segment is a point, which blocks nothing
        double u[3] = {q.e[0], q.e[1], q.e[2]};
        metric_tree::normalize(u);
        for (uint32_t i = top_always_.first; i < top_always_.first + top_always_.count; ++i)
            if (slab_may_cross(always_fine_[i], q) && test_cluster(always_fine_[i], q)) return true;
        size_t top = 0;
        for (uint32_t c : always_coarse_) {
            const IndexRange r = fine_always_[c];
            for (uint32_t k = r.first; k < r.first + r.count; ++k)
                if (slab_may_cross(always_fine_[k], q) && test_cluster(always_fine_[k], q)) return true;
            if (fine_roots_[c] != none) stack[top++] = fine_roots_[c];
            if (top && walk(stack, top, q, u)) return true;
            top = 0;
        }
        if (root_ == none) return false;
        stack[top++] = root_;
        return walk(stack, top, q, u);
    }

    bool walk(uint32_t* stack, size_t top, const Query& q, const double* u) const {
        while (top) {
            const Node& node = nodes_[stack[--top]];
            if (q.stats) ++q.stats->nodes_visited;
            if (q.dist < node.near_min) continue;
            const double s = metric_tree::distance<true>(metric_tree::central_of(node), u) - double(node.alpha);
            if (node.child[2] != none && s + tol >= double(node.overlap_min) && s - tol <= double(node.overlap_max))
                stack[top++] = node.child[2];
            if (node.child[1] != none && s + tol > double(node.delta) && s - tol <= double(node.far_child_max))
                stack[top++] = node.child[1];
            if (node.child[0] != none && s - tol <= double(node.delta) && s + tol >= double(node.near_child_min))
                stack[top++] = node.child[0];
            if (s > tol || q.dist < node.near) continue;
            if (node.cluster & coarse_bit) {
                const uint32_t c = node.cluster & ~coarse_bit;
                if (!coarse_boxes_.empty() &&
                    !segment_may_touch_box(coarse_obb(c), q.p, light_, blocking_start(q.from)))
                    continue;
                const IndexRange r = fine_always_[c];
                for (uint32_t k = r.first; k < r.first + r.count; ++k)
                    if (slab_may_cross(always_fine_[k], q) && test_cluster(always_fine_[k], q)) return true;
                if (fine_roots_[c] != none) stack[top++] = fine_roots_[c];
            } else if (slab_may_cross(node.cluster, q) && test_cluster(node.cluster, q)) {
                return true;
            }
        }
        return false;
    }

    std::vector<Node> nodes_;
    std::vector<uint32_t> always_fine_;    // fine clusters without a cone (in ranges per coarse cluster: two levels)
    std::vector<uint32_t> always_coarse_;  // two levels: coarse clusters without a cone, entered by every point
    std::vector<uint32_t> fine_roots_;     // two levels: each coarse cluster's fine tree
    std::vector<IndexRange> fine_always_;  // two levels: each coarse cluster's range of always_fine_
    std::vector<BoxFilter> coarse_boxes_;  // two levels: each coarse box set up for the light (none without boxes)
    IndexRange top_always_;                // one level: always_fine_ whole
    uint32_t root_ = none, depth_ = 0;
    double capsule_aspect_ = 4;
    MetricBuild build_ = MetricBuild::heuristic;
    bool slabs_ = false;
    metric_tree::Work work_;  // kept between builds so that a rebuild reuses its memory
};

}  // namespace CB_LANES
}  // namespace cb

#undef CB_METRIC_INLINE
