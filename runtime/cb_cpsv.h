// Clustered partitioned shadow volumes (the thesis's CPSV, chapter 2): per point light, ternary trees of
// planes through the light (TOP-trees) over the shadow volumes of cluster boxes. A query walks the trees to
// the few clusters whose volume holds the point and tests their triangles exactly (cb_shadow.h), so its
// answers are those of occluded_reference, faster.
//
// A tree. Each volume is a chain of its 4 planes: the inside branch of one plane leads to the next, and
// the last to a cluster node. A plane node has three children: inside (volumes entirely on its inside),
// outside (entirely outside) and straddling (both); a query follows the side its point is on, and the
// straddling child unless the point is farther from the plane than any volume down there reaches. A
// cluster node acts when the point is beyond the closing distance, then goes on into its own subtree:
// volumes inserted later that lie inside this one. Nothing is dropped there: a volume is only conservative,
// so a point inside it may still be lit by its cluster and shadowed by a later one. Volumes go in, one by
// one, in a shuffled order (fixed seed) that keeps the trees balanced. Clusters whose box holds the light,
// or is level with it, have no volume: they are tested for every point that gets that far.
//
// Two levels: a tree over the coarse clusters' volumes whose cluster nodes enter a tree over that coarse
// cluster's fine clusters (when the asset has coarse boxes; otherwise one tree over the fine clusters).
//
// Every node also keeps the smallest closing distance of the volumes below it: a point nearer the light
// than that skips the whole subtree (nothing there can shadow it). Plane nodes and cluster nodes live in
// two arrays of 32-byte records; a child reference with the top bit set names a cluster node.
//
// Building allocates (std::vector); queries do not: the caller passes a stack of stack_size() entries.
// Header-only C++17, no exceptions. MIT licensed (runtime/LICENSE).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "cb_asset.h"
#include "cb_shadow.h"

namespace cb {

class ClusterShadowTree {
public:
    static constexpr uint32_t none = 0xffffffffu;

    // One instance of the asset's meshes, for one light given in world space. In one-sided mode
    // (cb_shadow.h), clusters whose front cone holds the light, and that have no double-sided triangle,
    // cannot block anything and are left out. `two_levels` false builds one tree over the fine clusters
    // even when the asset has coarse boxes.
    void build(const AssetView& view, uint32_t instance, const double* world_light, bool one_sided = false,
               bool two_levels = true) {
        view_ = &view;
        one_sided_ = one_sided;
        skipped_ = 0;
        planes_.clear();
        leaves_.clear();
        always_fine_.clear();
        always_coarse_.clear();
        root_ = none;
        depth_ = 0;
        top_always_ = {};
        usable_ = invert_instance(view.instances[instance].transform, inverse_);
        if (!usable_) return;  // a singular transform flattens the mesh: it blocks nothing
        apply_instance(inverse_, world_light, light_);
        mesh_ = &view.meshes[view.instances[instance].mesh];
        bool two = two_levels && view.coarse_bounds.obbs;
        // At most 4 planes and a cluster node per volume: reserve once, so capacity is what is used.
        size_t volumes = mesh_->fine_count + (two ? mesh_->coarse_count : 0);
        planes_.reserve(volumes * 4);
        leaves_.reserve(volumes);

        if (!two) {
            // One level: every fine cluster in one tree; always-tested ones in one list.
            uint32_t fine_depth = 0;
            root_ = build_fine_tree(0, mesh_->fine_count, fine_depth, always_fine_);
            top_always_ = {0, uint32_t(always_fine_.size())};
            depth_ = fine_depth;
            shrink();
            return;
        }
        // Two levels: a fine tree per coarse cluster, then the coarse tree over them.
        std::vector<uint32_t> fine_roots(mesh_->coarse_count, none);
        std::vector<Range> fine_always(mesh_->coarse_count);
        std::vector<bool> wanted(mesh_->coarse_count, true);
        uint32_t fine_depth = 0;
        for (uint32_t c = 0; c < mesh_->coarse_count; ++c) {
            const ClusterRange& r = view.coarse[mesh_->first_coarse + c];
            if (one_sided_ && skippable(view.coarse_bounds, mesh_->first_coarse + c, coarse_triangles(c))) {
                skipped_ += r.count;
                wanted[c] = false;
                continue;
            }
            uint32_t first_always = uint32_t(always_fine_.size()), depth = 0;
            fine_roots[c] = build_fine_tree(r.first, r.count, depth, always_fine_);
            fine_always[c] = {first_always, uint32_t(always_fine_.size()) - first_always};
            fine_depth = std::max(fine_depth, depth);
        }
        uint32_t coarse_depth = 0;
        for (uint32_t c : shuffled(mesh_->coarse_count)) {
            if (!wanted[c]) continue;
            ShadowVolume v = make_shadow_volume(view.coarse_bounds.obb(mesh_->first_coarse + c), light_);
            Leaf leaf;
            leaf.kind = Leaf::coarse;
            leaf.fine_root = fine_roots[c];
            leaf.always = fine_always[c];
            if (!v.valid) {  // the light is in or level with this coarse box: enter its fine tree every time
                leaf.near = leaf.near_min = 0;
                always_coarse_.push_back(add_leaf(leaf));
                continue;
            }
            insert(root_, v, leaf, coarse_depth);
        }
        depth_ = coarse_depth + fine_depth + 1;
        shrink();
    }

