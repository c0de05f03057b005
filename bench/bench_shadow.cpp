// Shadow query benchmark: clusterbake's per-light shadow volume trees against Embree 3 on the same points.
// The points are what a camera sees: the first hits of a W x W view (found with Embree), then each point's
// segment to the light. Prints build time, queries per second on 1 and 2 threads, traversal counts, memory,
// and how often the two disagree (Embree is not exact: grazing contacts, and its near bound differs from
// our self-shadowing policy). Times are medians of --runs rounds; each round builds our trees, then runs our
// passes and Embree's one after the other, so noise hits both alike. Both sides' passes run on the same two
// worker threads, kept for the whole run, with the same chunking. Asserts nothing.
//
//   bench_shadow [--data DIR] [--view 1024] [--copies 25] [--runs 3] [--only NAME] [--one-sided 1] [--traversal T]
//                [--frames N]
//   (NAME "big": only the big scene; --one-sided 1: our trees in one-sided mode, whose answers equal
//   two-sided ones outside closed meshes; Embree stays two-sided; T: scan (default), top-two, top-one, mtsv-one or
//   mtsv-two, how our trees reach the fine clusters, cb::Traversal, or compare: every traversal and the metric
//   trees' settings on the same points, one thread, beside Embree; --frames N: no Embree passes, only N of
//   our frames per light on one thread, their shortest and median time; and the queries of each frame
//   again through cb::query_scene, the tools' query library and its run-time choice of lanes: the ratio of
//   their medians is what that dispatch costs against the runtime compiled for this machine. On a noisy
//   machine the shortest of many is the steadier figure for comparing two builds of the runtime, run
//   alternately)
#include <embree3/rtcore.h>

#include <cb_instance_shadow.h>
#include <cb_shadow.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "asset_file.h"
#include "bench_embree.h"
#include "bake.h"
#include "bench_common.h"
#include "load.h"
#include "scene_query.h"
#include "timing.h"

namespace fs = std::filesystem;

namespace {

// Worker threads kept for the whole run, as an engine's job system would keep them: each pass hands them a
// job and waits. Threads started for each pass would add their start-up, the same for both sides, to a
// short pass (docs/PERFORMANCE.md).
class Workers {
public:
    explicit Workers(unsigned count) {
        for (unsigned w = 0; w < count; ++w) threads_.emplace_back([this, w] { serve(w); });
    }
    ~Workers() {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            stop_ = true;
        }
        wake_.notify_all();
        for (std::thread& t : threads_) t.join();
    }
    // job(w) on workers 0 .. count - 1; returns when all have finished.
    void run(unsigned count, const std::function<void(unsigned)>& job) {
        std::unique_lock<std::mutex> lock(mutex_);
        job_ = &job;
        count_ = count;
        busy_ = count;
        ++generation_;
        wake_.notify_all();
        done_.wait(lock, [this] { return busy_ == 0; });
    }

private:
    void serve(unsigned w) {
        unsigned long seen = 0;
        for (;;) {
            std::unique_lock<std::mutex> lock(mutex_);
            wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
            if (stop_) return;
            seen = generation_;
            if (w >= count_) continue;
            const std::function<void(unsigned)>* job = job_;
            lock.unlock();
            (*job)(w);
            lock.lock();
            if (--busy_ == 0) done_.notify_one();
        }
    }
    std::vector<std::thread> threads_;
    std::mutex mutex_;
    std::condition_variable wake_, done_;
    const std::function<void(unsigned)>* job_ = nullptr;
    unsigned count_ = 0, busy_ = 0;
    unsigned long generation_ = 0;
    bool stop_ = false;
};

struct Input {
    std::string name;
    cb::Scene scene;
};

// World-space triangle soup of the scene, for Embree.
void flatten(const cb::Scene& s, std::vector<float>& v, std::vector<unsigned>& t) {
    for (const cb::Instance& inst : s.instances) {
        const cb::Mesh& m = s.meshes[inst.mesh];
        unsigned base = unsigned(v.size() / 3);
        for (size_t k = 0; k < m.vertex_count(); ++k) {
            auto w =
                cb::transform_point(inst.world, m.positions[k * 3], m.positions[k * 3 + 1], m.positions[k * 3 + 2]);
            v.insert(v.end(), {float(w[0]), float(w[1]), float(w[2])});
        }
        for (uint32_t i : m.indices) t.push_back(base + i);
    }
}

