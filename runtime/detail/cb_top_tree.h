// The TOP-tree traversal (Traversal::top_two and Traversal::top_one, the thesis's method): ternary trees of
// planes through the light over the shadow volumes of cluster boxes (cb_shadow_volume.h). Each volume is a
// chain of its 4 planes: the inside branch of one plane leads to the next, and the last to a cluster node. A
// plane node has three children: inside (volumes entirely on its inside), outside (entirely outside) and
// straddling (both); a query follows the side its point is on, and the straddling child unless the point is
// farther from the plane than any volume down there reaches. A cluster node acts when the point is beyond
// the closing distance, then goes on into its own subtree: volumes inserted later that lie inside this one.
// Nothing is dropped there: a volume is only conservative, so a point inside it may still be lit by its
// cluster and shadowed by a later one. Volumes go in, one by one, in a shuffled order (fixed seed) that keeps
// the trees balanced. Clusters whose box holds the light, or is level with it, have no volume: they are
// tested for every point that gets that far. Two levels: a tree over the coarse clusters' volumes whose
// cluster nodes enter a tree over that coarse cluster's fine clusters (Traversal::top_two, when the asset has
// coarse boxes; otherwise, and with Traversal::top_one, one tree over the fine clusters).
//
// Every node also keeps the smallest closing distance of the volumes below it: a point nearer the light
// than that skips the whole subtree (nothing there can shadow it). Plane nodes and cluster nodes live in
// two arrays of 32-byte records; a child reference with the top bit set names a cluster node.
//
// A tile of points (cb_tile.h) walks each tree once with the pyramid from the light that holds their
// directions; the answers are those of a walk per point. Header-only C++17, no exceptions; building
// allocates (std::vector) and starts no thread, queries do not. MIT licensed (runtime/LICENSE).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "../cb_asset.h"
#include "cb_math.h"
#include "cb_shadow_volume.h"
#include "cb_simd.h"
#include "cb_tile.h"