    // Entries the query stack needs: pending siblings along the deepest path through both levels.
    size_t stack_size() const { return size_t(depth_) * 2 + 4; }

    // True when the segment from world point p to the light is blocked by this instance. `stack` holds
    // stack_size() entries.
    bool occluded(const double* world_p, uint32_t* stack, QueryStats* stats = nullptr) const {
        if (!usable_) return false;
        Query q;
        apply_instance(inverse_, world_p, q.p);
        for (int k = 0; k < 3; ++k) q.e[k] = q.p[k] - light_[k];
        q.dist = std::sqrt(q.e[0] * q.e[0] + q.e[1] * q.e[1] + q.e[2] * q.e[2]);
        q.stats = stats;
        for (uint32_t i = top_always_.first; i < top_always_.first + top_always_.count; ++i)
            if (test_cluster(always_fine_[i], q)) return true;
        for (uint32_t node : always_coarse_)  // coarse clusters around the light, one walk each
            if (walk(node, stack, q)) return true;
        return root_ != none && walk(root_, stack, q);
    }

    size_t node_count() const { return planes_.size() + leaves_.size(); }
    // Bytes this tree holds (the asset it reads is not counted).
    size_t memory_bytes() const {
        return planes_.capacity() * sizeof(PlaneNode) + leaves_.capacity() * sizeof(Leaf) +
               (always_fine_.capacity() + always_coarse_.capacity()) * sizeof(uint32_t);
    }
    size_t always_tested() const { return always_fine_.size(); }
    size_t skipped_clusters() const { return skipped_; }  // one-sided: fine clusters the light sees from the front

private:
    static constexpr uint32_t leaf_bit = 0x80000000u;

    struct Range {
        uint32_t first = 0, count = 0;
    };

    // A plane through the light; inside: dot(n, p - light) >= 0.
    struct PlaneNode {          // 32 bytes
        float n[3];             // unit to float precision
        // Every point of every volume in the straddling subtree makes an angle with the plane whose sine is
        // at most this (rounded up); a point farther from the plane skips that subtree.
        float straddle_sine;
        float near_min;         // smallest closing distance below (rounded down)
        uint32_t child[3];      // inside, outside, straddling
    };

    // The end of a volume's chain: its cluster, then the volumes inserted later inside it.
    struct Leaf {               // 32 bytes
        enum Kind : uint32_t { fine, coarse };
        float near = 0;         // closing distance (rounded down)
        float near_min = 0;     // the smaller of near and the closing distances in `inside`
        uint32_t inside = none;
        uint32_t fine_root = none;  // coarse: the root of its fine tree
        uint32_t cluster = none;    // fine: the fine cluster (mesh-local)
        Range always;               // coarse: its fine clusters tested whenever it is entered
        Kind kind = fine;
    };

    static_assert(sizeof(PlaneNode) == 32 && sizeof(Leaf) == 32, "tree nodes are 32-byte records (RUNTIME.md)");

    struct Query {
        double p[3], e[3], dist;
        QueryStats* stats;
    };

    static float round_down(double x) {
        float f = float(x);
        return double(f) > x ? std::nextafter(f, 0.0f) : f;
    }
    static float round_up(double x) {
        float f = float(x);
        return double(f) < x ? std::nextafter(f, 2.0f) : f;
    }

    uint32_t add_leaf(const Leaf& leaf) {
        leaves_.push_back(leaf);
        return uint32_t(leaves_.size() - 1) | leaf_bit;
    }

