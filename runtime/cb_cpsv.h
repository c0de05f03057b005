// Clustered partitioned shadow volumes (the thesis's CPSV, chapter 2): per point light, a ternary tree of
// planes through the light (a TOP-tree) over the shadow volumes of the fine clusters' boxes. A query walks
// the tree to the few clusters whose volume holds the point and tests their triangles exactly
// (cb_shadow.h), so its answers are those of occluded_reference, faster.
//
// The tree. Each volume is a chain of its 4 planes: the inside branch of one plane leads to the next, and
// the last to a cluster node. A plane node has three children: inside (volumes entirely on its inside),
// outside (entirely outside) and straddling (both); a query follows the side its point is on and always the
// straddling child. A cluster node tests its cluster when the point is beyond the closing distance, then
// goes on into its own subtree: volumes inserted later that lie inside this one. Nothing is dropped there:
// a cluster's volume is only conservative, so a point inside it may still be lit by it and shadowed by a
// later one. Volumes go in, one by one, in a shuffled order (fixed seed) that keeps the tree balanced.
// Clusters whose box holds the light, or is level with it, have no volume and are tested for every point.
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
    // cannot block anything and are left out.
    void build(const AssetView& view, uint32_t instance, const double* world_light, bool one_sided = false) {
        view_ = &view;
        one_sided_ = one_sided;
        skipped_ = 0;
        nodes_.clear();
        always_.clear();
        root_ = none;
        depth_ = 0;
        usable_ = invert_instance(view.instances[instance].transform, inverse_);
        if (!usable_) return;  // a singular transform flattens the mesh: it blocks nothing
        apply_instance(inverse_, world_light, light_);
        mesh_ = &view.meshes[view.instances[instance].mesh];
        uint32_t n = mesh_->fine_count;
        // Shuffled insertion order, the same for every build (xorshift with a fixed seed).
        std::vector<uint32_t> order(n);
        for (uint32_t i = 0; i < n; ++i) order[i] = i;
        uint64_t state = 0x9e3779b97f4a7c15ULL;
        for (uint32_t i = n; i > 1; --i) {
            state ^= state << 13, state ^= state >> 7, state ^= state << 17;
            uint32_t j = uint32_t(state % i);
            uint32_t t = order[i - 1];
            order[i - 1] = order[j];
            order[j] = t;
        }
        for (uint32_t f : order) insert(f);
    }

    // Entries the query stack needs: the tree's depth plus the pending siblings along a path.
    size_t stack_size() const { return size_t(depth_) * 2 + 2; }

    // True when the segment from world point p to the light is blocked by this instance. `stack` holds
    // stack_size() entries.
    bool occluded(const double* world_p, uint32_t* stack, QueryStats* stats = nullptr) const {
        if (!usable_) return false;
        double p[3];
        apply_instance(inverse_, world_p, p);
        double e[3] = {p[0] - light_[0], p[1] - light_[1], p[2] - light_[2]};
        double dist = std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
        for (uint32_t f : always_)
            if (test_cluster(f, p, stats)) return true;
        size_t top = 0;
        if (root_ != none) stack[top++] = root_;
        while (top) {
            const Node& node = nodes_[stack[--top]];
            if (stats) ++stats->nodes_visited;
            if (node.cluster != none) {  // cluster node: its triangles, then the volumes inside it
                if (dist >= node.near && test_cluster(node.cluster, p, stats)) return true;
                if (node.child[0] != none) stack[top++] = node.child[0];
                continue;
            }
            double s = node.n[0] * e[0] + node.n[1] * e[1] + node.n[2] * e[2];
            double tol = 1e-9 * node.n_length * dist;  // near the plane: both sides
            if (node.child[2] != none && std::fabs(s) <= (node.straddle_sine + 1e-9) * node.n_length * dist)
                stack[top++] = node.child[2];
            if (s <= tol && node.child[1] != none) stack[top++] = node.child[1];
            if (s >= -tol && node.child[0] != none) stack[top++] = node.child[0];
        }
        return false;
    }

    size_t node_count() const { return nodes_.size(); }
    size_t memory_bytes() const { return nodes_.capacity() * sizeof(Node) + always_.capacity() * sizeof(uint32_t); }
    size_t always_tested() const { return always_.size(); }
    size_t skipped_clusters() const { return skipped_; }  // one-sided: clusters the light sees from the front

