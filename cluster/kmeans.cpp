// Hierarchical k-means++ over triangle boxes seen as 6-D points (min xyz, max xyz): the distance is
// |min1 - min2|^2 + |max1 - max2|^2 and a centre is the mean box (Meister and Bittner's clustering of
// triangles for BVH construction, used in section 2.2.2 of the thesis, chapter 2).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>

#include "cluster.h"
#include "nearest_centre.h"
#include "random.h"

namespace cb {
namespace {

// Nodes of more points than this run k-means++ and Lloyd on this many of them (drawn from the node's seed).
const size_t lloyd_sample_limit = 2048;

// Lloyd stops once at most one point in this many changed cluster in an iteration. Iterating to no change
// at all gave the dragon's fine clusters a 1.4% smaller mean radius and the same largest one, at 1.5 times
// the time (bench_cluster, docs/PERFORMANCE.md).
const size_t lloyd_settled = 20;

typedef float FloatPair __attribute__((vector_size(8)));
typedef double DoublePair __attribute__((vector_size(16)));

inline float distance2(const float* a, const float* b) {
    float s = 0;
    for (int k = 0; k < 6; ++k) {
        float d = a[k] - b[k];
        s += d * d;
    }
    return s;
}

// KMeans's working arrays, kept by each thread from call to call: a bake runs k-means on thousands of chunks,
// and an array of a megabyte or more otherwise comes fresh from the system each time (the mmap threshold,
// cli/main.cpp), every page of it faulted in and zeroed again.
struct KMeansScratch {
    std::vector<float> points, sample, centres, nearest, coords;
    std::vector<double> block_sums;
    std::vector<uint32_t> assignment, pick;
    std::vector<uint8_t> picked;
    std::vector<std::vector<uint32_t>> groups;
    std::vector<std::pair<float, uint32_t>> keyed;
};

class KMeans {
public:
    KMeans(const float* boxes, uint32_t max_size, uint32_t branching, uint32_t max_iterations, KMeansScratch& s)
        : boxes_(boxes),
          max_size_(max_size),
          branching_(std::max(2u, branching)),
          max_iterations_(std::max(1u, max_iterations)),
          points_(s.points),
          sample_(s.sample),
          centres_(s.centres),
          nearest_(s.nearest),
          coords_(s.coords),
          block_sums_(s.block_sums),
          assignment_(s.assignment),
          pick_(s.pick),
          picked_(s.picked),
          groups_(s.groups),
          keyed_(s.keyed) {}

    void split(uint32_t* tris, size_t n, uint64_t seed, std::vector<uint32_t>& leaves) {
        if (n <= max_size_) {
            if (n) leaves.push_back(uint32_t(n));
            return;
        }
        size_t k = std::min<size_t>(branching_, (n + max_size_ - 1) / max_size_);
        // Two leaves' worth: a balanced median cut gives two halves of at least max_size / 2, where a
        // 2-means split of so few triangles often leaves a sliver of one or two.
        if (k == 2) return median_split(tris, n, seed, leaves);

        gather(tris, n);
        // Large nodes find their centres on a sample, then assign every point once: the top levels cut
        // tens of thousands of triangles into k parts, which a few thousand place as well.
        const float* sample = points_.data();
        size_t m = n;
        if (n > lloyd_sample_limit) {
            m = lloyd_sample_limit;
            draw_sample(n, m, splitmix(seed ^ 0x5a));
            sample = sample_.data();
        }
        size_t found = seed_centres(sample, m, k, seed);
        if (found < 2) return slice(tris, n, leaves);  // every box identical: any cut is as compact
        lloyd(sample, m, found);
        if (m < n) {
            assignment_.assign(n, uint32_t(-1));
            nearest_.resize(n);
            assign_nearest(points_.data(), n, centres_.data(), found, assignment_.data(), nearest_.data());
        }
        group(tris, n, found);
        merge_small(groups_);
        if (groups_.size() < 2) return slice(tris, n, leaves);

        // Write the groups back contiguously, then recurse into each (which reuses groups_).
        std::vector<size_t> sizes(groups_.size());
        for (size_t g = 0, at = 0; g < groups_.size(); at += sizes[g++]) {
            sizes[g] = groups_[g].size();
            std::copy(groups_[g].begin(), groups_[g].end(), tris + at);
        }
        for (size_t g = 0, at = 0; g < sizes.size(); at += sizes[g++])
            split(tris + at, sizes[g], splitmix(seed ^ (g + 1)), leaves);
    }

private:
    void gather(const uint32_t* tris, size_t n) {
        points_.resize(n * 6);
        // memcpy of a known size is a few moves; copy_n, not knowing the ranges apart, calls memmove per box.
        for (size_t i = 0; i < n; ++i) std::memcpy(&points_[i * 6], boxes_ + size_t(tris[i]) * 6, 6 * sizeof(float));
    }

