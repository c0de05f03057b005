// The trees a sun's traversal (cb_sun.h) walks in place of its scan when ShadowBuildOptions::traversal names
// one. Every ray of a sun runs along one direction, so a shadow volume is a prism and everything is decided
// in the sun's frame: across the direction in the plane (u, v), and by height w along it (up toward the sun).
// A point may be shadowed by a volume only when its (u, v) lies in the volume's shadow across the direction
// and its w lies below the volume's top.
//
// - SunLineTree (Traversal::top_two and top_one): the TOP tree of cb_top_tree.h with lines across the
//   direction in place of planes through a light. A box's prism is 4 lines that hold its shadow (a rectangle
//   along its longest projected axis) and its top; line nodes are ternary (inside, outside, straddling), each
//   volume a chain of its 4 lines ending in a prism node, inserted one by one in insertion_order().
// - SunDiscTree (Traversal::mtsv_one and mtsv_two): a metric tree over the discs the clusters' bounding spheres
//   cast across the direction, with the Euclidean metric of that plane (a sun has no angles to measure):
//   each node a disc that holds the discs below it, split at the median of the wider spread of their
//   centres, laid out in walk order with the index past each subtree, so that the walk needs no stack.
//
// Both hand the volumes that may hold some of a tile's points to pass(id, top, points). They are built in
// double and stored in float rounded outward; the walks compare in double, with the margin the caller gives
// (far above the rounding of the points' coordinates and of the stored floats). Header-only C++17, no
// exceptions; building allocates (std::vector), walks do not. MIT licensed (runtime/LICENSE).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "../cb_asset.h"
#include "cb_math.h"

