// Clustering: the hierarchy's invariants on generated and real meshes, determinism across thread counts,
// and the building blocks (Morton order, k-means, Forsyth, FIFO ACMR, patches, nearest centre).
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <numeric>
#include <random>

#include "bake.h"
#include "cluster.h"
#include "load.h"
#include "nearest_centre.h"
#include "baked.h"
#include "shared_scenes.h"

namespace fs = std::filesystem;

namespace {

struct TestMesh {
    std::vector<float> positions;
    std::vector<uint32_t> indices;
    size_t vertices() const { return positions.size() / 3; }
    size_t triangles() const { return indices.size() / 3; }
};

// A w x h grid of quads in the plane z = 0, two triangles each, triangles shuffled by `seed` (0: none).
TestMesh grid(int w, int h, float scale = 1, float offset = 0, unsigned seed = 0) {
    TestMesh m;
    for (int j = 0; j <= h; ++j)
        for (int i = 0; i <= w; ++i)
            m.positions.insert(m.positions.end(), {offset + i * scale, offset + j * scale, offset});
    std::vector<std::array<uint32_t, 3>> tris;
    for (int j = 0; j < h; ++j)
        for (int i = 0; i < w; ++i) {
            uint32_t a = uint32_t(j * (w + 1) + i), b = a + 1, c = a + uint32_t(w + 1), d = c + 1;
            tris.push_back({a, b, c});
            tris.push_back({b, d, c});
        }
    if (seed) std::shuffle(tris.begin(), tris.end(), std::mt19937(seed));
    for (auto& t : tris) m.indices.insert(m.indices.end(), t.begin(), t.end());
    return m;
}

bool shares_vertex(const uint32_t* a, const uint32_t* b) {
    for (int x = 0; x < 3; ++x)
        for (int y = 0; y < 3; ++y)
            if (a[x] == b[y]) return true;
    return false;
}

// Every invariant the hierarchy promises.
void check_hierarchy(const cb::Hierarchy& h, const uint32_t* indices, size_t triangle_count,
                     const cb::ClusterOptions& o) {
    ASSERT_EQ(h.order.size(), triangle_count);
    std::vector<uint32_t> sorted(h.order.begin(), h.order.end());
    std::sort(sorted.begin(), sorted.end());
    for (size_t i = 0; i < sorted.size(); ++i) ASSERT_EQ(sorted[i], i) << "order is not a permutation";
    ASSERT_EQ(h.corners.size(), triangle_count * 3);
    for (size_t i = 0; i < triangle_count; ++i)
        for (int k = 0; k < 3; ++k)
            ASSERT_EQ(h.corners[i * 3 + k], indices[size_t(h.order[i]) * 3 + k]) << "corners of triangle " << i;
    ASSERT_FALSE(h.fine_offsets.empty());
    ASSERT_FALSE(h.coarse_offsets.empty());
    EXPECT_EQ(h.fine_offsets.front(), 0u);
    EXPECT_EQ(h.fine_offsets.back(), triangle_count);
    EXPECT_EQ(h.coarse_offsets.front(), 0u);
    EXPECT_EQ(h.coarse_offsets.back(), h.fine_count());
    for (size_t f = 0; f < h.fine_count(); ++f) {
        uint32_t n = h.fine_offsets[f + 1] - h.fine_offsets[f];
        ASSERT_GE(n, 1u);
        ASSERT_LE(n, o.fine_size) << "fine cluster " << f;
    }
    for (size_t c = 0; c < h.coarse_count(); ++c) {
        ASSERT_LT(h.coarse_offsets[c], h.coarse_offsets[c + 1]) << "empty coarse cluster";
        uint32_t tris = h.fine_offsets[h.coarse_offsets[c + 1]] - h.fine_offsets[h.coarse_offsets[c]];
        ASSERT_LE(tris, o.coarse_size) << "coarse cluster " << c;
    }
    if (o.method == cb::ClusterMethod::vco) {  // every fine cluster is one connected patch
        for (size_t f = 0; f < h.fine_count(); ++f) {
            uint32_t first = h.fine_offsets[f], n = h.fine_offsets[f + 1] - first;
            std::vector<bool> reached(n, false);
            reached[0] = true;
            for (bool grew = true; grew;) {
                grew = false;
                for (uint32_t i = 0; i < n; ++i)
                    for (uint32_t j = 0; j < n; ++j)
                        if (reached[i] && !reached[j] &&
                            shares_vertex(indices + size_t(h.order[first + i]) * 3,
                                          indices + size_t(h.order[first + j]) * 3))
                            reached[j] = grew = true;
            }
            ASSERT_TRUE(std::all_of(reached.begin(), reached.end(), [](bool b) { return b; })) << "patch " << f;
        }
    }
}

// Per fine cluster, the extent of its vertices' x and y ranges, combined by `reduce(width, height)`;
// returns the mean over the clusters.
template <class Reduce>
double mean_xy_extent(const float* positions, const uint32_t* indices, const cb::Hierarchy& h, Reduce reduce) {
    double sum = 0;
    for (size_t f = 0; f < h.fine_count(); ++f) {
        float lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
        for (uint32_t i = h.fine_offsets[f]; i < h.fine_offsets[f + 1]; ++i)
            for (int k = 0; k < 3; ++k)
                for (int a = 0; a < 2; ++a) {
                    float x = positions[size_t(indices[size_t(h.order[i]) * 3 + k]) * 3 + a];
                    lo[a] = std::min(lo[a], x);
                    hi[a] = std::max(hi[a], x);
                }
        sum += reduce(double(hi[0] - lo[0]), double(hi[1] - lo[1]));
    }
    return sum / double(h.fine_count());
}

const cb::ClusterMethod all_methods[] = {cb::ClusterMethod::kmeans, cb::ClusterMethod::vco, cb::ClusterMethod::morton};

cb::Hierarchy cluster(const TestMesh& m, cb::ClusterOptions o, unsigned threads = 0) {
    return cb::build_hierarchy(m.positions.data(), m.vertices(), m.indices.data(), m.triangles(), o, nullptr, {},
                               threads);
}

}  // namespace

