// Clustering benchmark: speed, memory, cache efficiency and compactness of each method, against
// meshoptimizer's meshlets and vertex cache optimiser on the same input in the same run.
//
//   bench_cluster [--data DIR] [--fine 16] [--runs 5] [--copies 25] [--only NAME]
//
// Prints tables; asserts nothing. Times are medians of --runs runs (3 for the big scene).
#include <meshoptimizer.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "bench_common.h"
#include "cluster.h"
#include "load.h"

namespace fs = std::filesystem;

namespace {

struct Input {
    std::string name;
    std::vector<float> positions;
    std::vector<uint32_t> indices;
    size_t vertices() const { return positions.size() / 3; }
    size_t triangles() const { return indices.size() / 3; }
};

// Peak resident memory above the level at the start of a measurement (Linux: clear_refs resets VmHWM).
struct PeakMemory {
    long baseline_kb = 0;
    static long read_kb(const char* key) {
        std::ifstream in("/proc/self/status");
        std::string k;
        long v = -1;
        while (in >> k) {
            if (k == key) {
                in >> v;
                return v;
            }
        }
        return -1;
    }
    void reset() {
        std::ofstream("/proc/self/clear_refs") << "5";
        baseline_kb = read_kb("VmRSS:");
    }
    double extra_mb() const {
        long peak = read_kb("VmHWM:");
        return peak < 0 || baseline_kb < 0 ? NAN : double(peak - baseline_kb) / 1024.0;
    }
};

using cb::bench::median_seconds;

struct Compactness {
    double mean_radius = 0, max_radius = 0, mean_triangles = 0;  // radius: AABB half-diagonal / mesh diagonal
    size_t clusters = 0;
};

// `cluster_of_position` lists triangles cluster by cluster; `sizes` gives each cluster's count.
Compactness compactness(const Input& in, const uint32_t* tris, const std::vector<uint32_t>& sizes) {
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < in.positions.size(); ++i) {
        lo[i % 3] = std::min(lo[i % 3], in.positions[i]);
        hi[i % 3] = std::max(hi[i % 3], in.positions[i]);
    }
    double diagonal = std::sqrt(double(hi[0] - lo[0]) * (hi[0] - lo[0]) + double(hi[1] - lo[1]) * (hi[1] - lo[1]) +
                                double(hi[2] - lo[2]) * (hi[2] - lo[2]));
    Compactness c;
    size_t at = 0;
    for (uint32_t n : sizes) {
        float a[3] = {INFINITY, INFINITY, INFINITY}, b[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (size_t i = at; i < at + n; ++i)
            for (int k = 0; k < 3; ++k) {
                const float* p = &in.positions[size_t(in.indices[size_t(tris[i]) * 3 + k]) * 3];
                for (int d = 0; d < 3; ++d) {
                    a[d] = std::min(a[d], p[d]);
                    b[d] = std::max(b[d], p[d]);
                }
            }
        double r = 0.5 *
            std::sqrt(double(b[0] - a[0]) * (b[0] - a[0]) + double(b[1] - a[1]) * (b[1] - a[1]) +
                      double(b[2] - a[2]) * (b[2] - a[2])) /
            diagonal;
        c.mean_radius += r;
        c.max_radius = std::max(c.max_radius, r);
        at += n;
    }
    c.clusters = sizes.size();
    c.mean_radius /= double(std::max<size_t>(1, sizes.size()));
    c.mean_triangles = double(at) / double(std::max<size_t>(1, sizes.size()));
    return c;
}

std::vector<uint32_t> permuted(const Input& in, const std::vector<uint32_t>& order) {
    std::vector<uint32_t> out(order.size() * 3);
    for (size_t i = 0; i < order.size(); ++i)
        for (int k = 0; k < 3; ++k) out[i * 3 + k] = in.indices[size_t(order[i]) * 3 + k];
    return out;
}

Input load_input(const fs::path& path) {
    cb::Scene s = cb::load_scene(path.string());
    Input in;
    in.name = path.filename().string();
    in.positions = s.meshes[0].positions;
    in.indices = s.meshes[0].indices;
    return in;
}

Input big_scene(const Input& base, int copies) {
    cb::Mesh m;
    m.name = base.name;
    m.positions = base.positions;
    m.indices = base.indices;
    cb::Mesh merged = cb::bench::merged_copies(m, copies);
    return {std::to_string(copies) + "x " + base.name, std::move(merged.positions), std::move(merged.indices)};
}

struct Row {
    std::string method;
    double seconds_1 = 0, seconds_n = 0, extra_mb = 0, acmr = 0;
    Compactness c;
};

void print_row(const Input& in, const Row& r, unsigned threads) {
    double t = double(in.triangles());
    std::printf("| %-26s | %-25s | %8.2f | %8.2f | %7.1f | %6.3f | %7.0f | %6.2f | %7.4f | %7.4f |\n", in.name.c_str(),
                r.method.c_str(), t / r.seconds_1 / 1e6, r.seconds_n > 0 ? t / r.seconds_n / 1e6 : NAN, r.extra_mb,
                r.acmr, double(r.c.clusters), r.c.mean_triangles, r.c.mean_radius, r.c.max_radius);
    (void)threads;
}

void run(const Input& in, uint32_t fine, int runs) {
    unsigned hw = std::max(1u, std::thread::hardware_concurrency());
    PeakMemory mem;
    std::vector<Row> rows;
    for (cb::ClusterMethod method : {cb::ClusterMethod::kmeans, cb::ClusterMethod::vco, cb::ClusterMethod::morton}) {
        cb::ClusterOptions o;
        o.method = method;
        o.fine_size = fine;
        cb::Hierarchy h;
        Row r;
        r.method = std::string("clusterbake ") + cb::method_name(method);
        mem.reset();
        r.seconds_1 = median_seconds(runs, [&] {
            h = cb::build_hierarchy(in.positions.data(), in.vertices(), in.indices.data(), in.triangles(), o, nullptr,
                                    {}, 1);
        });
        r.extra_mb = mem.extra_mb();
        r.seconds_n = median_seconds(runs, [&] {
            h = cb::build_hierarchy(in.positions.data(), in.vertices(), in.indices.data(), in.triangles(), o, nullptr,
                                    {}, hw);
        });
        r.acmr = cb::fifo_acmr(h.corners.data(), in.triangles(), in.vertices(), 32);
        std::vector<uint32_t> sizes;
        for (size_t f = 0; f < h.fine_count(); ++f) sizes.push_back(h.fine_offsets[f + 1] - h.fine_offsets[f]);
        r.c = compactness(in, h.order.data(), sizes);
        rows.push_back(r);
    }
    // meshoptimizer's meshlets on the input order, at most `limit` triangles and 3 * limit vertices: once at
    // our maximum size, once at the k-means mean size rounded to a multiple of 4 (meshoptimizer's rule), so
    // compactness is also compared at equal cluster counts.
    uint32_t kmeans_mean = uint32_t(std::lround(rows[0].c.mean_triangles / 4.0)) * 4;
    for (uint32_t limit : {fine, std::max(4u, kmeans_mean)}) {
        size_t max_v = std::min<size_t>(255, size_t(limit) * 3);
        size_t bound = meshopt_buildMeshletsBound(in.indices.size(), max_v, limit);
        std::vector<meshopt_Meshlet> meshlets(bound);
        std::vector<unsigned> mv(bound * max_v);
        std::vector<unsigned char> mt(bound * limit * 3);
        size_t count = 0;
        Row r;
        r.method = "meshopt_buildMeshlets " + std::to_string(limit);
        mem.reset();
        r.seconds_1 = median_seconds(runs, [&] {
            count = meshopt_buildMeshlets(meshlets.data(), mv.data(), mt.data(), in.indices.data(), in.indices.size(),
                                          in.positions.data(), in.vertices(), 12, max_v, limit, 0.0f);
        });
        r.extra_mb = mem.extra_mb();
        r.seconds_n = 0;  // single-threaded API
        // Map meshlet-local triangles back to triangles of the input by their vertex triples.
        Input local = in;
        local.indices.clear();
        std::vector<uint32_t> tris, sizes;
        for (size_t m = 0; m < count; ++m) {
            const meshopt_Meshlet& ml = meshlets[m];
            for (size_t t = 0; t < ml.triangle_count; ++t) {
                for (int k = 0; k < 3; ++k)
                    local.indices.push_back(mv[ml.vertex_offset + mt[ml.triangle_offset + t * 3 + k]]);
                tris.push_back(uint32_t(tris.size()));
            }
            sizes.push_back(ml.triangle_count);
        }
        r.acmr = cb::fifo_acmr(local.indices.data(), local.indices.size() / 3, in.vertices(), 32);
        r.c = compactness(local, tris.data(), sizes);
        rows.push_back(r);
    }
    for (const Row& r : rows) print_row(in, r, hw);

    // Vertex cache order alone, whole mesh: our Forsyth against meshopt_optimizeVertexCache.
    std::vector<uint32_t> ours, theirs(in.indices.size());
    double t_ours =
        median_seconds(runs, [&] { ours = cb::forsyth_order(in.indices.data(), in.triangles(), in.vertices(), 32); });
    double t_meshopt = median_seconds(
        runs, [&] { meshopt_optimizeVertexCache(theirs.data(), in.indices.data(), in.indices.size(), in.vertices()); });
    std::vector<uint32_t> ours_idx = permuted(in, ours);
    double acmr_in = cb::fifo_acmr(in.indices.data(), in.triangles(), in.vertices(), 32);
    double acmr_ours = cb::fifo_acmr(ours_idx.data(), in.triangles(), in.vertices(), 32);
    double acmr_theirs = cb::fifo_acmr(theirs.data(), in.triangles(), in.vertices(), 32);
    std::printf(
        "|   vertex cache, %-20s | input ACMR %.3f | ours %.3f in %.1f ms | meshopt %.3f in %.1f ms | time "
        "ours/meshopt %.2f |\n",
        in.name.c_str(), acmr_in, acmr_ours, t_ours * 1e3, acmr_theirs, t_meshopt * 1e3, t_ours / t_meshopt);
}

}  // namespace