namespace cb {
inline namespace CB_LANES {
namespace top_tree {

constexpr uint32_t none = TraversalBase::none;
constexpr uint32_t cluster_bit = 0x80000000u;  // in a child reference: a cluster node

// A plane through the light; inside: dot(n, p - light) >= 0.
struct PlaneNode {  // 32 bytes
    float n[3];     // unit to float precision
    // Every point of every volume in the straddling subtree makes an angle with the plane whose sine is
    // at most this (rounded up); a point farther from the plane skips that subtree.
    float straddle_sine;
    float near_min;     // smallest closing distance below (rounded down)
    uint32_t child[3];  // inside, outside, straddling
};

// The end of a volume's chain: its cluster, then the volumes inserted later inside it.
struct ClusterNode {     // 32 bytes
    float near = 0;      // closing distance (rounded down)
    float near_min = 0;  // the smaller of near and the closing distances in `inside`
    uint32_t inside = none;
    uint32_t fine_root = none;    // coarse: the root of its fine tree
    uint32_t cluster = none;      // fine: the fine cluster (mesh-local); none for a coarse cluster
    IndexRange always;            // coarse: its fine clusters tested whenever it is entered (a range of
                                  // always_fine_)
    uint32_t first_plane = none;  // the 4 planes of its volume, consecutive (none: no volume)
};

static_assert(sizeof(PlaneNode) == 32 && sizeof(ClusterNode) == 32, "tree nodes are 32-byte records (RUNTIME.md)");

// Nodes while a tree is built (renumber_in_walk_order() lays them out for queries).
struct Nodes {
    std::vector<PlaneNode> planes;
    std::vector<ClusterNode> clusters;
};

}  // namespace top_tree

// The working arrays of TopTreeTraversal::build, reusable between builds (ShadowBuildOptions::scratch).
struct BuildScratch {
    top_tree::Nodes built;                             // every node before the walk-order layout
    std::vector<uint32_t> plane_to, cluster_to, todo;  // the layout's renumbering
    size_t memory_bytes() const {
        return built.planes.capacity() * sizeof(top_tree::PlaneNode) +
            built.clusters.capacity() * sizeof(top_tree::ClusterNode) +
            (plane_to.capacity() + cluster_to.capacity() + todo.capacity()) * sizeof(uint32_t);
    }
};

class TopTreeTraversal : public TraversalBase {
public:
    // One instance of the asset's meshes, for one light given in world space: two levels unless
    // options.traversal is Traversal::top_one or the asset has no coarse boxes.
    void build(const AssetView& view, uint32_t instance, const double* world_light, const ShadowBuildOptions& options) {
        build(view, placement_of(view, instance), world_light, options);
    }
    // The same for a mesh of the asset placed by the caller (a runtime scene's instance).
    void build(const AssetView& view, Placement at, const double* world_light, const ShadowBuildOptions& options) {
        BuildScratch own;
        BuildScratch& work = options.scratch ? *options.scratch : own;
        planes_.clear();
        clusters_.clear();
        always_fine_.clear();
        always_coarse_.clear();
        root_ = none;
        depth_ = 0;
        top_always_ = {};
        if (!set_instance(view, at, world_light, options.one_sided, options.bias)) return;
        const bool two = options.traversal != Traversal::top_one && view.coarse_bounds.obbs;
        Nodes& all = work.built;
        all.planes.clear();
        all.clusters.clear();
        // At most 4 planes and a cluster node per volume.
        size_t volumes = mesh_->fine_count + (two ? mesh_->coarse_count : 0);
        all.planes.reserve(volumes * 4);
        all.clusters.reserve(volumes);

        if (!two) {
            // One level: every fine cluster in one tree; always-tested ones in one list.
            uint32_t fine_depth = 0;
            root_ = build_fine_tree(all, 0, mesh_->fine_count, fine_depth, always_fine_, skipped_);
            top_always_ = {0, uint32_t(always_fine_.size())};
            depth_ = fine_depth;
            renumber_in_walk_order(all, work);
            return;
        }
        // Fine trees, one per coarse cluster, then the coarse tree over them.
        const uint32_t coarse_count = mesh_->coarse_count;
        std::vector<uint32_t> fine_roots(coarse_count, none);
        std::vector<IndexRange> fine_always(coarse_count);
        std::vector<uint8_t> wanted(coarse_count, 1);
        uint32_t fine_depth = 0;
        for (uint32_t c = 0; c < coarse_count; ++c) {
            const ClusterRange& r = view.coarse[mesh_->first_coarse + c];
            if (one_sided_ && skippable(view.coarse_bounds, mesh_->first_coarse + c, coarse_triangles(c))) {
                skipped_ += r.count;
                wanted[c] = 0;
                continue;
            }
            uint32_t first_always = uint32_t(always_fine_.size()), depth = 0;
            fine_roots[c] = build_fine_tree(all, r.first, r.count, depth, always_fine_, skipped_);
            fine_always[c] = {first_always, uint32_t(always_fine_.size()) - first_always};
            fine_depth = std::max(fine_depth, depth);
        }
        uint32_t coarse_depth = build_coarse_tree(all, wanted, [&](uint32_t c, ClusterNode& leaf) {
            leaf.fine_root = fine_roots[c];
            leaf.always = fine_always[c];
        });
        depth_ = coarse_depth + fine_depth + 1;
        renumber_in_walk_order(all, work);
    }

    // Entries the query stack needs: pending siblings along the deepest path through both levels.
    size_t stack_size() const { return size_t(depth_) * 2 + 4; }

    // True when the segment from world point p to the light is blocked by this instance. `stack` holds
    // stack_size() entries.
    bool occluded(const double* world_p, uint32_t* stack, QueryStats* stats = nullptr) const {
        if (!usable_ || !finite3(world_p)) return false;  // a point that is not finite is never in shadow
        return walk_alone(world_p, stack, stats);
    }

    // The tile walk: of the `count` world points points + 3 * index[i] (xyz doubles), those set in `alive`
    // that this instance shadows, as a mask; the same answers as occluded() point by point. The tree is
    // walked once with a pyramid from the light that holds every point's direction: a node is skipped only
    // when no point of the tile could reach it. At a cluster node, each point is tested against the node's
    // own volume (its 4 planes and closing distance) before its cluster's triangles, so a point meets the
    // clusters whose volumes hold it, as its own walk would. Points too far from the tile's mean direction
    // (over 60 degrees), at the light, not finite or beyond 1e30 walk alone. `stack` holds stack_size()
    // entries; uses about 13 KB of the thread's stack besides (and a cluster test's, docs/RUNTIME.md).
    uint64_t occluded_tile(const double* points, const uint32_t* index, uint32_t count, uint64_t alive, uint32_t* stack,
                           QueryStats* stats = nullptr, TileCache* cache = nullptr) const {
        if (!usable_ || alive == 0) return 0;
        Tile t;
        uint64_t alone;
        const uint64_t off = start_tile(t, points, index, count, alive, stats, cache, nullptr, alone);
        auto find = [&] {
            for (uint32_t i = top_always_.first; i < top_always_.first + top_always_.count && t.alive; ++i)
                test_points(always_fine_[i], t.alive, t);
            for (uint32_t node : always_coarse_)
                if (t.alive) tile_walk(node, t.alive, t, stack);
            if (root_ != none && t.alive) tile_walk(root_, t.alive, t, stack);
        };
        // Points over 60 degrees off the tile's mean direction walk alone too.
        return walk_tile(
            t, alone | off, find, [&](uint32_t id, uint64_t in) { enter_coarse(id, in, t, stack); },
            [&](uint32_t i) { return walk_alone(points + size_t(index[i]) * 3, stack, stats); });
    }

    size_t node_count() const { return planes_.size() + clusters_.size(); }
    // Bytes this traversal holds (the asset it reads is not counted).
    size_t memory_bytes() const {
        return planes_.capacity() * sizeof(PlaneNode) + clusters_.capacity() * sizeof(ClusterNode) +
            (always_fine_.capacity() + always_coarse_.capacity()) * sizeof(uint32_t);
    }
    size_t always_tested() const { return always_fine_.size(); }

private:
    using PlaneNode = top_tree::PlaneNode;
    using ClusterNode = top_tree::ClusterNode;
    using Nodes = top_tree::Nodes;
    static constexpr uint32_t cluster_bit = top_tree::cluster_bit;

    // The smallest and largest sine of the pyramid's rays against the plane with normal n (4 at once with SSE).
    static void ray_sines(const float* n, const Pyramid& P, float& smin, float& smax) {
#ifdef CB_SIMD_SSE2
        __m128 s = _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_set1_ps(n[0]), _mm_load_ps(P.rx)),
                                         _mm_mul_ps(_mm_set1_ps(n[1]), _mm_load_ps(P.ry))),
                              _mm_mul_ps(_mm_set1_ps(n[2]), _mm_load_ps(P.rz)));
        __m128 swapped = _mm_shuffle_ps(s, s, _MM_SHUFFLE(1, 0, 3, 2));
        __m128 lo = _mm_min_ps(s, swapped), hi = _mm_max_ps(s, swapped);
        smin = _mm_cvtss_f32(_mm_min_ss(lo, _mm_shuffle_ps(lo, lo, _MM_SHUFFLE(2, 3, 0, 1))));
        smax = _mm_cvtss_f32(_mm_max_ss(hi, _mm_shuffle_ps(hi, hi, _MM_SHUFFLE(2, 3, 0, 1))));
#else
        float s[4];
        for (int r = 0; r < 4; ++r) s[r] = n[0] * P.rx[r] + n[1] * P.ry[r] + n[2] * P.rz[r];
        smin = std::min(std::min(s[0], s[1]), std::min(s[2], s[3]));
        smax = std::max(std::max(s[0], s[1]), std::max(s[2], s[3]));
#endif
    }

    // A coarse cluster's fine tree, walked by the points `in` with the pyramid narrowed to them.
    void walk_fine_tree(uint32_t root, uint64_t in, Tile& t, uint32_t* stack) const {
        const Pyramid whole = narrow_pyramid(t, in);
        tile_walk(root, in, t, stack);
        t.pyramid = whole;
    }

    // The points of `subset` that may lie in the volume of `leaf`: beyond its closing distance and inside
    // its planes with the walk's tolerance plus the float evaluation's error (below 6e-7 of the distance).
    // Bit k of `straddled` is set when plane k may cut the tile's pyramid; the others hold every point.
    // One instruction tests a whole vector of points, over the lane groups that hold some of the subset.
    uint64_t volume_points(const ClusterNode& leaf, uint64_t subset, uint32_t straddled, const Tile& t) const {
        if (!subset) return 0;
        float n[4][3];  // the planes to check
        int planes = 0;
        if (leaf.first_plane != none)
            for (int k = 0; k < 4; ++k) {
                if (!(straddled >> k & 1)) continue;
                const float* from = planes_[leaf.first_plane + k].n;
                n[planes][0] = from[0];
                n[planes][1] = from[1];
                n[planes][2] = from[2];
                ++planes;
            }
        uint32_t begin, end;
        simd::lane_span(subset, begin, end);
        const simd::Floats near = simd::splat(leaf.near), zero = simd::splat(0.0f);
        uint64_t in = 0;
        for (uint32_t i = begin; i < end; i += simd::width) {
            if (!simd::group(subset, i)) continue;
            const simd::Floats ex = simd::load(t.ex + i), ey = simd::load(t.ey + i), ez = simd::load(t.ez + i),
                               slack = simd::load(t.slack + i);
            simd::Floats margin =
                simd::load(t.fd + i) - near;  // >= 0: inside everything checked (a float difference has the exact sign)
            for (int k = 0; k < planes; ++k)
                margin = simd::min(margin, simd::dot_plus(ex, ey, ez, n[k][0], n[k][1], n[k][2], slack));
            in |= uint64_t(simd::bits(margin >= zero)) << i;
        }
        return in & subset;
    }

    // One point on its own, in double: the tree walk.
    bool walk_alone(const double* world_p, uint32_t* stack, QueryStats* stats) const {
        if (!usable_ || !finite3(world_p)) return false;
        const Query q = make_query(world_p, stats, nullptr);
        if (!may_block(q.from)) return false;  // within the bias of the light
        for (uint32_t i = top_always_.first; i < top_always_.first + top_always_.count; ++i)
            if (test_cluster(always_fine_[i], q)) return true;
        for (uint32_t node : always_coarse_)  // coarse clusters around the light, one walk each
            if (walk(node, stack, q)) return true;
        return root_ != none && walk(root_, stack, q);
    }

    // A coarse cluster's node entered by the points `in` (walk_entered): its always-tested fine clusters, then
    // its fine tree.
    void enter_coarse(uint32_t id, uint64_t in, Tile& t, uint32_t* stack) const {
        const ClusterNode& leaf = clusters_[id];
        for (uint32_t k = leaf.always.first; k < leaf.always.first + leaf.always.count; ++k)
            test_points(always_fine_[k], in, t);
        if (leaf.fine_root != none && (in & t.alive)) walk_fine_tree(leaf.fine_root, in & t.alive, t, stack);
    }

    // The walk of `walk` for a tile's points `subset` at once (see occluded_tile).
    void tile_walk(uint32_t start, uint64_t subset, Tile& t, uint32_t* stack) const {
        size_t top = 0;
        stack[top++] = start;
        // The walk's tolerance (1e-9), and room for the float evaluation (the sines below err by under 4e-7).
        const float tol = 1e-6f;
        const Pyramid& P = t.pyramid;
        while (top && (subset & t.alive)) {
            uint32_t ref = stack[--top];
            // Bit k: the k-th last plane passed on the way down may cut the pyramid (a chain's 4 planes are
            // the last 4 before its cluster node; unknown planes count as cutting).
            uint32_t straddled = 15;
            for (;;) {
                if (t.stats) ++t.stats->nodes_visited;
                if (ref & cluster_bit) {
                    const ClusterNode& leaf = clusters_[ref & ~cluster_bit];
                    if (P.dmax < leaf.near_min) break;
                    if (leaf.inside != none) stack[top++] = leaf.inside;
                    if (P.dmax < leaf.near) break;
                    // Planes 0..3 of the chain are bits 3..0 of the history.
                    uint32_t chain =
                        (straddled >> 3 & 1) | (straddled >> 1 & 2) | (straddled << 1 & 4) | (straddled << 3 & 8);
                    uint64_t in = volume_points(leaf, subset & t.alive, chain, t);
                    if (!in) break;
                    if (leaf.cluster != none) {
                        add_pending(t, leaf.near, leaf.cluster, in);
                    } else {
                        uint32_t* rest = stack + top;  // the stack above this walk's entries
                        add_entered(t, leaf.near, uint32_t(&leaf - clusters_.data()), in,
                                    [&](uint32_t id, uint64_t points) { enter_coarse(id, points, t, rest); });
                    }
                    break;
                }
                const PlaneNode& node = planes_[ref];
                if (P.dmax < node.near_min) break;
                float smin, smax;
                ray_sines(node.n, P, smin, smax);
                // Every point's sine against the plane is at least smin when smin >= 0, at most smax when
                // smax <= 0 (a positive mix of unit rays is no longer than its weights).
                float reach = node.straddle_sine + tol;
                if (node.child[2] != none && !(smin > reach || smax < -reach)) stack[top++] = node.child[2];
                if (smin <= tol && node.child[1] != none) stack[top++] = node.child[1];
                if (smax < -tol || node.child[0] == none) break;
                straddled = (straddled << 1 | (smin > tol ? 0u : 1u)) & 15;
                ref = node.child[0];
            }
        }
    }

    static uint32_t add_cluster_node(Nodes& nodes, const ClusterNode& leaf) {
        nodes.clusters.push_back(leaf);
        return uint32_t(nodes.clusters.size() - 1) | cluster_bit;
    }

    // Renumbers the nodes in the order a walk meets them (depth first, the inside branch next), so that a
    // query reads mostly consecutive memory, into planes_ and clusters_, sized to what is used.
    void renumber_in_walk_order(const Nodes& built, BuildScratch& work) {
        std::vector<uint32_t>&plane_to = work.plane_to, &cluster_to = work.cluster_to, &todo = work.todo;
        plane_to.assign(built.planes.size(), none);
        cluster_to.assign(built.clusters.size(), none);
        todo.clear();
        std::vector<PlaneNode>& planes = planes_;
        std::vector<ClusterNode>& leaves = clusters_;
        planes.clear();
        leaves.clear();
        planes.reserve(built.planes.size());
        leaves.reserve(built.clusters.size());
        auto visit = [&](uint32_t start) {
            todo.push_back(start);
            while (!todo.empty()) {
                uint32_t ref = todo.back();
                todo.pop_back();
                if (ref == none) continue;
                if (ref & cluster_bit) {
                    const ClusterNode& l = built.clusters[ref & ~cluster_bit];
                    cluster_to[ref & ~cluster_bit] = uint32_t(leaves.size());
                    leaves.push_back(l);
                    todo.push_back(l.inside);
                    todo.push_back(l.fine_root);
                } else {
                    const PlaneNode& n = built.planes[ref];
                    plane_to[ref] = uint32_t(planes.size());
                    planes.push_back(n);
                    todo.push_back(n.child[2]);
                    todo.push_back(n.child[1]);
                    todo.push_back(n.child[0]);
                }
            }
        };
        visit(root_);
        for (uint32_t r : always_coarse_) visit(r);
        auto map = [&](uint32_t ref) {
            return ref == none      ? none
                : ref & cluster_bit ? (cluster_to[ref & ~cluster_bit] | cluster_bit)
                                    : plane_to[ref];
        };
        for (PlaneNode& n : planes)
            for (uint32_t& c : n.child) c = map(c);
        // A chain's planes stay consecutive: the walk order takes the inside child right after its plane.
        for (ClusterNode& l : leaves) {
            l.inside = map(l.inside);
            l.fine_root = map(l.fine_root);
            l.first_plane = l.first_plane == none ? none : plane_to[l.first_plane];
        }
        root_ = map(root_);
        for (uint32_t& r : always_coarse_) r = map(r);
    }

    bool walk(uint32_t start, uint32_t* stack, const Query& q) const {
        size_t top = 0;
        stack[top++] = start;
        while (top) {
            uint32_t ref = stack[--top];
            for (;;) {  // down the inside children directly; the other children wait on the stack
                if (q.stats) ++q.stats->nodes_visited;
                if (ref & cluster_bit) {
                    const ClusterNode& leaf = clusters_[ref & ~cluster_bit];
                    if (q.dist < leaf.near_min) break;  // nearer the light than everything here
                    if (leaf.inside != none) stack[top++] = leaf.inside;
                    if (q.dist < leaf.near) break;
                    if (leaf.cluster != none) {  // its triangles
                        if (test_cluster(leaf.cluster, q)) return true;
                    } else {  // into its fine tree
                        for (uint32_t i = leaf.always.first; i < leaf.always.first + leaf.always.count; ++i)
                            if (test_cluster(always_fine_[i], q)) return true;
                        if (leaf.fine_root != none) stack[top++] = leaf.fine_root;
                    }
                    break;
                }
                const PlaneNode& node = planes_[ref];
                if (q.dist < node.near_min) break;
                double s = node.n[0] * q.e[0] + node.n[1] * q.e[1] + node.n[2] * q.e[2];
                double tol = 1e-9 * q.dist;  // near the plane: both sides
                if (node.child[2] != none && std::fabs(s) <= (double(node.straddle_sine) + 1e-9) * q.dist)
                    stack[top++] = node.child[2];
                if (s <= tol && node.child[1] != none) stack[top++] = node.child[1];
                if (s < -tol || node.child[0] == none) break;
                ref = node.child[0];
            }
        }
        return false;
    }

    // The tree over the coarse clusters set in `wanted`, in the shuffled order, into root_; `fill(c, leaf)`
    // says where each one's cluster node leads. A coarse cluster whose box holds the light (or is level
    // with it) gets no volume: its node goes to always_coarse_, entered by every point. Returns the depth.
    template <class Fill>
    uint32_t build_coarse_tree(Nodes& all, const std::vector<uint8_t>& wanted, Fill fill) {
        uint32_t depth = 0;
        std::vector<uint32_t> order;
        insertion_order(mesh_->coarse_count, order);
        for (uint32_t c : order) {
            if (!wanted[c]) continue;
            ShadowVolume v = make_shadow_volume(view_->coarse_bounds.obb(mesh_->first_coarse + c), light_);
            ClusterNode leaf;
            fill(c, leaf);
            if (!v.valid) {
                leaf.near = leaf.near_min = 0;
                always_coarse_.push_back(add_cluster_node(all, leaf));
                continue;
            }
            insert(all, root_, v, leaf, depth);
        }
        return depth;
    }

    // A tree over the fine clusters [first, first + count) of the mesh; returns its root. Clusters without
    // a volume go to `always`.
    uint32_t build_fine_tree(Nodes& nodes, uint32_t first, uint32_t count, uint32_t& depth,
                             std::vector<uint32_t>& always, size_t& skipped) const {
        uint32_t root = none;
        std::vector<uint32_t> order;
        insertion_order(count, order);
        for (uint32_t i : order) {
            uint32_t f = first + i;
            const FineCluster& r = view_->fine[mesh_->first_fine + f];
            if (one_sided_ &&
                skippable(view_->fine_bounds, mesh_->first_fine + f, {r.first_triangle, r.triangle_count})) {
                ++skipped;
                continue;
            }
            ShadowVolume v = view_->fine_bounds.obbs
                ? make_shadow_volume(view_->fine_bounds.obb(mesh_->first_fine + f), light_)
                : ShadowVolume{};
            if (!v.valid) {
                always.push_back(f);
                continue;
            }
            ClusterNode leaf;
            leaf.cluster = f;
            insert(nodes, root, v, leaf, depth);
        }
        return root;
    }

    // The 4 edge rays of a volume's cone: where pairs of its planes meet.
    static void edge_rays(const ShadowVolume& v, double rays[4][3]) {
        const int pairs[4][2] = {{0, 2}, {2, 1}, {1, 3}, {3, 0}};
        for (int r = 0; r < 4; ++r) {
            const float* a = v.normal[pairs[r][0]];
            const float* b = v.normal[pairs[r][1]];
            double c[3] = {double(a[1]) * b[2] - double(a[2]) * b[1], double(a[2]) * b[0] - double(a[0]) * b[2],
                           double(a[0]) * b[1] - double(a[1]) * b[0]};
            // Orient each ray into the cone: on the inside of the other two planes.
            const float* other = v.normal[pairs[(r + 2) % 4][0]];
            double s = c[0] * other[0] + c[1] * other[1] + c[2] * other[2];
            double len = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
            for (int k = 0; k < 3; ++k) rays[r][k] = (s < 0 ? -c[k] : c[k]) / len;
        }
    }

    // Inserts volume `v` ending in `leaf` into the tree rooted at `root` (a variable outside the arrays).
    static void insert(Nodes& nodes, uint32_t& root, const ShadowVolume& v, ClusterNode leaf, uint32_t& max_depth) {
        float near = math::round_down(v.near);
        double rays[4][3];
        edge_rays(v, rays);
        // Every direction in the cone is a positive mix of the rays, whose length is at least `spread` times
        // the mix's weight: |cos| against any plane is at most max over rays / spread.
        double dir[3] = {0, 0, 0};
        for (const double* r : rays)
            for (int k = 0; k < 3; ++k) dir[k] += r[k];
        double dl = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]), spread = 1;
        for (const double* r : rays) spread = std::min(spread, (r[0] * dir[0] + r[1] * dir[1] + r[2] * dir[2]) / dl);
        // The rays in float, to classify 4 at once. Their rounding and the float sines err by under 3e-7,
        // so the thresholds below are 1e-6: a volume goes to one side only when it is clearly there.
        Pyramid cone;
        for (int r = 0; r < 4; ++r) {
            cone.rx[r] = float(rays[r][0]);
            cone.ry[r] = float(rays[r][1]);
            cone.rz[r] = float(rays[r][2]);
        }
        // Walk down while the volume falls clearly on one side; stop at the first empty slot, named by the
        // node that holds it (indices, since the appends below may move the arrays).
        uint32_t* slot = &root;
        uint32_t parent = none, depth = 0;
        int which = 0;
        for (uint32_t at = root; at != none;) {
            ++depth;
            parent = at;
            if (at & cluster_bit) {  // past an earlier volume's chain: into its subtree
                ClusterNode& l = nodes.clusters[at & ~cluster_bit];
                l.near_min = std::min(l.near_min, near);
                which = 0;
                at = l.inside;
                continue;
            }
            PlaneNode& node = nodes.planes[at];
            node.near_min = std::min(node.near_min, near);
            float smin, smax;
            ray_sines(node.n, cone, smin, smax);
            which = smin > 1e-6f ? 0 : smax < -1e-6f ? 1 : 2;
            if (which == 2) {
                double widest = std::max(double(smax), -double(smin)) + 1e-6;
                double sine = spread > 0 ? std::min(1.0, widest / spread + 1e-7) : 1.0;
                node.straddle_sine = std::max(node.straddle_sine, math::round_up(sine));
            }
            at = node.child[which];
        }
        // The chain: plane 0 -inside-> plane 1 -> plane 2 -> plane 3 -> the leaf.
        uint32_t first = uint32_t(nodes.planes.size());
        for (int k = 0; k < 4; ++k) {
            PlaneNode plane{};
            for (int j = 0; j < 3; ++j) plane.n[j] = v.normal[k][j];
            plane.near_min = near;
            plane.child[0] = first + uint32_t(k) + 1;
            plane.child[1] = plane.child[2] = none;
            nodes.planes.push_back(plane);
        }
        leaf.near = leaf.near_min = near;
        leaf.first_plane = first;
        nodes.planes.back().child[0] = add_cluster_node(nodes, leaf);
        if (parent == none)
            *slot = first;
        else if (parent & cluster_bit)
            nodes.clusters[parent & ~cluster_bit].inside = first;
        else
            nodes.planes[parent].child[which] = first;
        max_depth = std::max(max_depth, depth + 5);
    }

    std::vector<PlaneNode> planes_;
    std::vector<ClusterNode> clusters_;
    std::vector<uint32_t> always_fine_;    // fine clusters tested without a volume (ranges per coarse node)
    std::vector<uint32_t> always_coarse_;  // coarse cluster nodes entered for every query
    IndexRange top_always_;                // one level: the always-tested fine clusters
    uint32_t root_ = none;
    uint32_t depth_ = 0;
};

}  // namespace CB_LANES
}  // namespace cb