TEST(Cluster, InvariantsOnAGridForEveryMethodAndSize) {
    TestMesh m = grid(70, 50, 1, 0, 7);  // 7000 shuffled triangles
    for (cb::ClusterMethod method : all_methods)
        for (uint32_t fine : {8u, 16u, 24u, 32u}) {
            SCOPED_TRACE(std::string(cb::method_name(method)) + " fine " + std::to_string(fine));
            cb::ClusterOptions o;
            o.method = method;
            o.fine_size = fine;
            o.coarse_size = 1024;
            check_hierarchy(cluster(m, o), m.indices.data(), m.triangles(), o);
        }
    // The k-means coarse level (the default): tree nodes of at most coarse_size, grown in Morton chunks
    // (several here), or in one tree over the whole mesh.
    for (uint32_t presplit : {0u, 2500u, 65536u}) {
        SCOPED_TRACE("presplit " + std::to_string(presplit));
        cb::ClusterOptions tree;
        tree.coarse_size = 1000;  // not a multiple of anything: the tree's leaves are at most this
        tree.kmeans_presplit = presplit;
        cb::Hierarchy h = cluster(m, tree);
        check_hierarchy(h, m.indices.data(), m.triangles(), tree);
        EXPECT_GE(h.coarse_count(), 7u);
    }
}

TEST(Cluster, KmeansCoarseClustersAreCompacterThanMortonChunks) {
    // Two grids 1000 apart: the Morton chunk at the end of the first grid reaches into the second and spans
    // the gap; a k-means node does not. Compared by the summed AABB diagonals of the coarse clusters.
    TestMesh a = grid(40, 25, 1, 0, 5), b = grid(40, 25, 1, 0, 6);
    TestMesh m = a;
    const uint32_t offset = uint32_t(a.positions.size() / 3);
    for (size_t i = 0; i < b.positions.size(); i += 3)
        m.positions.insert(m.positions.end(), {b.positions[i] + 1000.0f, b.positions[i + 1], b.positions[i + 2]});
    for (uint32_t i : b.indices) m.indices.push_back(i + offset);
    auto spread = [&](const cb::Hierarchy& h) {
        double sum = 0;
        for (size_t c = 0; c < h.coarse_count(); ++c) {
            float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
            for (uint32_t at = h.fine_offsets[h.coarse_offsets[c]]; at < h.fine_offsets[h.coarse_offsets[c + 1]]; ++at)
                for (int k = 0; k < 3; ++k)
                    for (int j = 0; j < 3; ++j) {
                        float x = m.positions[size_t(m.indices[size_t(h.order[at]) * 3 + k]) * 3 + j];
                        lo[j] = std::min(lo[j], x);
                        hi[j] = std::max(hi[j], x);
                    }
            sum += std::sqrt(double(hi[0] - lo[0]) * (hi[0] - lo[0]) + double(hi[1] - lo[1]) * (hi[1] - lo[1]) +
                             double(hi[2] - lo[2]) * (hi[2] - lo[2]));
        }
        return sum;
    };
    cb::ClusterOptions tree, morton;
    tree.coarse_size = morton.coarse_size = 300;
    morton.kmeans_coarse_from_tree = false;
    cb::Hierarchy ht = cluster(m, tree), hm = cluster(m, morton);
    check_hierarchy(ht, m.indices.data(), m.triangles(), tree);
    EXPECT_LT(spread(ht), 0.5 * spread(hm));
}

TEST(Cluster, MortonChunksAreExactlyTheCoarseSize) {
    TestMesh m = grid(40, 40, 1, 0, 3);  // 3200 triangles
    cb::ClusterOptions o;
    o.coarse_size = 1000;
    o.kmeans_coarse_from_tree = false;
    cb::Hierarchy h = cluster(m, o);
    ASSERT_EQ(h.coarse_count(), 4u);
    for (size_t c = 0; c + 1 < h.coarse_count(); ++c)
        EXPECT_EQ(h.fine_offsets[h.coarse_offsets[c + 1]] - h.fine_offsets[h.coarse_offsets[c]], 1000u);
}

TEST(Cluster, IdenticalForAnyThreadCount) {
    TestMesh m = grid(120, 100, 0.5f, 3, 11);  // 24000 triangles, 12 coarse chunks
    for (cb::ClusterMethod method : all_methods) {
        cb::ClusterOptions o;
        o.method = method;
        o.kmeans_presplit = 4096;  // k-means: trees grown in 6 Morton chunks at once
        cb::Hierarchy one = cluster(m, o, 1);
        for (unsigned threads : {2u, 3u, 8u}) {
            cb::Hierarchy many = cluster(m, o, threads);
            EXPECT_EQ(one.order, many.order) << cb::method_name(method) << " threads " << threads;
            EXPECT_EQ(one.corners, many.corners);
            EXPECT_EQ(one.fine_offsets, many.fine_offsets);
            EXPECT_EQ(one.coarse_offsets, many.coarse_offsets);
        }
    }
}