static int run(int argc, char** argv) {
    cb::bench::Options o = cb::bench::parse_options(argc, argv, {});
    std::vector<fs::path> files = cb::bench::scanned_meshes(o, "bench_cluster");
    if (files.empty()) return 1;
    std::printf(
        "fine size %u, %d runs (median), %u hardware threads; M tri/s = million triangles per second; "
        "radius = cluster AABB half-diagonal / mesh diagonal; ACMR = FIFO 32 misses per triangle\n\n",
        o.fine, o.runs, std::max(1u, std::thread::hardware_concurrency()));
    std::printf(
        "| input | method | M tri/s 1 thread | M tri/s all | extra MB | ACMR | clusters | tri/cluster | mean radius | "
        "max radius |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
    Input dragon;
    for (const fs::path& f : files) {
        Input in = load_input(f);
        if (f.filename() == "dragon_vrip_res2_binary.ply") dragon = in;
        run(in, o.fine, o.runs);
    }
    if (o.copies > 0) {
        if (dragon.indices.empty()) dragon = load_input(o.data / "scanned/dragon_vrip_res2_binary.ply");
        run(big_scene(dragon, o.copies), o.fine, std::min(o.runs, 3));
    }
    return 0;
}

int main(int argc, char** argv) {
    return cb::bench::guarded_main("bench_cluster", [&] { return run(argc, argv); });
}