// One row of the comparison (--traversal compare): a traversal and its settings, on the asset with boxes
// and cones only (what bake writes by default) or with the fitted spheres, capsules and slabs too.
struct Config {
    const char* name;
    cb::Traversal traversal;
    cb::MetricBuild build;
    double capsule_aspect;
    bool fitted;  // the asset baked with --bounds all
};

const Config configs[] = {
    {"scan", cb::Traversal::scan, cb::MetricBuild::heuristic, 2, false},
    {"CPSV two levels (top-two)", cb::Traversal::top_two, cb::MetricBuild::heuristic, 2, false},
    {"CPSV one level (top-one)", cb::Traversal::top_one, cb::MetricBuild::heuristic, 2, false},
    {"MTSV heuristic", cb::Traversal::mtsv_one, cb::MetricBuild::heuristic, 4, true},
    {"MTSV reference build", cb::Traversal::mtsv_one, cb::MetricBuild::reference, 4, true},
    {"MTSV about the boxes", cb::Traversal::mtsv_one, cb::MetricBuild::heuristic, 4, false},
    {"MTSV two levels", cb::Traversal::mtsv_two, cb::MetricBuild::heuristic, 4, true},
    {"MTSV capsules from 1.25", cb::Traversal::mtsv_one, cb::MetricBuild::heuristic, 1.25, true},
    {"MTSV capsules from 2", cb::Traversal::mtsv_one, cb::MetricBuild::heuristic, 2, true},
    {"MTSV spheres only", cb::Traversal::mtsv_one, cb::MetricBuild::heuristic, INFINITY, true},
};

// Every configuration against one light on one thread, the same points, rounds alternating between them
// (medians), beside Embree's occluded1 on one thread (its build is once per scene, not counted).
void compare_light(const cb::AssetView& boxes, const cb::AssetView& fitted, const std::vector<cb::ScanBounds>& scan,
                   const std::vector<double>& pts, const double* light, const char* light_name,
                   const std::string& scene, int runs, bool one_sided, double bias,
                   const std::function<double()>& embree_pass) {
    const size_t n = pts.size() / 3, count = std::size(configs);
    std::vector<uint32_t> order(n), order_scratch(cb::batch_order_scratch_size(n));
    std::vector<std::vector<double>> build(count), query(count);
    std::vector<double> embree;
    std::vector<cb::QueryStats> stats(count);
    std::vector<size_t> bytes(count), nodes(count), capsules(count), shadowed(count), differ(count);
    std::vector<uint8_t> first, answers(n);
    for (int r = 0; r < std::max(1, runs); ++r) {
        for (size_t c = 0; c < count; ++c) {
            const Config& config = configs[c];
            const cb::AssetView& view = config.fitted ? fitted : boxes;
            std::vector<cb::InstanceShadow> trees(view.instance_count);
            cb::ShadowBuildOptions options;
            options.traversal = config.traversal;
            options.one_sided = one_sided;
            options.bounds = config.fitted ? nullptr : scan.data();
            options.capsule_aspect = config.capsule_aspect;
            options.metric_build = config.build;
            options.bias = bias;
            auto b0 = std::chrono::steady_clock::now();
            for (uint32_t i = 0; i < view.instance_count; ++i) trees[i].build(view, i, light, options);
            build[c].push_back(cb::seconds_since(b0));
            std::vector<uint32_t> scratch(cb::ordered_scratch_size(trees.data(), trees.size()));
            cb::QueryStats st;
            auto q0 = std::chrono::steady_clock::now();
            cb::batch_order(light, pts.data(), n, order.data(), order_scratch.data());
            cb::occluded_ordered(trees.data(), trees.size(), pts.data(), order.data(), n, answers.data(),
                                 scratch.data(), &st);
            query[c].push_back(cb::seconds_since(q0));
            stats[c] = st;
            bytes[c] = nodes[c] = capsules[c] = 0;
            for (const cb::InstanceShadow& t : trees) {
                bytes[c] += t.memory_bytes();
                nodes[c] += t.node_count();
                capsules[c] += t.capsules();
            }
            shadowed[c] = size_t(std::count(answers.begin(), answers.end(), uint8_t(1)));
            if (c == 0) first = answers;
            differ[c] = 0;
            for (size_t i = 0; i < n; ++i) differ[c] += answers[i] != first[i];
        }
        embree.push_back(embree_pass());
    }
    const double e = cb::median(embree), cpsv = cb::median(build[2]) + cb::median(query[2]);
    for (size_t c = 0; c < count; ++c) {
        const double b = cb::median(build[c]), q = cb::median(query[c]), dn = double(n);
        std::printf(
            "| %s | %s | %s | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %.1f | %.2f | %.2f | %.1f | %zu | %zu | %zu "
            "|\n",
            scene.c_str(), light_name, configs[c].name, b * 1e3, q * 1e3, (b + q) * 1e3, (b + q) / cpsv, (b + q) / e,
            dn / q / 1e6, double(stats[c].nodes_visited) / dn, double(stats[c].clusters_tested) / dn,
            double(stats[c].clusters_tested - shadowed[c]) / dn, double(bytes[c]) / 1024.0, nodes[c], capsules[c],
            differ[c]);
    }
    std::printf("| %s | %s | Embree occluded1 | (once: not counted) | %.2f | %.2f | | 1.00 | %.2f | | | | | | | |\n",
                scene.c_str(), light_name, e * 1e3, e * 1e3, double(n) / e / 1e6);
    std::fflush(stdout);
}