TEST(Cluster, TinyMeshes) {
    for (cb::ClusterMethod method : all_methods)
        for (size_t n : {0u, 1u, 2u, 16u, 17u, 33u}) {
            SCOPED_TRACE(std::string(cb::method_name(method)) + " " + std::to_string(n) + " triangles");
            TestMesh full = grid(40, 1);
            TestMesh m{full.positions,
                       std::vector<uint32_t>(full.indices.begin(), full.indices.begin() + std::ptrdiff_t(n * 3))};
            cb::ClusterOptions o;
            o.method = method;
            cb::Hierarchy h = cluster(m, o);
            check_hierarchy(h, m.indices.data(), m.triangles(), o);
            EXPECT_EQ(h.coarse_count(), n ? 1u : 0u);
            if (method == cb::ClusterMethod::kmeans && n == 17) {  // F + 1: two halves, no sliver
                ASSERT_EQ(h.fine_count(), 2u);
                EXPECT_GE(h.fine_offsets[1], 8u);
                EXPECT_GE(h.fine_offsets[2] - h.fine_offsets[1], 8u);
            }
        }
}

TEST(Cluster, DegenerateCoincidentAndCollinearInput) {
    // 500 copies of one triangle, a repeated-index triangle, zero-area slivers, all points on a line.
    TestMesh same;
    same.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    for (int i = 0; i < 500; ++i) same.indices.insert(same.indices.end(), {0, 1, 2});
    same.indices.insert(same.indices.end(), {0, 0, 1});
    TestMesh line;
    for (int i = 0; i < 300; ++i) line.positions.insert(line.positions.end(), {float(i), float(2 * i), float(-i)});
    for (uint32_t i = 0; i + 2 < 300; ++i) line.indices.insert(line.indices.end(), {i, i + 1, i + 2});
    for (const TestMesh* m : {&same, &line})
        for (cb::ClusterMethod method : all_methods) {
            SCOPED_TRACE(cb::method_name(method));
            cb::ClusterOptions o;
            o.method = method;
            o.coarse_size = 128;
            check_hierarchy(cluster(*m, o), m->indices.data(), m->triangles(), o);
        }
}

TEST(Cluster, HugeCoordinatesKeepResolution) {
    // A 1 m grid a million metres from the origin: Morton codes still separate every triangle.
    TestMesh m = grid(64, 64, 1.0f, 1.0e6f, 5);
    auto order = cb::morton_order(m.positions.data(), m.indices.data(), m.triangles());
    cb::ClusterOptions o;
    o.coarse_size = 512;
    cb::Hierarchy h = cluster(m, o);
    check_hierarchy(h, m.indices.data(), m.triangles(), o);
    // Compact chunks: each coarse chunk of the Morton order spans far less than the whole grid.
    for (size_t c = 0; c < h.coarse_count(); ++c) {
        float lo = INFINITY, hi = -INFINITY;
        for (uint32_t i = h.fine_offsets[h.coarse_offsets[c]]; i < h.fine_offsets[h.coarse_offsets[c + 1]]; ++i)
            for (int k = 0; k < 3; ++k) {
                float x = m.positions[size_t(m.indices[size_t(h.order[i]) * 3 + k]) * 3];
                lo = std::min(lo, x);
                hi = std::max(hi, x);
            }
        EXPECT_LE(hi - lo, 33.0f) << "chunk " << c;
    }
}

TEST(Cluster, MortonOrderIsZOrder) {
    // Eight tiny triangles at the corners of a cube: Z-order visits x first, then y, then z.
    TestMesh m;
    std::vector<int> corner_of_triangle = {7, 3, 5, 1, 6, 2, 4, 0};
    for (int c : corner_of_triangle) {
        float x = float(c & 1), y = float(c >> 1 & 1), z = float(c >> 2 & 1);
        uint32_t base = uint32_t(m.vertices());
        m.positions.insert(m.positions.end(), {x, y, z, x + 0.01f, y, z, x, y + 0.01f, z});
        m.indices.insert(m.indices.end(), {base, base + 1, base + 2});
    }
    auto order = cb::morton_order(m.positions.data(), m.indices.data(), m.triangles());
    for (size_t i = 0; i < 8; ++i) EXPECT_EQ(corner_of_triangle[order[i]], int(i));
}

TEST(Cluster, MortonOrderIsTheSameInParallelAndStable) {
    // 320,000 shuffled triangles (several parts of the parallel sort), half of them duplicated in place so
    // that equal keys must keep their input order.
    TestMesh m = grid(400, 200, 1, 0, 4);
    const size_t half = m.indices.size() / 2;
    m.indices.insert(m.indices.end(), m.indices.begin(), m.indices.begin() + std::ptrdiff_t(half));
    auto one = cb::morton_order(m.positions.data(), m.indices.data(), m.triangles(), 1);
    for (unsigned threads : {2u, 3u, 0u})
        EXPECT_EQ(cb::morton_order(m.positions.data(), m.indices.data(), m.triangles(), threads), one) << threads;
    // Stable: each copy, with the same key as its original, comes after it.
    std::vector<uint32_t> position(m.triangles());
    for (size_t i = 0; i < one.size(); ++i) position[one[i]] = uint32_t(i);
    for (size_t t = 0; t < half / 3; ++t) EXPECT_LT(position[t], position[t + m.triangles() - half / 3]) << t;
}

