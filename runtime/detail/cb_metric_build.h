// The metric trees' parts that do not depend on the traversal (cb_metric_tree.h): the node record, the
// angular geometry of cones and capsule-cones seen from a light (angles between directions, the distance from
// a direction to a volume's central element, fast_angle's bounded approximation), and the two builds over a
// list of volumes (the thesis's heuristic insertion, and the reference build with far pivots and median
// splits). Header-only C++17, no exceptions; building allocates (std::vector). MIT licensed
// (runtime/LICENSE).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "cb_math.h"
#include "cb_tile.h"

// The angle helpers sit in the walk's inner loop, where a call costs as much as their arithmetic.
#if defined(__GNUC__)
#define CB_METRIC_INLINE inline __attribute__((always_inline))
#else
#define CB_METRIC_INLINE inline
#endif

namespace cb {
inline namespace CB_LANES {
namespace metric_tree {

constexpr uint32_t none = TraversalBase::none;
constexpr uint32_t coarse_bit = 0x80000000u;  // in Node::cluster: a coarse cluster, whose fine tree is entered
// Radians, on every comparison of the walk: far above the error of fast_angle (below 3e-9) and of double
// rounding, which the build's and the walk's angles both carry.
constexpr double tolerance = 1e-7;
constexpr double pi = 3.14159265358979323846;  // M_PI is POSIX, not C++

// One volume seen from the light, and the split of the volumes inserted below it.
struct Node {                        // 72 bytes
    float dir_a[3];                  // direction of the sphere's centre, or of the capsule segment's first end
    float alpha;                     // half-angle of the cone, rounded up
    float dir_b[3];                  // direction of the capsule segment's other end (dir_a for a sphere)
    float delta;                     // split distance of s (see the top of the file)
    float overlap_min, overlap_max;  // s over the overlap child's volumes, rounded outward (min > max: none)
    float near_child_min;            // the least s of the near child's volumes, rounded down
    float far_child_max;             // the most s of the far child's volumes, rounded up
    float near;                      // distance from the light to the volume, rounded down
    float near_min;                  // the smallest near in the subtree rooted here
    uint32_t child[3];               // near, far, overlap
    uint32_t cluster;                // fine cluster (mesh-local), or coarse cluster | coarse_bit
};
static_assert(sizeof(Node) == 72, "metric tree nodes are 72-byte records (RUNTIME.md)");

// A node's central element in double: a point (a == b), or the minor arc from a to b with n the unit normal of
// its plane. a and b are read as stored (unit to float precision): every angle below is atan2 of a sine and
// a cosine, which does not depend on their lengths, and the lune's sides are signs.
struct Central {
    double a[3], b[3], n[3];
    bool arc;
};

inline void normalize(double* v) {
    const double inv = 1 / std::sqrt(math::dot3(v, v));
    for (int k = 0; k < 3; ++k) v[k] *= inv;
}

// The angle between u and v (unit or not), accurate at every size (atan2 of the sine and the cosine).
inline double angle(const double* u, const double* v) {
    double c[3];
    math::cross3(u, v, c);
    return std::atan2(std::sqrt(math::dot3(c, c)), math::dot3(u, v));
}

// atan(t) for |t| <= tan(pi / 8): its alternating series to t^17, whose remainder is below t^19 / 19 < 3e-9.
// The polynomial in t^2 is summed in Estrin's order (pairs, then pairs of pairs): a quarter of Horner's chain
// of dependent products, and the same error to within double rounding.
CB_METRIC_INLINE double atan_small(double t) {
    const double x = t * t, x2 = x * x, x4 = x2 * x2;
    const double p01 = 1.0 - x * (1.0 / 3), p23 = 1.0 / 5 - x * (1.0 / 7), p45 = 1.0 / 9 - x * (1.0 / 11),
                 p67 = 1.0 / 13 - x * (1.0 / 15);
    const double p03 = p01 + x2 * p23, p47 = p45 + x2 * p67;
    return t * (p03 + x4 * (p47 + x4 * (1.0 / 17)));
}

// The angle atan2(y, x) in [0, pi] for y >= 0, within 3e-9 radians (plus double rounding) of std::atan2, for
// a fraction of its time: the walk compares such angles with a tolerance of 1e-7. One division: the ratio of
// the smaller to the larger of y and |x|, or beyond tan(pi / 8) their difference over their sum (the tangent
// of the angle's distance from pi / 4).
CB_METRIC_INLINE double fast_angle(double y, double x) {
    const double ax = std::fabs(x);
    if (!(y > 0)) return x < 0 ? pi : 0;
    const bool steep = y > ax;  // then pi / 2 - atan(ax / y)
    const double lo = steep ? ax : y, hi = steep ? y : ax;
    const double tan_eighth = 0.41421356237309503;  // tan(pi / 8), rounded up
    double a = lo > tan_eighth * hi ? 0.25 * pi + atan_small((lo - hi) / (lo + hi)) : atan_small(lo / hi);
    if (steep) a = 0.5 * pi - a;
    return x < 0 ? pi - a : a;
}

// An upper bound of the angle between u and v (unit or not), for the tile walk's spread: below 45 degrees
// the tangent (within its cube over 3 of the angle: a division instead of fast_angle's series), otherwise
// fast_angle.
inline double angle_above(const double* u, const double* v) {
    double c[3];
    math::cross3(u, v, c);
    const double sine = std::sqrt(math::dot3(c, c)), cosine = math::dot3(u, v);
    return sine < cosine ? sine / cosine : fast_angle(sine, cosine);
}

// An upper bound of sin(a) for a in [0, pi / 2] (to double rounding), within a^7 / 5040 of it (its series
// cut after a term that adds): for the cone filters, which add a margin far above that rounding.
inline double sine_above(double a) {
    const double x = a * a;
    return a * (1 - x * (1.0 / 6 - x * (1.0 / 120)));
}

// The angle between u and v (unit or not: the angle does not depend on their lengths), by fast_angle.
CB_METRIC_INLINE double fast_angle_between(const double* u, const double* v) {
    double c[3];
    math::cross3(u, v, c);
    return fast_angle(std::sqrt(math::dot3(c, c)), math::dot3(u, v));
}

CB_METRIC_INLINE Central central_of(const Node& node) {
    Central c;
    for (int k = 0; k < 3; ++k) {
        c.a[k] = node.dir_a[k];
        c.b[k] = node.dir_b[k];
        c.n[k] = 0;
    }
    c.arc = node.dir_a[0] != node.dir_b[0] || node.dir_a[1] != node.dir_b[1] || node.dir_a[2] != node.dir_b[2];
    if (c.arc) {
        math::cross3(c.a, c.b, c.n);
        normalize(c.n);
    }
    return c;
}

// The angle from unit direction u to the central element: to the point, or to the nearest point of the arc
// (on the arc's plane between its ends: the angle off the plane; otherwise the nearer end). `fast`: by
// fast_angle, within 3e-9 radians of the exact angle (the build and the walk); otherwise by std::atan2 and
// std::asin (the tests' reference).
template <bool fast>
CB_METRIC_INLINE double distance(const Central& c, const double* u) {
    if (!c.arc) return fast ? fast_angle_between(u, c.a) : angle(u, c.a);
    double x[3];
    math::cross3(c.a, u, x);
    const double after_a = math::dot3(x, c.n);
    math::cross3(u, c.b, x);
    const double before_b = math::dot3(x, c.n);
    if (after_a >= 0 && before_b >= 0) {
        const double off = std::min(1.0, std::fabs(math::dot3(u, c.n)));
        return fast ? fast_angle(off, std::sqrt(std::max(0.0, 1 - off * off))) : std::asin(off);
    }
    return fast ? std::min(fast_angle_between(u, c.a), fast_angle_between(u, c.b))
                : std::min(angle(u, c.a), angle(u, c.b));
}

// A volume while the tree is built: the node it becomes, and its central element as a disc on the sphere of
// directions (midpoint m, every point of the element within `half` of it).
struct Element {
    Node node;
    double m[3], half;
    double delta;  // the heuristic's split distance, halved on each near step
};

// The working arrays of a build, kept between builds by reusing the traversal object.
struct Work {
    std::vector<Element> elements;
    std::vector<uint32_t> order, todo, to;
    std::vector<Node> built;
};

// s over element e's directions against pivot p (central element cp): [lo, hi].
CB_METRIC_INLINE void s_range(const Node& p, const Central& cp, const Element& e, double& lo, double& hi) {
    const double d = distance<true>(cp, e.m), spread = e.half + double(e.node.alpha);
    lo = d - spread - double(p.alpha);
    hi = d + spread - double(p.alpha);
}

// The thesis's insertion (algorithm 5), in a shuffled order with a fixed seed.
inline uint32_t build_heuristic(Work& work, uint32_t& depth) {
    std::vector<Element>& elements = work.elements;
    std::vector<Node>& built = work.built;
    // The angle of the cone that holds every element: the split distance each starts with.
    double mean[3] = {0, 0, 0};
    for (const Element& e : elements)
        for (int k = 0; k < 3; ++k) mean[k] += e.m[k];
    double scene = pi;
    if (math::dot3(mean, mean) > 0) {
        normalize(mean);
        scene = 0;
        for (const Element& e : elements)
            scene = std::max(scene, fast_angle_between(mean, e.m) + e.half + e.node.alpha);
        scene = std::min(scene, pi);
    }
    insertion_order(uint32_t(elements.size()), work.order);
    uint32_t root = none;
    for (uint32_t index : work.order) {
        Element& e = elements[index];
        e.delta = scene;
        uint32_t* link = &root;
        uint32_t d = 1;
        while (*link != none) {
            Node& p = built[*link];
            double lo, hi;
            // The pivot's central element made again at each step: kept beside the nodes, it would cost more
            // in cache misses than a point's conversion to double.
            s_range(p, central_of(p), e, lo, hi);
            p.near_min = std::min(p.near_min, e.node.near);
            if (hi <= double(p.delta)) {
                p.near_child_min = std::min(p.near_child_min, math::round_down(lo));
                link = &p.child[0];
                e.delta *= 0.5;
            } else if (lo > double(p.delta)) {
                p.far_child_max = std::max(p.far_child_max, math::round_up(hi));
                link = &p.child[1];
            } else {
                p.overlap_min = std::min(p.overlap_min, math::round_down(lo));
                p.overlap_max = std::max(p.overlap_max, math::round_up(hi));
                link = &p.child[2];
            }
            ++d;
        }
        e.node.delta = float(e.delta);
        *link = uint32_t(built.size());
        built.push_back(e.node);
        depth = std::max(depth, d);
    }
    return root;
}

// The reference build: for each set, the pivot is the one of up to 16 sampled elements whose summed
// distance to up to 64 sampled others is largest (after Yianilos), delta the median of the others'
// central s (after Uhlmann); sets are split until empty.
inline uint32_t build_reference(Work& work, uint32_t& depth) {
    std::vector<Element>& elements = work.elements;
    std::vector<Node>& built = work.built;
    // Each set is a range of `items`; where its subtree's root goes is a (node, child) slot, an index that
    // survives the nodes' array growing.
    insertion_order(uint32_t(elements.size()), work.order);
    std::vector<uint32_t> items = work.order;
    struct Slot {
        uint32_t node, child;  // node none: the root
    };
    struct Job {
        uint32_t first, count, depth;
        Slot slot;
    };
    uint32_t root = none;
    std::vector<Job> jobs{{0, uint32_t(items.size()), 1, {none, 0}}};
    std::vector<double> keys;
    std::vector<uint32_t> near_set, far_set, over_set;
    uint64_t state = 0x2545f4914f6cdd1dULL;
    auto next = [&state]() {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        return state;
    };
    while (!jobs.empty()) {
        const Job job = jobs.back();
        jobs.pop_back();
        if (job.count == 0) continue;
        uint32_t* set = items.data() + job.first;
        // The pivot.
        uint32_t best = 0;
        double best_sum = -1;
        const uint32_t candidates = std::min<uint32_t>(job.count, 16), others = std::min<uint32_t>(job.count, 64);
        for (uint32_t k = 0; k < candidates; ++k) {
            const uint32_t c = job.count <= 16 ? k : uint32_t(next() % job.count);
            double sum = 0;
            for (uint32_t j = 0; j < others; ++j) {
                const uint32_t o = job.count <= 64 ? j : uint32_t(next() % job.count);
                sum += angle(elements[set[c]].m, elements[set[o]].m);
            }
            if (sum > best_sum) {
                best_sum = sum;
                best = c;
            }
        }
        std::swap(set[0], set[best]);
        Element& pe = elements[set[0]];
        Node pivot = pe.node;
        const Central cp = central_of(pivot);
        keys.clear();
        for (uint32_t j = 1; j < job.count; ++j)
            keys.push_back(distance<true>(cp, elements[set[j]].m) - double(pivot.alpha));
        float delta = 0;
        if (!keys.empty()) {
            std::nth_element(keys.begin(), keys.begin() + keys.size() / 2, keys.end());
            delta = float(keys[keys.size() / 2]);
        }
        pivot.delta = delta;
        near_set.clear();
        far_set.clear();
        over_set.clear();
        for (uint32_t j = 1; j < job.count; ++j) {
            const Element& e = elements[set[j]];
            double lo, hi;
            s_range(pivot, cp, e, lo, hi);
            pivot.near_min = std::min(pivot.near_min, e.node.near);
            if (hi <= double(delta)) {
                pivot.near_child_min = std::min(pivot.near_child_min, math::round_down(lo));
                near_set.push_back(set[j]);
            } else if (lo > double(delta)) {
                pivot.far_child_max = std::max(pivot.far_child_max, math::round_up(hi));
                far_set.push_back(set[j]);
            } else {
                pivot.overlap_min = std::min(pivot.overlap_min, math::round_down(lo));
                pivot.overlap_max = std::max(pivot.overlap_max, math::round_up(hi));
                over_set.push_back(set[j]);
            }
        }
        const uint32_t index = uint32_t(built.size());
        built.push_back(pivot);
        if (job.slot.node == none)
            root = index;
        else
            built[job.slot.node].child[job.slot.child] = index;
        depth = std::max(depth, job.depth);
        // The three sets, back into the range after the pivot.
        uint32_t at = job.first + 1;
        const std::vector<uint32_t>* parts[3] = {&near_set, &far_set, &over_set};
        for (uint32_t k = 0; k < 3; ++k) {
            const uint32_t begin = at;
            for (uint32_t v : *parts[k]) items[at++] = v;
            jobs.push_back({begin, at - begin, job.depth + 1, {index, k}});
        }
    }
    return root;
}

}  // namespace metric_tree
}  // namespace CB_LANES
}  // namespace cb