void run(const Input& in, int view, int runs, bool one_sided, cb::Traversal level, int frames, bool comparing) {
    Workers workers(2);
    // Bake with the default options and open the asset as the runtime would.
    cb::BakeStats bs;
    std::vector<cb::AssetMesh> meshes = cb::cluster_scene(in.scene, {}, bs);
    cb::BoundsOptions bo;
    bo.mask = cb::bounds_auto;
    cb::fit_scene_bounds(meshes, bo, 0, bs);
    std::vector<uint8_t> bytes = cb::encode_asset(meshes, in.scene.instances);
    cb::LoadedAsset loaded;
    if (cb::open_asset_copy(bytes, loaded) != cb::AssetError::ok) return;
    const cb::AssetView& asset = loaded.view;
    const double bias = cb::default_shadow_bias(cb::asset_world_size(asset));  // the runtime's default, once
    cb::LoadedAsset fitted;  // --traversal compare: the same clusters with spheres, capsules and slabs too
    if (comparing) {
        bo.mask = cb::bounds_all;
        bo.capsule_ratio = 1;  // a capsule for every cluster: the query's --capsule-aspect chooses
        cb::fit_scene_bounds(meshes, bo, 0, bs);
        if (cb::open_asset_copy(cb::encode_asset(meshes, in.scene.instances), fitted) != cb::AssetError::ok) return;
    }
    // The scan's bounds (decoded boxes and bounding spheres): light-independent, made once, like Embree's BVH.
    auto s0 = std::chrono::steady_clock::now();
    const std::vector<cb::ScanBounds> scan_bounds = cb::make_scan_bounds(asset);
    const double scan_bounds_time = cb::seconds_since(s0);
    size_t scan_bounds_bytes = 0;
    for (const cb::ScanBounds& s : scan_bounds) scan_bounds_bytes += s.memory_bytes();

    std::vector<float> v;
    std::vector<unsigned> t;
    flatten(in.scene, v, t);
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < v.size(); ++i) {
        lo[i % 3] = std::min(lo[i % 3], v[i]);
        hi[i % 3] = std::max(hi[i % 3], v[i]);
    }
    double size = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
    double centre[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};

    cb::bench::embree_bytes = 0;
    cb::bench::embree_peak = 0;
    RTCDevice device = rtcNewDevice("threads=2");
    rtcSetDeviceMemoryMonitorFunction(device, cb::bench::embree_monitor, nullptr);
    auto t0 = std::chrono::steady_clock::now();
    RTCScene scene = rtcNewScene(device);
    RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    std::memcpy(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, v.size() / 3), v.data(),
                v.size() * 4);
    std::memcpy(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, t.size() / 3), t.data(),
                t.size() * 4);
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(scene);
    double embree_build = cb::seconds_since(t0);

    // Camera: looking at the centre from a diagonal; the points are the first hits.
    double eye[3] = {centre[0] + 1.2 * size, centre[1] + 0.8 * size, centre[2] + 1.5 * size};
    double fw[3], right[3], up[3] = {0, 1, 0}, len = 0;
    for (int k = 0; k < 3; ++k) {
        fw[k] = centre[k] - eye[k];
        len += fw[k] * fw[k];
    }
    for (double& x : fw) x /= std::sqrt(len);
    right[0] = fw[1] * up[2] - fw[2] * up[1];
    right[1] = fw[2] * up[0] - fw[0] * up[2];
    right[2] = fw[0] * up[1] - fw[1] * up[0];
    len = std::sqrt(right[0] * right[0] + right[1] * right[1] + right[2] * right[2]);
    for (double& x : right) x /= len;
    up[0] = right[1] * fw[2] - right[2] * fw[1];
    up[1] = right[2] * fw[0] - right[0] * fw[2];
    up[2] = right[0] * fw[1] - right[1] * fw[0];
    const std::vector<double> pts = cb::bench::first_hits(scene, eye, fw, right, up, view, 0.5);
    size_t n = pts.size() / 3;

    // Lights: outside the bounds; inside them; grazing the top of the bounds (a thousandth of the size above
    // it, so the segments run along the upper surfaces); and exactly on the plane of the middle triangle
    // (b + c - a is exact in double for float corners), off the triangle.
    const float* tri[3] = {&v[size_t(t[t.size() / 6 * 3]) * 3], &v[size_t(t[t.size() / 6 * 3 + 1]) * 3],
                           &v[size_t(t[t.size() / 6 * 3 + 2]) * 3]};
    const double lights[4][3] = {{centre[0] - 0.8 * size, centre[1] + 1.5 * size, centre[2] + 0.3 * size},
                                 {centre[0] + 0.1 * size, centre[1] + 0.05 * size, centre[2] - 0.1 * size},
                                 {centre[0] + 0.2 * size, hi[1] + 1e-3 * size, centre[2] - 0.1 * size},
                                 {double(tri[1][0]) + tri[2][0] - tri[0][0], double(tri[1][1]) + tri[2][1] - tri[0][1],
                                  double(tri[1][2]) + tri[2][2] - tri[0][2]}};
    const char* light_names[4] = {"outside", "inside", "grazing", "on a plane"};
    for (int li = 0; li < 4; ++li) {
        const double* light = lights[li];
        // Ours: build the trees (one per instance), then query, on 1 and 2 threads.
        std::vector<cb::InstanceShadow> trees(asset.instance_count);
        std::vector<cb::BuildScratch> build_scratch(asset.instance_count);  // kept between builds
        size_t always = 0;
        // Instances are shared between the threads (the runtime builds each on the thread that asks).
        auto build_trees = [&](unsigned threads) {
            auto b0 = std::chrono::steady_clock::now();
            auto build_some = [&](unsigned th) {
                cb::ShadowBuildOptions options;
                options.traversal = level;
                options.one_sided = one_sided;
                options.bounds = scan_bounds.data();
                options.bias = bias;
                for (uint32_t i = th; i < asset.instance_count; i += threads) {
                    options.scratch = &build_scratch[i];
                    trees[i].build(asset, i, light, options);
                }
            };
            std::vector<std::thread> helpers;
            for (unsigned th = 1; th < std::min<unsigned>(threads, asset.instance_count); ++th)
                helpers.emplace_back(build_some, th);
            build_some(0);
            for (std::thread& h : helpers) h.join();
            const double seconds = cb::seconds_since(b0);
            always = 0;
            for (const cb::InstanceShadow& tree : trees) always += tree.always_tested();
            return seconds;
        };
        std::vector<uint8_t> ours(n), embree1(n), embree16(n);
        cb::QueryStats stats;
        std::vector<std::vector<uint32_t>> query_scratch(2);  // per query thread, kept between frames like the build's
        std::vector<uint32_t> order(n), keys(n), order_scratch(cb::batch_order_scratch_size(n) - n);
        // Both sides' threads take the points in contiguous chunks (interleaved points would have them write
        // neighbouring bytes), handed out as they finish, smaller towards the end (an eighth of what is left per
        // thread, 1,024 to 4,096 points, whole tiles): parts of the view differ in cost, and the last chunk
        // should not leave a thread idle. Ours are chunks of the points' order by direction from the light, so
        // that each chunk's tiles are as close as one batch's. Both sides run on the workers while the main
        // thread waits (when it worked too, beside a thread started for the pass, the two often shared a core
        // for the whole pass: two threads ran no faster than one, on both sides). Ours each make the keys of a
        // part of the points; the last to finish sorts them while the others wait; then all answer chunks.
        auto take_chunk = [n](std::atomic<size_t>& next, unsigned threads, size_t& begin, size_t& end) {
            size_t at = next.load();
            do {
                if (at >= n) return false;
                const size_t size = std::clamp<size_t>((n - at) / (8 * threads), 1024, 4096) / 64 * 64;
                begin = at;
                end = std::min(n, at + (threads == 1 ? n : size));
            } while (!next.compare_exchange_weak(at, end));
            return true;
        };
        auto ours_pass = [&](unsigned threads) {
            auto s = std::chrono::steady_clock::now();
            std::vector<cb::QueryStats> st(threads);
            std::atomic<unsigned> keyed{0};
            std::atomic<bool> sorted{false};
            std::atomic<size_t> next{0};
            auto work = [&](unsigned th) {
                cb::batch_keys(light, pts.data(), n * th / threads, n * (th + 1) / threads, &keys[n * th / threads]);
                if (keyed.fetch_add(1) + 1 == threads) {
                    cb::batch_order_from_keys(keys.data(), n, order.data(), order_scratch.data());
                    sorted.store(true);
                } else {
                    while (!sorted.load()) std::this_thread::yield();
                }
                std::vector<uint32_t>& scratch = query_scratch[th];
                scratch.resize(std::max(scratch.size(), cb::ordered_scratch_size(trees.data(), trees.size())));
                cb::QueryStats local;  // per thread, copied out once: counters in one shared array would false-share
                for (size_t begin, end; take_chunk(next, threads, begin, end);)
                    cb::occluded_ordered(trees.data(), trees.size(), pts.data(), &order[begin], end - begin,
                                         ours.data(), scratch.data(), &local);
                st[th] = local;
            };
            workers.run(threads, work);
            stats = {};
            for (auto& s2 : st) {
                stats.nodes_visited += s2.nodes_visited;
                stats.clusters_tested += s2.clusters_tested;
                stats.triangles_tested += s2.triangles_tested;
            }
            return cb::seconds_since(s);
        };
        auto embree_pass = [&](unsigned threads, bool packets) {
            auto s = std::chrono::steady_clock::now();
            std::atomic<size_t> next{0};
            auto work = [&](unsigned) {
                for (size_t begin, end; take_chunk(next, threads, begin, end);)
                    cb::bench::occluded_range(scene, pts.data(), light, begin, end, packets ? 16 : 1, bias,
                                              packets ? embree16.data() : embree1.data());
            };
            workers.run(threads, work);
            return cb::seconds_since(s);
        };
        // build on 1 thread, ours 1 thread, build on 2, ours 2 threads, Embree occluded1 1 and 2, occluded16 1 and 2
        std::vector<double> t[8];
        // Each timed step starts after a pause: Embree's worker threads spin for a while after its passes,
        // and would otherwise take the second core from whatever runs next.
        auto settled = [](auto&& step) {
            std::this_thread::sleep_for(std::chrono::milliseconds(30));
            return step();
        };
        if (comparing) {
            compare_light(asset, fitted.view, scan_bounds, pts, light, light_names[li], in.name, runs, one_sided, bias,
                          [&] { return embree_pass(1, false); });
            continue;
        }
        if (frames > 0) {  // our frames alone (see the usage above), alternately inline and through query_scene
            std::vector<double> f, inline_queries, through_queries;
            cb::SceneQueryOptions qo;
            qo.traversal = level;
            qo.one_sided = one_sided;
            qo.threads = 1;
            for (int r = 0; r < frames; ++r) {
                const double b = build_trees(1), q = ours_pass(1);
                f.push_back(b + q);
                inline_queries.push_back(q);
                const cb::SceneQueryResult through = cb::query_scene(asset, light, pts.data(), n, qo);
                through_queries.push_back(through.query_seconds);
                if (through.shadowed != ours) std::printf("query_scene answers differ from the inline ones\n");
            }
            for (auto* v : {&f, &inline_queries, &through_queries}) std::sort(v->begin(), v->end());
            const size_t mid = f.size() / 2;
            std::printf("| %-16s | %s | %zu | %.2f ms | %.2f ms | %.2f ms | %.2f ms | %.3f |\n", in.name.c_str(),
                        light_names[li], n, f[0] * 1e3, f[mid] * 1e3, inline_queries[mid] * 1e3,
                        through_queries[mid] * 1e3, through_queries[mid] / inline_queries[mid]);
            continue;
        }
        for (int r = 0; r < std::max(1, runs); ++r) {
            t[7].push_back(settled([&] { return build_trees(2); }));
            t[2].push_back(settled([&] { return ours_pass(2); }));
            t[0].push_back(settled([&] { return build_trees(1); }));
            t[1].push_back(settled([&] { return ours_pass(1); }));
            t[3].push_back(settled([&] { return embree_pass(1, false); }));
            t[4].push_back(settled([&] { return embree_pass(2, false); }));
            t[5].push_back(settled([&] { return embree_pass(1, true); }));
            t[6].push_back(settled([&] { return embree_pass(2, true); }));
        }
        using cb::median;
        double build = median(t[0]), build2 = median(t[7]), ours1 = median(t[1]), ours2 = median(t[2]),
               e1 = median(t[3]), e2 = median(t[4]), p1 = median(t[5]), p2 = median(t[6]);
        // The ratios per round, then their median: this VM's speed drifts between rounds, and both sides of a
        // round's ratio ran within the same few hundred milliseconds.
        std::vector<double> r1, r2, q1, q2;  // against occluded1, then occluded16
        for (size_t r = 0; r < t[0].size(); ++r) {
            r1.push_back((t[0][r] + t[1][r]) / t[3][r]);
            r2.push_back((t[7][r] + t[2][r]) / t[4][r]);
            q1.push_back((t[0][r] + t[1][r]) / t[5][r]);
            q2.push_back((t[7][r] + t[2][r]) / t[6][r]);
        }
        const double ratio1 = median(r1), ratio2 = median(r2), packet1 = median(q1), packet2 = median(q2);
        size_t shadowed = 0, differ = 0;
        for (size_t i = 0; i < n; ++i) {
            shadowed += ours[i];
            differ += ours[i] != embree1[i];
        }
        double mq = double(n) / 1e6;
        size_t ours_bytes = bytes.size() + (level == cb::Traversal::scan ? scan_bounds_bytes : 0);
        for (const cb::InstanceShadow& tr : trees) ours_bytes += tr.memory_bytes();
        size_t scratch_bytes = 0;
        for (const cb::BuildScratch& b : build_scratch) scratch_bytes += b.memory_bytes();
        for (const std::vector<uint32_t>& q : query_scratch) scratch_bytes += q.capacity() * sizeof(uint32_t);
        scratch_bytes += (order.capacity() + keys.capacity() + order_scratch.capacity()) * sizeof(uint32_t);
        std::printf(
            "| %-16s | %s | %zu | %.0f%% | %.1f / %.1f ms | %.2f / %.2f | %.2f / %.2f | %.2f / %.2f | %.0f / %.1f ms | "
            "%.2f / %.2f | %.2f / %.2f | %.1f | %.1f | %.1f | %.1f | %zu | %.1f + %.1f / %.1f | %zu (%.3f%%) |\n",
            in.name.c_str(), light_names[li], n, 100.0 * double(shadowed) / double(n), build * 1e3, build2 * 1e3,
            mq / ours1, mq / ours2, mq / e1, mq / e2, mq / p1, mq / p2, embree_build * 1e3, scan_bounds_time * 1e3,
            ratio1, ratio2, packet1, packet2, double(stats.nodes_visited) / double(n),
            double(stats.clusters_tested) / double(n), double(stats.triangles_tested) / double(n),
            double(stats.clusters_tested - shadowed) / double(n), always, double(ours_bytes) / 1048576.0,
            double(scratch_bytes) / 1048576.0, double(cb::bench::embree_peak) / 1048576.0, differ,
            100.0 * double(differ) / double(n));
    }
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
}

}  // namespace