TEST(Cluster, SortKeysIsTheStableSortOfTheKeys) {
    // Key sets that take every path: tiny, all equal, few distinct values (long runs of ties), keys that
    // differ only in low bits, keys spread over all 63 bits, keys differing in scattered single bits (one
    // split per level, many levels deep), and dense groups far apart whose ranges split twice before they
    // fit in cache; each against std::stable_sort, on one thread and on several.
    std::mt19937_64 rng(7);
    auto spread = [&](size_t n, uint64_t mask) {
        std::vector<uint64_t> k(n);
        for (uint64_t& x : k) x = rng() & mask;
        return k;
    };
    std::vector<std::vector<uint64_t>> sets = {{},
                                               {5},
                                               {3, 1, 2, 1, 3},
                                               std::vector<uint64_t>(100000, 42),
                                               spread(1000, 7),
                                               spread(5000, 0xff00),
                                               spread(5000, (uint64_t(1) << 63) - 1),
                                               spread(20000, 0x8421084210842108),
                                               spread(70000, (uint64_t(1) << 63) - 1),
                                               spread(300000, 0x3ff),
                                               spread(1200000, (uint64_t(1) << 63) - 1)};
    // Three dense groups far apart, each larger than a cached range.
    std::vector<uint64_t> grouped = spread(400000, 0xfffff);
    for (size_t i = 0; i < grouped.size(); ++i) grouped[i] |= uint64_t(i % 3) << 60;
    sets.push_back(grouped);
    for (const std::vector<uint64_t>& keys : sets) {
        std::vector<uint32_t> expected(keys.size());
        std::iota(expected.begin(), expected.end(), 0u);
        std::stable_sort(expected.begin(), expected.end(), [&](uint32_t a, uint32_t b) { return keys[a] < keys[b]; });
        for (unsigned threads : {1u, 2u, 3u}) {
            std::vector<uint64_t> sorted = keys;
            std::vector<uint32_t> order(keys.size());
            cb::sort_keys(sorted.data(), order.data(), sorted.size(), threads);
            ASSERT_EQ(order, expected) << keys.size() << " keys, " << threads << " threads";
            for (size_t i = 0; i < sorted.size(); ++i) ASSERT_EQ(sorted[i], keys[order[i]]) << i;
        }
    }
}

TEST(Cluster, KMeansIsMoreCompactThanMortonSlices) {
    TestMesh m = grid(100, 100, 1, 0, 9);
    auto mean_extent = [&](cb::ClusterMethod method) {
        cb::ClusterOptions o;
        o.method = method;
        return mean_xy_extent(m.positions.data(), m.indices.data(), cluster(m, o),
                              [](double w, double h) { return w + h; });
    };
    EXPECT_LT(mean_extent(cb::ClusterMethod::kmeans), mean_extent(cb::ClusterMethod::morton));
}

TEST(Cluster, FifoAcmrByHand) {
    uint32_t one[] = {0, 1, 2};
    EXPECT_EQ(cb::fifo_acmr(one, 1, 3, 16), 3.0);
    uint32_t quad[] = {0, 1, 2, 2, 1, 3};
    EXPECT_EQ(cb::fifo_acmr(quad, 2, 4, 16), 2.0);
    // A 3-entry FIFO: after 0 1 2 3, vertex 0 has left, so the second triangle misses all of 3, 0... twice.
    uint32_t evict[] = {0, 1, 2, 3, 0, 1};
    EXPECT_EQ(cb::fifo_acmr(evict, 2, 4, 3), 3.0);  // 0 1 2 miss; 3 miss (evicts 0); 0 miss (evicts 1); 1 miss
}

TEST(Cluster, ForsythBeatsAShuffledOrder) {
    TestMesh m = grid(80, 80, 1, 0, 13);
    std::vector<uint32_t> order = cb::forsyth_order(m.indices.data(), m.triangles(), m.vertices(), 32);
    std::vector<uint32_t> sorted = order;
    std::sort(sorted.begin(), sorted.end());
    for (size_t i = 0; i < sorted.size(); ++i) ASSERT_EQ(sorted[i], i);
    std::vector<uint32_t> reordered;
    for (uint32_t t : order)
        reordered.insert(reordered.end(), m.indices.begin() + t * 3, m.indices.begin() + t * 3 + 3);
    double before = cb::fifo_acmr(m.indices.data(), m.triangles(), m.vertices(), 32);
    double after = cb::fifo_acmr(reordered.data(), m.triangles(), m.vertices(), 32);
    EXPECT_GT(before, 2.0);
    EXPECT_LT(after, 0.8);  // a regular grid's ideal is 0.5 plus the strip restarts
}

TEST(Cluster, ConnectedPatchesSplitDisjointTriangles) {
    uint32_t indices[] = {0, 1, 2, 10, 11, 12, 2, 3, 4, 12, 13, 14, 20, 21, 22};
    uint32_t tris[] = {0, 1, 2, 3, 4};
    std::vector<uint32_t> sizes;
    cb::connected_patches(indices, tris, 5, sizes);
    EXPECT_EQ(sizes, (std::vector<uint32_t>{2, 2, 1}));
    EXPECT_EQ(std::vector<uint32_t>(tris, tris + 5), (std::vector<uint32_t>{0, 2, 1, 3, 4}));
}

TEST(Cluster, NearestCentreStrategiesAgree) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(-1, 1);
    std::vector<float> points(3000 * 6), centres(64 * 6);
    for (float& p : points) p = u(rng);
    for (float& c : centres) c = u(rng);
    std::vector<uint32_t> a(3000, UINT32_MAX), b(3000, UINT32_MAX);
    std::vector<float> da(3000), db(3000);
    EXPECT_EQ(cb::assign_nearest_brute(points.data(), 3000, centres.data(), 64, a.data(), da.data()), 3000u);
    EXPECT_EQ(cb::assign_nearest_flann(points.data(), 3000, centres.data(), 64, b.data(), db.data()), 3000u);
    for (size_t i = 0; i < 3000; ++i) EXPECT_NEAR(da[i], db[i], 1e-5f);  // same distance (ties may differ)
    EXPECT_GE(std::count_if(a.begin(), a.end(), [&, i = size_t(0)](uint32_t x) mutable { return x == b[i++]; }), 2990);
}