namespace cb {
inline namespace CB_LANES {

// The prism that holds some points' rays toward the sun: the rectangle [lo, hi] bounding their (u, v), the
// lowest w among them, the largest |u| + |v| + |w|, and the margin every test of them takes.
struct SunPrism {
    double lo[2], hi[2], low, size, margin;
};

// A cluster box's prism along a sun: 4 lines across the direction that hold its shadow (inside line k:
// n[k] . (u, v) >= c[k]), the rectangle's corners where they meet, and the box's highest w.
struct SunBoxPrism {
    float n[4][2];
    float c[4];  // rounded down
    double corner[4][2];
    float top;  // rounded up
};

// The prism of `box` (mesh frame) along frame[0], in the coordinates of frame[1], frame[2], frame[0] taken
// from `origin`. The rectangle lies along the box axis whose shadow is longest; its normals are float, and
// its sides are pushed out by 1e-12 of the box's size and distance from `origin`, far above double rounding.
inline SunBoxPrism sun_box_prism(const Obb& box, const double* origin, const double (*frame)[3]) {
    double h[3];
    padded_halves(box, h);
    const double c[3] = {box.center[0] - origin[0], box.center[1] - origin[1], box.center[2] - origin[2]};
    const double cu = math::dot3(c, frame[1]), cv = math::dot3(c, frame[2]), cw = math::dot3(c, frame[0]);
    double au[3], av[3], aw[3];  // the half axes in the sun's frame
    int longest = 0;
    for (int k = 0; k < 3; ++k) {
        const double a[3] = {box.axis[k][0], box.axis[k][1], box.axis[k][2]};
        au[k] = h[k] * math::dot3(a, frame[1]);
        av[k] = h[k] * math::dot3(a, frame[2]);
        aw[k] = h[k] * math::dot3(a, frame[0]);
        if (au[k] * au[k] + av[k] * av[k] > au[longest] * au[longest] + av[longest] * av[longest]) longest = k;
    }
    const double len = std::sqrt(au[longest] * au[longest] + av[longest] * av[longest]);
    const float e[2] = {len > 0 ? float(au[longest] / len) : 1.0f, len > 0 ? float(av[longest] / len) : 0.0f};
    const double slack = 1e-12 * (std::fabs(cu) + std::fabs(cv) + std::fabs(cw) + h[0] + h[1] + h[2]);
    SunBoxPrism p;
    const float normals[4][2] = {{e[0], e[1]}, {-e[0], -e[1]}, {-e[1], e[0]}, {e[1], -e[0]}};
    double side[4];
    for (int k = 0; k < 4; ++k) {
        const double nu = normals[k][0], nv = normals[k][1];
        double c_k = nu * cu + nv * cv - slack;
        for (int j = 0; j < 3; ++j) c_k -= std::fabs(nu * au[j] + nv * av[j]);
        p.n[k][0] = normals[k][0];
        p.n[k][1] = normals[k][1];
        p.c[k] = math::round_down(c_k);
        side[k] = p.c[k];
    }
    // Lines 0 and 1 run along e, 2 and 3 across it: corner (i, j) solves n_i . x = c_i, n_j . x = c_j.
    const int pairs[4][2] = {{0, 2}, {2, 1}, {1, 3}, {3, 0}};
    for (int q = 0; q < 4; ++q) {
        const int i = pairs[q][0], j = pairs[q][1];
        const double a = p.n[i][0], b = p.n[i][1], d = p.n[j][0], f = p.n[j][1], det = a * f - b * d;
        p.corner[q][0] = (side[i] * f - b * side[j]) / det;
        p.corner[q][1] = (a * side[j] - side[i] * d) / det;
    }
    p.top = math::round_up(cw + std::fabs(aw[0]) + std::fabs(aw[1]) + std::fabs(aw[2]) + slack);
    return p;
}

// The points of `subset` (coordinates u, v, w, indexed by bit) within distance r of (cu, cv) across the
// direction and no higher than `top`: those whose ray toward the sun may meet a disc's sphere. In double.
inline uint64_t sun_disc_points(double cu, double cv, double r, double top, uint64_t subset, const double* u,
                                const double* v, const double* w) {
    const double r2 = r * r;
    for (uint64_t b = subset; b; b &= b - 1) {
        const uint32_t i = math::lowest_bit(b);
        const double du = u[i] - cu, dv = v[i] - cv;
        if (!(du * du + dv * dv <= r2 && w[i] <= top)) subset &= ~(uint64_t(1) << i);
    }
    return subset;
}

namespace sun_tree {
constexpr uint32_t none = 0xffffffffu;
constexpr uint32_t prism_bit = 0x80000000u;  // in a child reference: a prism node

// A line across the direction; inside: n . (u, v) >= c.
struct LineNode {  // 32 bytes
    float n[2], c;
    float reach;        // every volume of the straddling subtree lies within this of the line (rounded up)
    float top;          // the highest top below (rounded up)
    uint32_t child[3];  // inside, outside, straddling
};

// The end of a volume's chain: its cluster, then the volumes inserted later inside it.
struct PrismNode {  // 16 bytes
    float top;
    float top_max;  // the higher of top and the tops in `inside`
    uint32_t inside;
    uint32_t first_line;  // its 4 lines, consecutive
};

// A disc across the direction that holds the discs of its subtree, and their highest top.
struct DiscNode {  // 24 bytes
    float u, v, r, top;
    uint32_t next;  // the node after its subtree
    uint32_t id;    // a leaf's cluster; none for an inner node
};
}  // namespace sun_tree

class SunLineTree {
public:
    static constexpr uint32_t none = sun_tree::none;

    void clear() {
        lines_.clear();
        prisms_.clear();
        ids_.clear();
        depth_ = 0;
    }

    // Inserts the prism of cluster `id` into the tree whose root is `root` (none: empty).
    void insert(uint32_t& root, const SunBoxPrism& v, uint32_t id) {
        using sun_tree::prism_bit;
        uint32_t parent = none, depth = 0;
        int which = 0;
        for (uint32_t at = root; at != none;) {
            ++depth;
            parent = at;
            if (at & prism_bit) {  // past an earlier volume's chain: into its subtree
                sun_tree::PrismNode& p = prisms_[at & ~prism_bit];
                p.top_max = std::max(p.top_max, v.top);
                which = 0;
                at = p.inside;
                continue;
            }
            sun_tree::LineNode& node = lines_[at];
            node.top = std::max(node.top, v.top);
            double lo = INFINITY, hi = -INFINITY;
            for (const double* x : v.corner) {
                const double s = double(node.n[0]) * x[0] + double(node.n[1]) * x[1] - double(node.c);
                lo = std::min(lo, s);
                hi = std::max(hi, s);
                if (!(std::fabs(s) < INFINITY)) {  // a side beyond float's range: straddles, reaching everywhere
                    lo = -INFINITY;
                    hi = INFINITY;
                }
            }
            which = lo > 0 ? 0 : hi < 0 ? 1 : 2;
            if (which == 2) node.reach = std::max(node.reach, math::round_up(std::max(hi, -lo)));
            at = node.child[which];
        }
        // The chain: line 0 -inside-> line 1 -> line 2 -> line 3 -> the prism node.
        const uint32_t first = uint32_t(lines_.size());
        for (int k = 0; k < 4; ++k) {
            sun_tree::LineNode line{};
            line.n[0] = v.n[k][0];
            line.n[1] = v.n[k][1];
            line.c = v.c[k];
            line.top = v.top;
            line.child[0] = first + uint32_t(k) + 1;
            line.child[1] = line.child[2] = none;
            lines_.push_back(line);
        }
        prisms_.push_back({v.top, v.top, none, first});
        ids_.push_back(id);
        lines_.back().child[0] = uint32_t(prisms_.size() - 1) | prism_bit;
        if (parent == none)
            root = first;
        else if (parent & prism_bit)
            prisms_[parent & ~prism_bit].inside = first;
        else
            lines_[parent].child[which] = first;
        depth_ = std::max(depth_, depth + 5);
    }

    // Entries a walk's stack needs.
    size_t stack_size() const { return size_t(depth_) * 2 + 4; }
    size_t node_count() const { return lines_.size() + prisms_.size(); }
    size_t memory_bytes() const {
        return lines_.capacity() * sizeof(sun_tree::LineNode) + prisms_.capacity() * sizeof(sun_tree::PrismNode) +
            ids_.capacity() * sizeof(uint32_t);
    }

    // The walk from `root` by the points `in` (coordinates u, v, w, indexed by bit) within prism P: every
    // volume whose prism, grown by P.margin, holds some of them that are still set in `alive`, to
    // pass(id, top, those points). A line's side is taken for the whole rectangle at once; both sides are
    // taken within twice the margin (a rectangle grown by the margin reaches that much past its corners).
    template <class Pass>
    void walk(uint32_t root, uint64_t in, const uint64_t& alive, const double* u, const double* v, const double* w,
              const SunPrism& P, uint32_t* stack, Pass pass) const {
        using sun_tree::prism_bit;
        if (root == none) return;
        const double m = P.margin, tol = 2 * m;
        size_t top = 0;
        stack[top++] = root;
        while (top && (in & alive)) {
            uint32_t ref = stack[--top];
            for (;;) {
                if (ref & prism_bit) {
                    const sun_tree::PrismNode& leaf = prisms_[ref & ~prism_bit];
                    if (P.low > leaf.top_max + m) break;
                    if (leaf.inside != none) stack[top++] = leaf.inside;
                    if (P.low > leaf.top + m) break;
                    const uint64_t points = prism_points(leaf, in & alive, u, v, w, m);
                    if (points) pass(ids_[ref & ~prism_bit], double(leaf.top), points);
                    break;
                }
                const sun_tree::LineNode& node = lines_[ref];
                if (P.low > node.top + m) break;
                const double nu = node.n[0], nv = node.n[1];
                const double lo = nu * (nu >= 0 ? P.lo[0] : P.hi[0]) + nv * (nv >= 0 ? P.lo[1] : P.hi[1]) - node.c;
                const double hi = nu * (nu >= 0 ? P.hi[0] : P.lo[0]) + nv * (nv >= 0 ? P.hi[1] : P.lo[1]) - node.c;
                const double reach = double(node.reach) + tol;
                if (node.child[2] != none && !(lo > reach || hi < -reach)) stack[top++] = node.child[2];
                if (lo <= tol && node.child[1] != none) stack[top++] = node.child[1];
                if (hi < -tol || node.child[0] == none) break;
                ref = node.child[0];
            }
        }
    }

private:
    // The points of `subset` inside the 4 lines of `leaf`'s volume, and below its top, within margin m.
    uint64_t prism_points(const sun_tree::PrismNode& leaf, uint64_t subset, const double* u, const double* v,
                          const double* w, double m) const {
        const sun_tree::LineNode* line = &lines_[leaf.first_line];
        for (uint64_t b = subset; b; b &= b - 1) {
            const uint32_t i = math::lowest_bit(b);
            bool in = w[i] <= double(leaf.top) + m;
            for (int k = 0; k < 4 && in; ++k)
                in = double(line[k].n[0]) * u[i] + double(line[k].n[1]) * v[i] - double(line[k].c) >= -m;
            if (!in) subset &= ~(uint64_t(1) << i);
        }
        return subset;
    }

    std::vector<sun_tree::LineNode> lines_;
    std::vector<sun_tree::PrismNode> prisms_;
    std::vector<uint32_t> ids_;  // each prism node's cluster
    uint32_t depth_ = 0;
};

// A cluster's bounding sphere in the sun's frame: its disc across the direction and its top.
struct SunDisc {
    double u, v, r, top;
    uint32_t id;
};

class SunDiscTree {
public:
    static constexpr uint32_t none = sun_tree::none;

    void clear() { nodes_.clear(); }

    // A tree over discs [0, n) (reordered); returns its root (none when n is 0).
    uint32_t build(SunDisc* discs, uint32_t n) {
        if (n == 0) return none;
        const uint32_t root = uint32_t(nodes_.size());
        add(discs, n);
        return root;
    }

    size_t node_count() const { return nodes_.size(); }
    size_t memory_bytes() const { return nodes_.capacity() * sizeof(sun_tree::DiscNode); }

    // The walk of the tree at `root`, as SunLineTree::walk: every leaf whose disc and top, grown by P.margin,
    // hold some of the points `in` still set in `alive`, to pass(id, top, those points).
    template <class Pass>
    void walk(uint32_t root, uint64_t in, const uint64_t& alive, const double* u, const double* v, const double* w,
              const SunPrism& P, Pass pass) const {
        if (root == none) return;
        const double m = P.margin;
        const uint32_t end = nodes_[root].next;
        for (uint32_t at = root; at < end && (in & alive);) {
            const sun_tree::DiscNode& node = nodes_[at];
            const double r = double(node.r) + m;
            const double du = std::max(std::max(P.lo[0] - node.u, double(node.u) - P.hi[0]), 0.0);
            const double dv = std::max(std::max(P.lo[1] - node.v, double(node.v) - P.hi[1]), 0.0);
            if (P.low > double(node.top) + m || du * du + dv * dv > r * r) {
                at = node.next;
                continue;
            }
            if (node.id != none) {
                const uint64_t points =
                    sun_disc_points(node.u, node.v, double(node.r) + m, double(node.top) + m, in & alive, u, v, w);
                if (points) pass(node.id, double(node.top), points);
            }
            ++at;
        }
    }

private:
    // Adds the subtree of discs [0, n), depth first: a node, its nearer half, its farther half.
    void add(SunDisc* d, uint32_t n) {
        const uint32_t at = uint32_t(nodes_.size());
        nodes_.push_back({});
        double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY}, top = -INFINITY;
        double clo[2] = {INFINITY, INFINITY}, chi[2] = {-INFINITY, -INFINITY};  // the centres' spread
        for (uint32_t i = 0; i < n; ++i) {
            const double c[2] = {d[i].u, d[i].v};
            for (int k = 0; k < 2; ++k) {
                lo[k] = std::min(lo[k], c[k] - d[i].r);
                hi[k] = std::max(hi[k], c[k] + d[i].r);
                clo[k] = std::min(clo[k], c[k]);
                chi[k] = std::max(chi[k], c[k]);
            }
            top = std::max(top, d[i].top);
        }
        sun_tree::DiscNode node;
        node.u = float(0.5 * (lo[0] + hi[0]));
        node.v = float(0.5 * (lo[1] + hi[1]));
        double r = 0;  // from the float centre, so that the stored disc holds every disc below
        for (uint32_t i = 0; i < n; ++i)
            r = std::max(r, std::hypot(d[i].u - double(node.u), d[i].v - double(node.v)) + d[i].r);
        node.r = math::round_up(r * (1 + 1e-12));
        node.top = math::round_up(top);
        node.id = n == 1 ? d[0].id : none;
        if (n > 1) {
            const int k = chi[0] - clo[0] >= chi[1] - clo[1] ? 0 : 1;
            const uint32_t half = n / 2;
            std::nth_element(d, d + half, d + n, [k](const SunDisc& a, const SunDisc& b) {
                const double x = k == 0 ? a.u : a.v, y = k == 0 ? b.u : b.v;
                return x < y || (x == y && a.id < b.id);
            });
            add(d, half);
            add(d + half, n - half);
        }
        node.next = uint32_t(nodes_.size());
        nodes_[at] = node;
    }

    std::vector<sun_tree::DiscNode> nodes_;
};

}  // namespace CB_LANES
}  // namespace cb