static int run(int argc, char** argv) {
    cb::bench::Options defaults;
    defaults.runs = 3;
    cb::bench::Options o = cb::bench::parse_options(argc, argv, defaults);
    using Level = cb::Traversal;
    Level level = o.level == "top-two" || o.level == "trees" ? Level::top_two
        : o.level == "top-one" || o.level == "one-tree"      ? Level::top_one
        : o.level == "mtsv-one" || o.level == "mtsv"         ? Level::mtsv_one
        : o.level == "mtsv-two"                              ? Level::mtsv_two
                                                             : Level::scan;
    const bool comparing = o.level == "compare";
    if (comparing) {
        std::printf(
            "%s; %dx%d view; every traversal on the same points and lights, one thread, medians of %d rounds "
            "alternating between them; frame = per-light build + the queries of the view's points (sorted by "
            "direction, then tiles); 'vs CPSV' = frame / CPSV one level's frame; 'vs Embree' = frame / Embree "
            "occluded1's queries alone; KB = the per-light structures (the asset is not counted); differ = answers "
            "unlike the scan's\n\n",
            o.one_sided ? "one-sided" : "two-sided", o.view, o.view, std::max(1, o.runs));
        std::printf(
            "| scene | light | configuration | build ms | queries ms | frame ms | vs CPSV | vs Embree | M q/s | "
            "nodes/query | clusters/query | useless clusters/query | KB | nodes | capsule-cones | differ |\n"
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    } else if (o.frames > 0) {
        std::printf("%s, traversal '%s'; %dx%d view; our frames alone (build and queries, one thread), %d per light\n",
                    o.one_sided ? "one-sided trees" : "two-sided trees", o.level.c_str(), o.view, o.view, o.frames);
        std::printf(
            "inline: the runtime compiled into this benchmark (%s lanes); query_scene: the same queries (after the "
            "build) through the tools' query library, dispatched at run time to %s lanes\n\n",
            cb::simd::name, cb::query_lanes());
        std::printf(
            "| scene | light | points | shortest frame | median frame | inline queries, median | query_scene "
            "queries, median | ratio |\n|---|---|---|---|---|---|---|---|\n");
    } else {
        std::printf(
            "%s, traversal '%s'; %dx%d view; medians of %d rounds; M q/s = million queries per second on 1 / 2 "
            "threads; 'ours vs Embree' = "
            "(our build + our queries) / Embree's queries alone, 1 / 2 threads, the median of the rounds' ratios "
            "(below 1: we "
            "are faster), against occluded1, then occluded16 (packets of 16 consecutive pixels); memory: our asset, "
            "scan bounds and "
            "trees + scratch kept between frames (the build's and the two query threads') / Embree's peak\n\n",
            o.one_sided ? "one-sided trees" : "two-sided trees", o.level.c_str(), o.view, o.view, std::max(1, o.runs));
        std::printf(
            "| scene | light | points | in shadow | our build 1 / 2 threads | ours M q/s | Embree occluded1 M q/s | "
            "Embree occluded16 M q/s | "
            "Embree build / our scan bounds (once per asset) | ours vs Embree occluded1 | ours vs Embree occluded16 | "
            "nodes/query | clusters/query | triangles/query | useless clusters/query | always tested | MB ours + "
            "scratch / Embree | disagree |\n");
        std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    }
    std::vector<Input> inputs;
    for (const char* f : {"scanned/dragon_vrip_res2_binary.ply", "scanned/horse.ply"})
        if (cb::bench::wanted(o, f))
            inputs.push_back({fs::path(f).filename().string(), cb::load_scene((o.data / f).string())});
    if (o.copies > 0 && cb::bench::wanted(o, "big")) {
        cb::Scene base = cb::load_scene((o.data / "scanned/dragon_vrip_res2_binary.ply").string());
        cb::Scene big;
        big.meshes.push_back(cb::bench::merged_copies(base.meshes[0], o.copies));
        big.instances.push_back({0, cb::identity_transform(), "big"});
        inputs.push_back({std::to_string(o.copies) + "x dragon", std::move(big)});
    }
    for (const Input& in : inputs) run(in, o.view, o.runs, o.one_sided != 0, level, o.frames, comparing);
    return 0;
}

int main(int argc, char** argv) {
    return cb::bench::guarded_main("bench_shadow", [&] { return run(argc, argv); });
}