    // `m` distinct points of the node, drawn uniformly (a partial Fisher-Yates shuffle), in node order.
    void draw_sample(size_t n, size_t m, uint64_t seed) {
        SplitMix rng{seed};
        pick_.resize(n);
        std::iota(pick_.begin(), pick_.end(), 0u);
        for (size_t i = 0; i < m; ++i) std::swap(pick_[i], pick_[i + size_t(rng.next() % (n - i))]);
        // Into node order by marks read back in one pass: sorting the m picks cost more (1.2% of a bake).
        picked_.assign(n, 0);
        for (size_t i = 0; i < m; ++i) picked_[pick_[i]] = 1;
        sample_.resize(m * 6);
        for (size_t j = 0, i = 0; i < m; ++j)
            if (picked_[j]) std::memcpy(&sample_[6 * i++], &points_[j * 6], 6 * sizeof(float));
    }

    // k-means++: the first centre uniformly, each next one with probability proportional to the squared
    // distance to the nearest centre so far. Returns how many distinct centres exist (fewer than k when the
    // points have fewer distinct values). The points go to six coordinate arrays once, for lower_nearest's
    // lanes; a draw walks the sums of blocks of 64 points, then the points of one block.
    size_t seed_centres(const float* points, size_t n, size_t k, uint64_t seed) {
        SplitMix rng{seed};
        centres_.assign(k * 6, 0.0f);
        coords_.resize(n * 6);
        for (size_t i = 0; i < n; ++i)
            for (int j = 0; j < 6; ++j) coords_[size_t(j) * n + i] = points[i * 6 + j];
        const size_t blocks = (n + lower_nearest_block - 1) / lower_nearest_block;
        block_sums_.resize(blocks);
        nearest_.assign(n, INFINITY);
        size_t first = size_t(rng.next() % n);
        std::copy_n(&points[first * 6], 6, &centres_[0]);
        lower_nearest(coords_.data(), n, &centres_[0], nearest_.data(), block_sums_.data());
        size_t found = 1;
        while (found < k) {
            double total = 0;
            for (double b : block_sums_) total += b;
            if (!(total > 0)) break;
            size_t pick = draw(rng.uniform() * total);
            if (pick == SIZE_MAX) break;
            std::copy_n(&points[pick * 6], 6, &centres_[found * 6]);
            lower_nearest(coords_.data(), n, &centres_[found * 6], nearest_.data(), block_sums_.data());
            ++found;
        }
        centres_.resize(found * 6);
        return found;
    }

    // The first point whose running sum of nearest_ passes `target`, among points not on a centre; the
    // last such point when rounding leaves the target unreached; SIZE_MAX when there is none.
    size_t draw(double target) const {
        double run = 0;
        for (size_t b = 0; b < block_sums_.size(); ++b) {
            const size_t at = b * lower_nearest_block, end = std::min(nearest_.size(), at + lower_nearest_block);
            if (run + block_sums_[b] > target) {
                double r = run;
                for (size_t i = at; i < end; ++i) {
                    r += nearest_[i];
                    if (r > target && nearest_[i] > 0) return i;
                }
            }
            run += block_sums_[b];
        }
        for (size_t i = nearest_.size(); i-- > 0;)
            if (nearest_[i] > 0) return i;
        return SIZE_MAX;
    }

    // Lloyd iterations until the assignments settle (or the cap), scanning the points as seed_centres left
    // them in coords_. An empty cluster takes the point farthest from its own centre, so k clusters stay k.
    void lloyd(const float* points, size_t n, size_t k) {
        assignment_.assign(n, uint32_t(-1));
        std::vector<double> sum(k * 6);
        std::vector<uint32_t> size(k);
        for (uint32_t iteration = 0; iteration < max_iterations_; ++iteration) {
            size_t changed =
                assign_nearest(points, n, centres_.data(), k, assignment_.data(), nearest_.data(), coords_.data());
            if (changed * lloyd_settled <= n) break;
            std::fill(sum.begin(), sum.end(), 0.0);
            std::fill(size.begin(), size.end(), 0u);
            // Each cluster's sum adds its points in order. A run of points in one cluster (the points come
            // in space order) adds in registers, not through memory, where each add would wait on the store
            // before it; two coordinates a lane pair, each lane's adds the scalar ones in the same order.
            for (size_t i = 0; i < n;) {
                const uint32_t a = assignment_[i];
                DoublePair run[3];
                std::memcpy(run, &sum[a * 6], sizeof run);
                size_t end = i;
                for (; end < n && assignment_[end] == a; ++end) {
                    FloatPair p[3];
                    std::memcpy(p, &points[end * 6], sizeof p);
                    for (int d = 0; d < 3; ++d) run[d] += __builtin_convertvector(p[d], DoublePair);
                }
                std::memcpy(&sum[a * 6], run, sizeof run);
                size[a] += uint32_t(end - i);
                i = end;
            }
            for (size_t c = 0; c < k; ++c) {
                if (size[c] == 0) {
                    size_t far = size_t(std::max_element(nearest_.begin(), nearest_.end()) - nearest_.begin());
                    std::copy_n(&points[far * 6], 6, &centres_[c * 6]);
                    nearest_[far] = 0;  // do not hand the same point to two empty clusters
                    continue;
                }
                for (int d = 0; d < 6; ++d) centres_[c * 6 + d] = float(sum[c * 6 + d] / size[c]);
            }
        }
    }