    // Renumbers the nodes in the order a walk meets them (depth first, the inside branch next), so that a
    // query reads mostly consecutive memory; and releases unused capacity (clusters without a volume).
    void shrink() {
        std::vector<uint32_t> plane_to(planes_.size(), none), leaf_to(leaves_.size(), none), todo;
        std::vector<PlaneNode> planes;
        std::vector<Leaf> leaves;
        planes.reserve(planes_.size());
        leaves.reserve(leaves_.size());
        auto visit = [&](uint32_t start) {
            todo.push_back(start);
            while (!todo.empty()) {
                uint32_t ref = todo.back();
                todo.pop_back();
                if (ref == none) continue;
                if (ref & leaf_bit) {
                    const Leaf& l = leaves_[ref & ~leaf_bit];
                    leaf_to[ref & ~leaf_bit] = uint32_t(leaves.size());
                    leaves.push_back(l);
                    todo.push_back(l.inside);
                    todo.push_back(l.fine_root);
                } else {
                    const PlaneNode& n = planes_[ref];
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
            return ref == none ? none : ref & leaf_bit ? (leaf_to[ref & ~leaf_bit] | leaf_bit) : plane_to[ref];
        };
        for (PlaneNode& n : planes)
            for (uint32_t& c : n.child) c = map(c);
        for (Leaf& l : leaves) l.inside = map(l.inside), l.fine_root = map(l.fine_root);
        root_ = map(root_);
        for (uint32_t& r : always_coarse_) r = map(r);
        planes_ = std::move(planes);
        leaves_ = std::move(leaves);
    }

    bool walk(uint32_t start, uint32_t* stack, const Query& q) const {
        size_t top = 0;
        stack[top++] = start;
        while (top) {
            uint32_t ref = stack[--top];
            for (;;) {  // down the inside children directly; the other children wait on the stack
                if (q.stats) ++q.stats->nodes_visited;
                if (ref & leaf_bit) {
                    const Leaf& leaf = leaves_[ref & ~leaf_bit];
                    if (q.dist < leaf.near_min) break;  // nearer the light than everything here
                    if (leaf.inside != none) stack[top++] = leaf.inside;
                    if (q.dist < leaf.near) break;
                    if (leaf.kind == Leaf::fine) {  // its triangles
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

    // Insertion order for n items, the same for every build (xorshift with a fixed seed).
    static std::vector<uint32_t> shuffled(uint32_t n) {
        std::vector<uint32_t> order(n);
        for (uint32_t i = 0; i < n; ++i) order[i] = i;
        uint64_t state = 0x9e3779b97f4a7c15ULL;
        for (uint32_t i = n; i > 1; --i) {
            state ^= state << 13, state ^= state >> 7, state ^= state << 17;
            std::swap(order[i - 1], order[state % i]);
        }
        return order;
    }

    Range coarse_triangles(uint32_t c) const {
        const ClusterRange& r = view_->coarse[mesh_->first_coarse + c];
        const FineCluster& a = view_->fine[mesh_->first_fine + r.first];
        const FineCluster& z = view_->fine[mesh_->first_fine + r.first + r.count - 1];
        return {a.first_triangle, z.first_triangle + z.triangle_count - a.first_triangle};
    }

    // One-sided: a cluster the light sees entirely from the front, with no double-sided triangle.
    bool skippable(const LevelBounds& bounds, uint32_t index, Range triangles) const {
        if (!bounds.cones || !light_in_front_cone(bounds.cone(index), light_)) return false;
        for (uint32_t t = triangles.first; t < triangles.first + triangles.count; ++t)
            if (view_->double_sided(size_t(mesh_->first_triangle) + t)) return false;
        return true;
    }

    // A tree over the fine clusters [first, first + count) of the mesh; returns its root. Clusters without
    // a volume go to `always`.
    uint32_t build_fine_tree(uint32_t first, uint32_t count, uint32_t& depth, std::vector<uint32_t>& always) {
        uint32_t root = none;
        for (uint32_t i : shuffled(count)) {
            uint32_t f = first + i;
            const FineCluster& r = view_->fine[mesh_->first_fine + f];
            if (one_sided_ && skippable(view_->fine_bounds, mesh_->first_fine + f, {r.first_triangle, r.triangle_count})) {
                ++skipped_;
                continue;
            }
            ShadowVolume v = view_->fine_bounds.obbs ? make_shadow_volume(view_->fine_bounds.obb(mesh_->first_fine + f), light_)
                                                     : ShadowVolume{};
            if (!v.valid) {
                always.push_back(f);
                continue;
            }
            Leaf leaf;
            leaf.kind = Leaf::fine;
            leaf.cluster = f;
            insert(root, v, leaf, depth);
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
    void insert(uint32_t& root, const ShadowVolume& v, Leaf leaf, uint32_t& max_depth) {
        float near = round_down(v.near);
        double rays[4][3];
        edge_rays(v, rays);
        // Every direction in the cone is a positive mix of the rays, whose length is at least `spread` times
        // the mix's weight: |cos| against any plane is at most max over rays / spread.
        double dir[3] = {0, 0, 0};
        for (const double* r : rays)
            for (int k = 0; k < 3; ++k) dir[k] += r[k];
        double dl = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]), spread = 1;
        for (const double* r : rays) spread = std::min(spread, (r[0] * dir[0] + r[1] * dir[1] + r[2] * dir[2]) / dl);
        // Walk down while the volume falls clearly on one side; stop at the first empty slot, named by the
        // node that holds it (indices, since the appends below may move the arrays).
        uint32_t* slot = &root;
        uint32_t parent = none, depth = 0;
        int which = 0;
        for (uint32_t at = root; at != none;) {
            ++depth;
            parent = at;
            if (at & leaf_bit) {  // past an earlier volume's chain: into its subtree
                Leaf& l = leaves_[at & ~leaf_bit];
                l.near_min = std::min(l.near_min, near);
                which = 0;
                at = l.inside;
                continue;
            }
            PlaneNode& node = planes_[at];
            node.near_min = std::min(node.near_min, near);
            bool in = true, out = true;
            double widest = 0;
            for (const double* r : rays) {
                double s = node.n[0] * r[0] + node.n[1] * r[1] + node.n[2] * r[2];
                in &= s > 1e-9;
                out &= s < -1e-9;
                widest = std::max(widest, std::fabs(s));
            }
            which = in ? 0 : out ? 1 : 2;
            if (which == 2) {
                double sine = spread > 0 ? std::min(1.0, widest / spread + 1e-7) : 1.0;
                node.straddle_sine = std::max(node.straddle_sine, round_up(sine));
            }
            at = node.child[which];
        }
        // The chain: plane 0 -inside-> plane 1 -> plane 2 -> plane 3 -> the leaf.
        uint32_t first = uint32_t(planes_.size());
        for (int k = 0; k < 4; ++k) {
            PlaneNode plane{};
            for (int j = 0; j < 3; ++j) plane.n[j] = v.normal[k][j];
            plane.near_min = near;
            plane.child[0] = first + uint32_t(k) + 1;
            plane.child[1] = plane.child[2] = none;
            planes_.push_back(plane);
        }
        leaf.near = leaf.near_min = near;
        planes_.back().child[0] = add_leaf(leaf);
        if (parent == none) *slot = first;
        else if (parent & leaf_bit) leaves_[parent & ~leaf_bit].inside = first;
        else planes_[parent].child[which] = first;
        max_depth = std::max(max_depth, depth + 5);
    }

    // A cluster's triangles, unless the segment certainly misses its box (a volume only says the point
    // is in the box's shadow cone, which a 4-plane outline makes wider than the box).
    bool test_cluster(uint32_t f, const Query& q) const {
        if (view_->fine_bounds.obbs && !segment_may_touch_box(view_->fine_bounds.obb(mesh_->first_fine + f), q.p, light_))
            return false;
        return cluster_blocks(*view_, *mesh_, f, q.p, light_, one_sided_, q.stats);
    }

    const AssetView* view_ = nullptr;
    const MeshRecord* mesh_ = nullptr;
    double inverse_[12] = {}, light_[3] = {};
    bool usable_ = false, one_sided_ = false;
    size_t skipped_ = 0;
    std::vector<PlaneNode> planes_;
    std::vector<Leaf> leaves_;
    std::vector<uint32_t> always_fine_;    // fine clusters tested without a volume (ranges per coarse node)
    std::vector<uint32_t> always_coarse_;  // coarse cluster nodes entered for every query
    Range top_always_;                     // one level: the always-tested fine clusters
    uint32_t root_ = none;
    uint32_t depth_ = 0;
};

// The batch form: `trees` holds one tree per instance, all built for the same light; out[i] is 1 when point
// i (xyz doubles) is in shadow. `stack` holds the largest stack_size() of the trees. The trees are const:
// callers may split the points across threads, each with its own stack.
inline void occluded_batch(const ClusterShadowTree* trees, size_t tree_count, const double* points, size_t n, uint8_t* out,
                           uint32_t* stack, QueryStats* stats = nullptr) {
    for (size_t i = 0; i < n; ++i) {
        out[i] = 0;
        for (size_t t = 0; t < tree_count && !out[i]; ++t) out[i] = trees[t].occluded(points + i * 3, stack, stats) ? 1 : 0;
    }
}

}  // namespace cb