private:
    struct Node {
        double n[3] = {0, 0, 0};  // plane through the light; inside: dot(n, p - light) >= 0
        double n_length = 0;
        // Plane nodes: every point of every volume in the straddling subtree makes an angle with the plane
        // whose sine is at most this; a point farther from the plane skips that subtree.
        double straddle_sine = 0;
        double near = 0;          // cluster nodes: closing distance
        uint32_t cluster = none;  // none for plane nodes
        uint32_t child[3] = {none, none, none};  // plane: inside, outside, straddling; cluster: inside
    };

    // The 4 edge rays of a volume's cone: where pairs of its planes meet.
    static void edge_rays(const ShadowVolume& v, double rays[4][3]) {
        const int pairs[4][2] = {{0, 2}, {2, 1}, {1, 3}, {3, 0}};
        for (int r = 0; r < 4; ++r) {
            const double* a = v.normal[pairs[r][0]];
            const double* b = v.normal[pairs[r][1]];
            double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
            // Orient each ray into the cone: on the inside of the other two planes.
            const double* other = v.normal[pairs[(r + 2) % 4][0]];
            double s = c[0] * other[0] + c[1] * other[1] + c[2] * other[2];
            double len = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
            for (int k = 0; k < 3; ++k) rays[r][k] = (s < 0 ? -c[k] : c[k]) / len;
        }
    }

    uint32_t add_node(const Node& n) {
        nodes_.push_back(n);
        return uint32_t(nodes_.size() - 1);
    }

    void insert(uint32_t f) {
        if (one_sided_ && view_->fine_bounds.cones && light_in_front_cone(view_->fine_bounds.cones[mesh_->first_fine + f], light_)) {
            const ClusterRange& r = view_->fine[mesh_->first_fine + f];
            bool any_double = false;
            for (uint32_t t = r.first; t < r.first + r.count && !any_double; ++t)
                any_double = view_->double_sided(size_t(mesh_->first_triangle) + t);
            if (!any_double) {
                ++skipped_;
                return;
            }
        }
        ShadowVolume v = view_->fine_bounds.obbs ? make_shadow_volume(view_->fine_bounds.obbs[mesh_->first_fine + f], light_)
                                                 : ShadowVolume{};
        if (!v.valid) {
            always_.push_back(f);
            return;
        }
        double rays[4][3];
        edge_rays(v, rays);
        // Every direction in the cone is a positive mix of the rays, whose length is at least `spread` times
        // the mix's weight: |cos| against any plane is at most max over rays / spread.
        double dir[3] = {0, 0, 0};
        for (const double* r : rays)
            for (int k = 0; k < 3; ++k) dir[k] += r[k];
        double dl = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]), spread = 1;
        for (const double* r : rays) spread = std::min(spread, (r[0] * dir[0] + r[1] * dir[1] + r[2] * dir[2]) / dl);
        // Walk down while the volume falls clearly on one side; stop at the first empty slot, named by its
        // parent and child index (pointers into nodes_ would not survive the appends below).
        uint32_t parent = none, at = root_;
        int which = 0;
        uint32_t depth = 0;
        while (at != none) {
            const Node node = nodes_[at];  // a copy: the straddle bound is written back below
            ++depth;
            if (node.cluster != none) {  // past an earlier volume's chain: into its subtree
                which = 0;
            } else {
                bool in = true, out = true;
                double widest = 0;
                for (const double* r : rays) {
                    double s = (node.n[0] * r[0] + node.n[1] * r[1] + node.n[2] * r[2]) / node.n_length;
                    in &= s > 1e-9;
                    out &= s < -1e-9;
                    widest = std::max(widest, std::fabs(s));
                }
                which = in ? 0 : out ? 1 : 2;
                if (which == 2) {
                    double sine = spread > 0 ? std::min(1.0, widest / spread) : 1.0;
                    nodes_[at].straddle_sine = std::max(node.straddle_sine, sine);
                }
            }
            parent = at;
            at = nodes_[at].child[which];
        }
        // The chain: plane 0 -inside-> plane 1 -> plane 2 -> plane 3 -> cluster node.
        uint32_t first = uint32_t(nodes_.size());
        for (int k = 0; k < 4; ++k) {
            Node plane;
            for (int j = 0; j < 3; ++j) plane.n[j] = v.normal[k][j];
            plane.n_length = std::sqrt(plane.n[0] * plane.n[0] + plane.n[1] * plane.n[1] + plane.n[2] * plane.n[2]);
            plane.child[0] = first + uint32_t(k) + 1;
            add_node(plane);
        }
        Node leaf;
        leaf.cluster = f;
        leaf.near = v.near;
        add_node(leaf);
        (parent == none ? root_ : nodes_[parent].child[which]) = first;
        depth_ = std::max(depth_, depth + 5);
    }

    bool test_cluster(uint32_t f, const double* p, QueryStats* stats) const {
        const ClusterRange& range = view_->fine[mesh_->first_fine + f];
        const float* pos = view_->positions + size_t(mesh_->first_vertex) * 3;
        const uint32_t* tri = view_->triangles + size_t(mesh_->first_triangle) * 3;
        if (stats) ++stats->clusters_tested;
        for (uint32_t t = range.first; t < range.first + range.count; ++t) {
            double corner[3][3];
            for (int k = 0; k < 3; ++k)
                for (int j = 0; j < 3; ++j) corner[k][j] = pos[size_t(tri[size_t(t) * 3 + k]) * 3 + j];
            if (stats) ++stats->triangles_tested;
            bool two_sided = !one_sided_ || view_->double_sided(size_t(mesh_->first_triangle) + t);
            if (segment_triangle(p, light_, corner[0], corner[1], corner[2], two_sided).blocks) return true;
        }
        return false;
    }

    const AssetView* view_ = nullptr;
    const MeshRecord* mesh_ = nullptr;
    double inverse_[12] = {}, light_[3] = {};
    bool usable_ = false, one_sided_ = false;
    size_t skipped_ = 0;
    std::vector<Node> nodes_;
    std::vector<uint32_t> always_;
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