    // groups_: the members of each cluster in their current order, empty ones dropped. The lists keep their
    // storage from node to node.
    void group(const uint32_t* tris, size_t n, size_t k) {
        groups_.resize(k);
        for (auto& g : groups_) g.clear();
        // A run of points in one cluster (the points come in space order) goes in at once.
        for (size_t i = 0, end; i < n; i = end) {
            const uint32_t a = assignment_[i];
            for (end = i + 1; end < n && assignment_[end] == a;) ++end;
            groups_[a].insert(groups_[a].end(), tris + i, tris + end);
        }
        groups_.erase(std::remove_if(groups_.begin(), groups_.end(), [](const auto& g) { return g.empty(); }),
                      groups_.end());
    }

    // Merges each group under half the limit into the sibling whose mean box is nearest, while the merged
    // group still fits one leaf: fewer slivers, no leaf over the limit.
    void merge_small(std::vector<std::vector<uint32_t>>& groups) {
        for (;;) {
            size_t smallest = 0;
            for (size_t g = 1; g < groups.size(); ++g)
                if (groups[g].size() < groups[smallest].size()) smallest = g;
            if (groups.size() < 2 || groups[smallest].size() * 2 >= max_size_) return;
            float a[6];
            mean_box(groups[smallest], a);
            size_t best = SIZE_MAX;
            float best_d = INFINITY;
            for (size_t g = 0; g < groups.size(); ++g) {
                if (g == smallest || groups[g].size() + groups[smallest].size() > max_size_) continue;
                float b[6];
                mean_box(groups[g], b);
                float d = distance2(a, b);
                if (d < best_d) {
                    best_d = d;
                    best = g;
                }
            }
            if (best == SIZE_MAX) return;
            groups[best].insert(groups[best].end(), groups[smallest].begin(), groups[smallest].end());
            groups.erase(groups.begin() + std::ptrdiff_t(smallest));
        }
    }

    void mean_box(const std::vector<uint32_t>& g, float out[6]) const {
        double s[6] = {};
        for (uint32_t t : g)
            for (int d = 0; d < 6; ++d) s[d] += boxes_[size_t(t) * 6 + d];
        for (int d = 0; d < 6; ++d) out[d] = float(s[d] / double(g.size()));
    }

    // Halves at the median of box centres along the axis where they spread most.
    void median_split(uint32_t* tris, size_t n, uint64_t seed, std::vector<uint32_t>& leaves) {
        float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (size_t i = 0; i < n; ++i)
            for (int k = 0; k < 3; ++k) {
                float c = centre(tris[i], k);
                lo[k] = std::min(lo[k], c);
                hi[k] = std::max(hi[k], c);
            }
        int axis = 0;
        for (int k = 1; k < 3; ++k)
            if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
        size_t half = n / 2;
        // Each centre once, beside its triangle, instead of looked up through the triangle at every comparison.
        keyed_.resize(n);
        for (size_t i = 0; i < n; ++i) keyed_[i] = {centre(tris[i], axis), tris[i]};
        std::nth_element(
            keyed_.begin(), keyed_.begin() + std::ptrdiff_t(half), keyed_.end(), [](const auto& a, const auto& b) {
                return a.first < b.first ||
                    (a.first == b.first && a.second < b.second);  // a total order: the same cut on every run
            });
        for (size_t i = 0; i < n; ++i) tris[i] = keyed_[i].second;
        split(tris, half, splitmix(seed ^ 1), leaves);
        split(tris + half, n - half, splitmix(seed ^ 2), leaves);
    }

    float centre(uint32_t t, int axis) const { return boxes_[size_t(t) * 6 + axis] + boxes_[size_t(t) * 6 + 3 + axis]; }

    void slice(uint32_t*, size_t n, std::vector<uint32_t>& leaves) const {
        for (size_t at = 0; at < n; at += max_size_) leaves.push_back(uint32_t(std::min<size_t>(max_size_, n - at)));
    }

    const float* boxes_;
    uint32_t max_size_, branching_, max_iterations_;
    std::vector<float>&points_, &sample_, &centres_, &nearest_, &coords_;
    std::vector<double>& block_sums_;
    std::vector<uint32_t>&assignment_, &pick_;
    std::vector<uint8_t>& picked_;
    std::vector<std::vector<uint32_t>>& groups_;
    std::vector<std::pair<float, uint32_t>>& keyed_;
};

}  // namespace

void kmeans_split(const float* boxes, uint32_t* tris, size_t count, uint32_t max_size, uint32_t branching,
                  uint32_t max_iterations, uint64_t seed, std::vector<uint32_t>& leaf_sizes) {
    thread_local KMeansScratch scratch;
    KMeans(boxes, std::max(1u, max_size), branching, max_iterations, scratch).split(tris, count, seed, leaf_sizes);
}

}  // namespace cb