// The point-by-point scan the blocked one must match bit for bit: the six terms summed in order, the first
// strictly nearest centre kept.
TEST(Cluster, BlockedNearestCentreScanMatchesThePlainOne) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(-1, 1);
    for (size_t n : {1, 63, 64, 65, 1000}) {
        for (size_t k : {1, 2, 8, 13}) {
            std::vector<float> points(n * 6), centres(k * 6);
            for (float& p : points) p = u(rng);
            for (float& c : centres) c = u(rng);
            if (k > 2) std::copy_n(&centres[0], 6, &centres[(k - 1) * 6]);  // a tie: the lower index wins
            if (n > 3) std::copy_n(&centres[6], 6, &points[3 * 6]);         // a point on a centre
            std::vector<uint32_t> got(n, 7), want(n);
            std::vector<float> got_d(n), want_d(n);
            cb::assign_nearest_brute(points.data(), n, centres.data(), k, got.data(), got_d.data());
            for (size_t i = 0; i < n; ++i) {
                float best = INFINITY;
                uint32_t best_c = 0;
                for (size_t c = 0; c < k; ++c) {
                    float d = 0;
                    for (int j = 0; j < 6; ++j)
                        d += (points[i * 6 + j] - centres[c * 6 + j]) * (points[i * 6 + j] - centres[c * 6 + j]);
                    if (d < best) {
                        best = d;
                        best_c = uint32_t(c);
                    }
                }
                want[i] = best_c;
                want_d[i] = best;
            }
            EXPECT_EQ(got, want) << n << " points, " << k << " centres";
            EXPECT_EQ(got_d, want_d) << n << " points, " << k << " centres";
            // The same points as six coordinate arrays: the same answers.
            std::vector<float> coords(n * 6);
            for (size_t i = 0; i < n; ++i)
                for (size_t j = 0; j < 6; ++j) coords[j * n + i] = points[i * 6 + j];
            std::vector<uint32_t> from_coords(n, 7);
            std::vector<float> from_coords_d(n);
            cb::assign_nearest_coords(coords.data(), n, centres.data(), k, from_coords.data(), from_coords_d.data());
            EXPECT_EQ(from_coords, want) << n << " points, " << k << " centres, coordinate arrays";
            EXPECT_EQ(from_coords_d, want_d) << n << " points, " << k << " centres, coordinate arrays";
        }
    }
}

// k-means++ seeding's pass: the lowered distances are the plain scan's floats, and each block's sum is the
// eight running sums (point i into sum i mod 8) added in a fixed tree, within rounding of a serial sum.
TEST(Cluster, LoweredNearestDistancesAndBlockSumsMatchAPlainScan) {
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> u(-1, 1);
    std::uniform_int_distribution<int> exponent(-30, 30);
    for (size_t n : {1, 7, 63, 64, 65, 1000}) {
        // Each point at its own scale, over 60 binary orders of magnitude: the distances' sums in double round,
        // so their order shows.
        std::vector<float> points(n * 6), coords(n * 6);
        for (size_t i = 0; i < n; ++i) {
            const int e = exponent(rng);
            for (int j = 0; j < 6; ++j) points[i * 6 + j] = std::ldexp(u(rng), e);
        }
        for (size_t i = 0; i < n; ++i)
            for (int j = 0; j < 6; ++j) coords[size_t(j) * n + i] = points[i * 6 + j];
        const size_t blocks = (n + cb::lower_nearest_block - 1) / cb::lower_nearest_block;
        std::vector<float> got(n, INFINITY), want(n, INFINITY);
        std::vector<double> sums(blocks, -1.0);
        for (int round = 0; round < 4; ++round) {
            const float* centre = &points[((round * 37) % n) * 6];  // a centre on a point: its distance is 0
            cb::lower_nearest(coords.data(), n, centre, got.data(), sums.data());
            for (size_t i = 0; i < n; ++i) {
                float d = 0;
                for (int j = 0; j < 6; ++j) d += (points[i * 6 + j] - centre[j]) * (points[i * 6 + j] - centre[j]);
                want[i] = std::min(want[i], d);
            }
            EXPECT_EQ(got, want) << n << " points, round " << round;
            for (size_t b = 0; b < blocks; ++b) {
                double lanes[8] = {}, serial = 0;
                for (size_t i = b * 64; i < std::min(n, b * 64 + 64); ++i) {
                    lanes[(i - b * 64) % 8] += want[i];
                    serial += want[i];
                }
                const double tree =
                    ((lanes[0] + lanes[1]) + (lanes[2] + lanes[3])) + ((lanes[4] + lanes[5]) + (lanes[6] + lanes[7]));
                EXPECT_EQ(sums[b], tree) << n << " points, block " << b;
                EXPECT_NEAR(sums[b], serial, 1e-12 * std::max(1.0, serial)) << n << " points, block " << b;
            }
        }
    }
}

// The sort-based definition of a closed mesh, against which the linear check is compared.
bool closed_by_sorting(const cb::Mesh& m) {
    std::vector<uint64_t> edges;
    for (size_t t = 0; t < m.triangle_count(); ++t)
        for (int k = 0; k < 3; ++k)
            edges.push_back(uint64_t(m.indices[t * 3 + k]) << 32 | m.indices[t * 3 + (k + 1) % 3]);
    if (edges.empty()) return false;
    std::sort(edges.begin(), edges.end());
    for (size_t i = 0; i < edges.size(); ++i) {
        if (i + 1 < edges.size() && edges[i + 1] == edges[i]) return false;
        if (!std::binary_search(edges.begin(), edges.end(), edges[i] << 32 | edges[i] >> 32)) return false;
    }
    return true;
}

TEST(Cluster, ClosedMeshCheck) {
    cb::Mesh cube;  // a unit cube, wound outward
    for (int i = 0; i < 8; ++i)
        cube.positions.insert(cube.positions.end(), {float(i & 1), float(i >> 1 & 1), float(i >> 2)});
    cube.indices = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                    2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
    EXPECT_TRUE(cb::is_closed(cube));
    EXPECT_TRUE(closed_by_sorting(cube));
    std::vector<std::pair<const char*, cb::Mesh>> cases;
    cb::Mesh open = cube;
    open.indices.resize(open.indices.size() - 3);
    cases.push_back({"a face missing", open});
    cb::Mesh flipped = cube;
    std::swap(flipped.indices[1], flipped.indices[2]);
    cases.push_back({"a face flipped", flipped});
    cb::Mesh doubled = cube;
    doubled.indices.insert(doubled.indices.end(), {0, 2, 1, 0, 1, 2});
    cases.push_back({"a face and its reverse added", doubled});
    cb::Mesh loop = cube;
    loop.indices.insert(loop.indices.end(), {0, 0, 2, 0, 2, 0});
    cases.push_back({"loop edges, each once", loop});
    cb::Mesh loop_twice = loop;
    loop_twice.indices.insert(loop_twice.indices.end(), {0, 0, 2, 0, 2, 0});
    cases.push_back({"loop edges twice", loop_twice});
    cases.push_back({"no triangles", cb::Mesh{}});
    for (const auto& [name, mesh] : cases) EXPECT_EQ(cb::is_closed(mesh), closed_by_sorting(mesh)) << name;
    if (!fs::exists(CB_SHARED_DATA)) GTEST_SKIP() << "../shared/data is absent: the shared meshes are not checked";
    for (const char* f : {"scanned/bunny.stl", "scanned/kitten.off", "scanned/horse.ply", "hard/non_manifold_wrap.obj",
                          "hard/tube.obj", "hard/joined_tetrahedra.obj"}) {
        cb::Scene s = cb::load_scene((fs::path(CB_SHARED_DATA) / f).string());
        for (const cb::Mesh& m : s.meshes)
            for (unsigned threads : {1u, 2u, 3u})
                EXPECT_EQ(cb::is_closed(m.indices.data(), m.indices.size(), m.vertex_count(), threads),
                          closed_by_sorting(m))
                    << f << ", " << threads << " threads";
    }
}

// A torus of quads, closed and wound outward: large enough for is_closed to split its vertices over threads.
cb::Mesh torus(uint32_t around, uint32_t across) {
    cb::Mesh m;
    for (uint32_t i = 0; i < around; ++i)
        for (uint32_t j = 0; j < across; ++j) {
            double a = 2 * M_PI * i / around, b = 2 * M_PI * j / across, r = 3 + std::cos(b);
            m.positions.insert(m.positions.end(), {float(r * std::cos(a)), float(r * std::sin(a)), float(std::sin(b))});
        }
    auto at = [&](uint32_t i, uint32_t j) { return (i % around) * across + j % across; };
    for (uint32_t i = 0; i < around; ++i)
        for (uint32_t j = 0; j < across; ++j)
            m.indices.insert(m.indices.end(),
                             {at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    return m;
}

TEST(Cluster, ClosedMeshCheckSplitOverThreads) {
    cb::Mesh closed = torus(120, 90);  // 21,600 triangles
    cb::Mesh flipped = closed, open = closed, extra = closed;
    std::swap(flipped.indices[30001], flipped.indices[30002]);  // one triangle in the middle turned over
    open.indices.erase(open.indices.begin() + 60000, open.indices.begin() + 60003);
    extra.indices.insert(extra.indices.end(), {5000, 5001, 5002});  // its edges used a third time
    for (unsigned threads : {1u, 2u, 3u, 7u}) {
        for (const cb::Mesh* m : {&closed, &flipped, &open, &extra}) {
            EXPECT_EQ(cb::is_closed(m->indices.data(), m->indices.size(), m->vertex_count(), threads),
                      closed_by_sorting(*m))
                << threads << " threads";
            // The entries in a caller's array instead, whatever it held: each range in its own stretch of it.
            std::vector<uint32_t> scratch(m->indices.size(), 0xabababab);
            EXPECT_EQ(cb::is_closed(m->indices.data(), m->indices.size(), m->vertex_count(), threads, scratch.data()),
                      closed_by_sorting(*m))
                << threads << " threads, scratch given";
        }
    }
    EXPECT_TRUE(closed_by_sorting(closed));
}

TEST(Cluster, EveryMeshOfEverySharedFile) {
    if (!fs::exists(CB_SHARED_DATA)) GTEST_SKIP() << "../shared/data is absent";
    size_t files = cb::test::for_each_shared_scene([&](const std::string& path, const cb::Scene& scene) {
        for (cb::ClusterMethod method : all_methods) {
            SCOPED_TRACE(path + " " + cb::method_name(method));
            cb::ClusterOptions o;
            o.method = method;
            for (const cb::Mesh& mesh : scene.meshes) {
                cb::Hierarchy h = cb::build_hierarchy(mesh.positions.data(), mesh.vertex_count(), mesh.indices.data(),
                                                      mesh.triangle_count(), o);
                check_hierarchy(h, mesh.indices.data(), mesh.triangle_count(), o);
                if (HasFatalFailure()) return;
            }
        }
    });
    EXPECT_GE(files, 30u);
}

// Encodes a scene, opens it as the runtime does, and checks the decoded triangles are the original ones
// (same corner coordinates and winding), permuted.
void check_round_trip(const std::string& path) {
    SCOPED_TRACE(path);
    cb::Scene scene = cb::load_scene(path);
    cb::ClusterOptions o;
    cb::BakeStats stats;
    std::vector<cb::AssetMesh> meshes = cb::cluster_scene(scene, o, stats);
    std::vector<uint8_t> bytes = cb::encode_asset(meshes, scene.instances);
    std::vector<uint64_t> aligned((bytes.size() + 7) / 8);
    std::memcpy(aligned.data(), bytes.data(), bytes.size());
    cb::AssetView view;
    ASSERT_EQ(cb::open_asset(aligned.data(), bytes.size(), &view), cb::AssetError::ok);
    EXPECT_EQ(view.mesh_count, scene.meshes.size());
    EXPECT_EQ(view.instance_count, scene.instances.size());
    EXPECT_EQ(view.triangle_count, stats.triangles);
    EXPECT_EQ(view.fine_count, stats.fine_clusters);
    // The clustered triangles are the original ones (same corner positions, same winding), permuted.
    for (uint32_t m = 0; m < view.mesh_count; ++m) {
        const cb::MeshRecord& r = view.meshes[m];
        std::vector<std::array<float, 9>> a, b;
        for (uint32_t f = 0; f < r.fine_count; ++f) {
            const cb::FineCluster& c = view.fine[r.first_fine + f];
            for (uint32_t t = c.first_triangle; t < c.first_triangle + c.triangle_count; ++t) {
                uint32_t id[3];
                view.triangle(r, f, t, id);
                std::array<float, 9> x;
                for (int k = 0; k < 9; ++k) x[k] = view.position(r, id[k / 3])[k % 3];
                a.push_back(x);
            }
        }
        const cb::Mesh& mesh = scene.meshes[m];
        for (size_t t = 0; t < mesh.triangle_count(); ++t) {
            std::array<float, 9> y;
            for (int k = 0; k < 9; ++k) y[k] = mesh.positions[size_t(mesh.indices[t * 3 + k / 3]) * 3 + k % 3];
            b.push_back(y);
        }
        std::sort(a.begin(), a.end());
        std::sort(b.begin(), b.end());
        EXPECT_EQ(a, b);
    }
    // Any single flipped byte is caught (checksum or structure), and every truncation.
    for (size_t at : {size_t(3), size_t(70), bytes.size() / 2, bytes.size() - 1}) {
        std::vector<uint64_t> bad = aligned;
        reinterpret_cast<uint8_t*>(bad.data())[at] ^= 0x40;
        EXPECT_NE(cb::open_asset(bad.data(), bytes.size(), &view), cb::AssetError::ok) << at;
    }
    for (size_t cut : {size_t(0), size_t(63), size_t(64), bytes.size() - 16})
        EXPECT_NE(cb::open_asset(aligned.data(), cut, &view), cb::AssetError::ok) << cut;
}

TEST(Cluster, AssetRoundTripsThroughTheRuntimeView) {
    check_round_trip(std::string(CB_SOURCE_DIR) + "/data/default_scene.glb");
    // Over 65,535 vertices: some reused vertices lie too far back for a 16-bit reference and are stored again.
    if (fs::exists(CB_SHARED_DATA))
        check_round_trip(std::string(CB_SHARED_DATA) + "/scanned/dragon_vrip_res2_binary.ply");
}

// The bytes of a section of an encoded asset, and a way to re-seal the checksum after editing them.
struct Sections {
    std::vector<uint64_t> storage;
    size_t size;
    uint8_t* bytes() { return reinterpret_cast<uint8_t*>(storage.data()); }
    cb::SectionEntry* entry(cb::SectionType type) {
        cb::AssetHeader h;
        std::memcpy(&h, bytes(), sizeof h);
        for (uint32_t i = 0; i < h.section_count; ++i) {
            auto* e =
                reinterpret_cast<cb::SectionEntry*>(bytes() + sizeof(cb::AssetHeader) + i * sizeof(cb::SectionEntry));
            if (e->type == uint32_t(type)) return e;
        }
        return nullptr;
    }
    template <class T>
    T* data(cb::SectionType type) {
        return reinterpret_cast<T*>(bytes() + entry(type)->offset);
    }
    cb::AssetError open() {
        uint64_t sum = cb::asset_checksum(bytes(), size);
        std::memcpy(bytes() + offsetof(cb::AssetHeader, checksum), &sum, 8);
        cb::AssetView view;
        return cb::open_asset(storage.data(), size, &view);
    }
};

TEST(Cluster, AssetReaderRefusesMalformedClustersAndPackedBounds) {
    cb::test::Baked good = cb::test::bake(std::string(CB_SOURCE_DIR) + "/data/default_scene.glb");
    ASSERT_GT(good.view.mesh_count, 0u);
    size_t size = 0;
    {
        cb::AssetHeader h;
        std::memcpy(&h, good.data(), sizeof h);
        size = h.file_size;
    }
    auto fresh = [&] {
        Sections s{std::vector<uint64_t>((size + 7) / 8), size};
        std::memcpy(s.bytes(), good.data(), size);
        return s;
    };
    using T = cb::SectionType;
    ASSERT_EQ(fresh().open(), cb::AssetError::ok);
    Sections s = fresh();
    s.data<uint16_t>(T::vertex_refs)[0] = 0;  // a reference to the cluster's own first vertex
    EXPECT_EQ(s.open(), cb::AssetError::bad_cluster_range);
    s = fresh();
    s.data<uint16_t>(T::vertex_refs)[0] = 65535;  // before the mesh's first vertex
    EXPECT_EQ(s.open(), cb::AssetError::bad_cluster_range);
    s = fresh();
    s.data<uint8_t>(T::triangles)[5] = 200;  // past the first cluster's vertex list
    EXPECT_EQ(s.open(), cb::AssetError::bad_cluster_range);
    s = fresh();
    s.data<cb::FineCluster>(T::fine_clusters)[1].first_vertex += 1;  // vertex ranges no longer tile
    EXPECT_EQ(s.open(), cb::AssetError::bad_cluster_range);
    s = fresh();
    s.data<cb::PackedObb>(T::fine_obbs)[0].largest = 4;
    EXPECT_EQ(s.open(), cb::AssetError::bad_packed_bounds);
    s = fresh();
    s.data<cb::PackedObb>(T::fine_obbs)[0].half[1] = -0.5f;
    EXPECT_EQ(s.open(), cb::AssetError::bad_packed_bounds);
    s = fresh();
    s.data<cb::PackedCone>(T::fine_cones)[0].cos_half_angle = 1.5f;
    EXPECT_EQ(s.open(), cb::AssetError::bad_packed_bounds);
    s = fresh();
    s.entry(T::fine_obbs)->type = 999;  // cones without the boxes they are stored relative to
    EXPECT_EQ(s.open(), cb::AssetError::bad_packed_bounds);
}

TEST(Cluster, CityModelAtHugeCoordinates) {
    // The 3dfier terrain sits at x ~ 85,000, y ~ 447,000 with a 524 m extent: Morton chunks and k-means
    // clusters must stay local, not collapse because of the large offset.
    fs::path file = fs::path(CB_SHARED_DATA) / "hard/3dfier_testarea/testarea.obj";
    if (!fs::exists(file)) GTEST_SKIP() << "../shared/data is absent";
    cb::Scene scene = cb::load_scene(file.string());
    const cb::Mesh& m = scene.meshes[0];
    cb::ClusterOptions o;
    cb::Hierarchy h =
        cb::build_hierarchy(m.positions.data(), m.vertex_count(), m.indices.data(), m.triangle_count(), o);
    check_hierarchy(h, m.indices.data(), m.triangle_count(), o);
    double mean_extent =
        mean_xy_extent(m.positions.data(), m.indices.data(), h, [](double w, double h) { return std::max(w, h); });
    EXPECT_LT(mean_extent, 40.0) << "fine clusters of a 524 m terrain should span metres, not the whole site";
}

// cluster_scene_releasing clusters as cluster_scene does and gives the scene's storage back as it goes: each
// mesh's positions move into its clustered mesh, and its indices and primitives are freed, not only emptied.
TEST(Cluster, ReleasingClusteringFreesTheScenesArrays) {
    cb::Scene scene = cb::load_scene(std::string(CB_SOURCE_DIR) + "/data/default_scene.glb");
    cb::ClusterOptions o;
    cb::BakeStats stats;
    const std::vector<cb::AssetMesh> kept = cb::cluster_scene(scene, o, stats);
    const std::vector<cb::AssetMesh> released = cb::cluster_scene_releasing(scene, o, stats, {}, 2);
    ASSERT_EQ(released.size(), kept.size());
    for (size_t m = 0; m < kept.size(); ++m) {
        EXPECT_EQ(released[m].positions, kept[m].positions);
        EXPECT_EQ(released[m].triangles, kept[m].triangles);
        EXPECT_EQ(released[m].fine.size(), kept[m].fine.size());
        const cb::Mesh& mesh = scene.meshes[m];
        EXPECT_EQ(mesh.positions.capacity() + mesh.indices.capacity() + mesh.primitives.capacity(), 0u) << m;
    }
}

// Bounds fitting reports its progress by cluster triangles, a block of clusters at a time, from one thread
// at a time, rising to the total (every fine and coarse cluster's triangles), and fits the same volumes as
// without a report.
TEST(Cluster, BoundsFittingReportsItsProgress) {
    cb::Scene scene = cb::load_scene(std::string(CB_SOURCE_DIR) + "/data/default_scene.glb");
    cb::ClusterOptions o;
    cb::BakeStats stats;
    const std::vector<cb::AssetMesh> clustered = cb::cluster_scene(scene, o, stats);
    size_t expected = 0, clusters = 0;
    for (const cb::AssetMesh& m : clustered) {
        expected += 2 * m.triangles.size() / 3;
        clusters += m.fine.size() + m.coarse.size();
    }  // fine and coarse
    for (unsigned threads : {1u, 2u, 4u}) {
        SCOPED_TRACE(threads);
        std::vector<cb::AssetMesh> reported = clustered, silent = clustered;
        std::vector<std::pair<size_t, size_t>> calls;
        std::atomic<int> inside{0};
        bool overlapped = false;
        cb::BoundsOptions b;
        cb::fit_scene_bounds(reported, b, threads, stats, [&](size_t done, size_t total) {
            overlapped |= inside.fetch_add(1) != 0;
            calls.emplace_back(done, total);
            inside.fetch_sub(1);
        });
        cb::fit_scene_bounds(silent, b, threads, stats);
        EXPECT_FALSE(overlapped);
        ASSERT_FALSE(calls.empty());
        for (const auto& c : calls) EXPECT_EQ(c.second, expected);
        EXPECT_TRUE(std::is_sorted(calls.begin(), calls.end()));
        EXPECT_EQ(calls.back().first, expected);
        if (threads == 1) {
            EXPECT_GT(clusters, 1000u);
            EXPECT_GE(calls.size(), clusters / 64);  // one a block of clusters
        }
        EXPECT_EQ(cb::encode_asset(reported, scene.instances), cb::encode_asset(silent, scene.instances));
    }
}
