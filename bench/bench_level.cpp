// Whole-level shadow benchmark: the runtime's level (cb_level.h: instances culled per tile through a
// world-space hierarchy) against Embree 3's rtcOccluded1 and rtcOccluded16 on the same points, one thread
// and --threads threads, with Embree given both one flattened BVH of every instance's triangles and its own
// two-level instancing (the fastest of the four counts).
// Scenes: every scene of ../shared/data, data/default_scene.glb, and generated cities (a ground plane and
// instances of 20 buildings, random yaw, every seventh mirrored) of 10 to 100,000 buildings. Points: the
// first hits of a W x W view looking down at the scene's centre from a diagonal; lights: beside and above
// the scene (outside), overhead, grazing the ground, and inside the bounds; and two suns, in the directions of
// the outside and the grazing lights from the centre (Embree's rays along the same direction, without end).
// Ours per light counts everything a frame costs: ordering the points, culling the tiles, setting the
// instances met up for the light, and the queries (each thread's scratch kept from pass to pass, as an engine
// keeps it); on several threads each step runs in ranges on threads started for the pass (Embree's rays
// too). Medians of --runs rounds, each running ours then Embree's. Also the cost of moving 1,000 instances
// and committing (a refit). Asserts nothing.
//
//   bench_level [--data DIR] [--view 512] [--runs 3] [--cities 10,100,1000,10000,100000] [--only NAME]
//               [--lights all|points|suns|outside|overhead|grazing|inside|"sun high"|"sun low"]
//               [--traversal scan|top-two|top-one|mtsv-one|mtsv-two] [--one-sided 1] [--threads 2]
//               [--obb refined|pca|pca-area|cgal]
#include <embree3/rtcore.h>

#include <cb_level.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "asset_file.h"
#include "bench_embree.h"
#include "bake.h"
#include "city.h"
#include "load.h"
#include "scene_query.h"
#include "timing.h"

namespace fs = std::filesystem;

namespace {

struct Settings {
    int view = 512, runs = 3;
    unsigned threads = 2;  // the second measurement's (the first is one thread)
    std::vector<uint32_t> cities = {10, 100, 1000, 10000, 100000};
    std::string only;
    std::string lights = "all";  // "points" or "suns": only those; or one light by name
    cb::ShadowBuildOptions options;
    cb::ObbMethod obb = cb::ObbMethod::refined;  // the bake's box fitter: what box tightness is worth at run time
};

// Ours / the fastest Embree, per scene and light: point lights, then suns.
std::vector<double> ratios, threaded_ratios, sun_ratios, sun_threaded_ratios;

// Embree scenes over the same triangles: one flattened BVH (when the level has at most `flat_limit`
// triangles in it), and two levels (a BVH per mesh, instanced).
struct EmbreeScenes {
    RTCDevice device = nullptr;
    RTCScene flat = nullptr, instanced = nullptr;
    std::vector<RTCScene> meshes;
    size_t flat_bytes = 0, instanced_bytes = 0;
    ~EmbreeScenes() {
        for (RTCScene s : meshes) rtcReleaseScene(s);
        if (flat) rtcReleaseScene(flat);
        if (instanced) rtcReleaseScene(instanced);
        if (device) rtcReleaseDevice(device);
    }
};

RTCScene triangles(RTCDevice device, const std::vector<float>& v, const std::vector<unsigned>& t) {
    RTCScene scene = rtcNewScene(device);
    RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    std::memcpy(
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, std::max<size_t>(1, v.size() / 3)),
        v.data(), v.size() * 4);
    std::memcpy(
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, std::max<size_t>(1, t.size() / 3)),
        t.data(), t.size() * 4);
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(scene);
    return scene;
}

void build_embree(const cb::Scene& s, EmbreeScenes& e, size_t flat_limit) {
    e.device = rtcNewDevice("threads=1");
    rtcSetDeviceMemoryMonitorFunction(e.device, cb::bench::embree_monitor, nullptr);
    size_t in_scene = 0;
    for (const cb::Instance& inst : s.instances) in_scene += s.meshes[inst.mesh].triangle_count();
    if (in_scene <= flat_limit) {
        cb::bench::embree_bytes = 0;
        std::vector<float> v;
        std::vector<unsigned> t;
        for (const cb::Instance& inst : s.instances) {
            const cb::Mesh& m = s.meshes[inst.mesh];
            const unsigned base = unsigned(v.size() / 3);
            for (size_t k = 0; k < m.vertex_count(); ++k) {
                auto w =
                    cb::transform_point(inst.world, m.positions[k * 3], m.positions[k * 3 + 1], m.positions[k * 3 + 2]);
                v.insert(v.end(), {float(w[0]), float(w[1]), float(w[2])});
            }
            for (uint32_t i : m.indices) t.push_back(base + i);
        }
        e.flat = triangles(e.device, v, t);
        e.flat_bytes = size_t(std::max(0LL, cb::bench::embree_bytes.load()));
    }
    cb::bench::embree_bytes = 0;
    for (const cb::Mesh& m : s.meshes) {
        std::vector<unsigned> t(m.indices.begin(), m.indices.end());
        e.meshes.push_back(triangles(e.device, m.positions, t));
    }
    e.instanced = rtcNewScene(e.device);
    for (const cb::Instance& inst : s.instances) {
        RTCGeometry g = rtcNewGeometry(e.device, RTC_GEOMETRY_TYPE_INSTANCE);
        rtcSetGeometryInstancedScene(g, e.meshes[inst.mesh]);
        float m[12];
        for (int col = 0; col < 4; ++col)
            for (int row = 0; row < 3; ++row) m[col * 3 + row] = float(inst.world[size_t(col) * 4 + row]);
        rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, m);
        rtcCommitGeometry(g);
        rtcAttachGeometry(e.instanced, g);
        rtcReleaseGeometry(g);
    }
    rtcCommitScene(e.instanced);
    e.instanced_bytes = size_t(std::max(0LL, cb::bench::embree_bytes.load()));
}

// Runs job(t) for t in [0, threads): on threads started here, the calling thread taking job 0.
template <class Job>
void on_threads(unsigned threads, Job job) {
    std::vector<std::thread> helpers;
    for (unsigned t = 1; t < threads; ++t) helpers.emplace_back(job, t);
    job(0);
    for (std::thread& h : helpers) h.join();
}

// Every point on `threads` threads, each a contiguous part of the view; returns the seconds taken.
double embree_pass(RTCScene scene, const std::vector<double>& pts, const double* light, double bias, int packet,
                   unsigned threads, std::vector<uint8_t>& out, bool sun) {
    const size_t n = pts.size() / 3;
    auto t0 = std::chrono::steady_clock::now();
    on_threads(threads, [&](unsigned t) {
        cb::bench::occluded_range(scene, pts.data(), light, n * t / threads / 16 * 16,
                                  t + 1 == threads ? n : n * (t + 1) / threads / 16 * 16, packet, bias, out.data(),
                                  sun);
    });
    return cb::seconds_since(t0);
}

// Ours for one light (or sun) on `threads` threads: order (one thread), cull, set up and answer in ranges.
double our_pass(cb::LevelShadow& shadow, const cb::Level& level, const double* light, const std::vector<double>& pts,
                const cb::ShadowBuildOptions& options, unsigned threads, std::vector<uint8_t>& out, bool sun,
                cb::QueryStats* stats = nullptr) {
    const size_t n = pts.size() / 3;
    auto t0 = std::chrono::steady_clock::now();
    if (sun)
        shadow.begin_sun(level, light, pts.data(), n, options);
    else
        shadow.begin(level, light, pts.data(), n, options);
    const size_t tiles = shadow.tile_count();
    on_threads(threads, [&](unsigned t) { shadow.cull(tiles * t / threads, tiles * (t + 1) / threads); });
    const size_t built = shadow.gather();
    // Each thread's scratch is kept from pass to pass, as an engine keeps it from frame to frame.
    static std::vector<cb::BuildScratch> build_scratch;
    if (build_scratch.size() < threads) build_scratch.resize(threads);
    on_threads(threads,
               [&](unsigned t) { shadow.build(built * t / threads, built * (t + 1) / threads, &build_scratch[t]); });
    static std::vector<std::vector<uint32_t>> scratches;
    if (scratches.size() < threads) scratches.resize(threads);
    on_threads(threads, [&](unsigned t) {
        std::vector<uint32_t>& scratch = scratches[t];
        if (scratch.size() < shadow.scratch_size()) scratch.resize(shadow.scratch_size());
        shadow.occluded(tiles * t / threads, tiles * (t + 1) / threads, out.data(), scratch.data(), stats);
    });
    return cb::seconds_since(t0);
}

void run(const std::string& name, const cb::Scene& scene, const Settings& s) {
    cb::BakeStats bs;
    std::vector<cb::AssetMesh> meshes = cb::cluster_scene(scene, {}, bs);
    cb::BoundsOptions bo;
    bo.mask = cb::bounds_auto;
    bo.obb = s.obb;
    cb::fit_scene_bounds(meshes, bo, 1, bs);
    cb::LoadedAsset loaded;
    if (cb::open_asset_copy(cb::encode_asset(meshes, scene.instances), loaded) != cb::AssetError::ok) return;
    const cb::AssetView& asset = loaded.view;

    auto l0 = std::chrono::steady_clock::now();
    cb::Level level;
    level.add_baked(level.add_asset(asset));  // the scan's bounds: the suns read them whatever the traversal
    level.commit();
    const double level_seconds = cb::seconds_since(l0);

    EmbreeScenes e;
    build_embree(scene, e, 20'000'000);

    // The bounds of the world triangles, and the camera's first hits.
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (const cb::Instance& inst : scene.instances) {
        const cb::Mesh& m = scene.meshes[inst.mesh];
        for (size_t k = 0; k < m.vertex_count(); ++k) {
            auto w =
                cb::transform_point(inst.world, m.positions[k * 3], m.positions[k * 3 + 1], m.positions[k * 3 + 2]);
            for (int j = 0; j < 3; ++j) {
                lo[j] = std::min(lo[j], w[j]);
                hi[j] = std::max(hi[j], w[j]);
            }
        }
    }
    const double size = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
    if (!(size > 0 && size < 1e30 &&
          std::max({std::fabs(lo[0]), std::fabs(lo[1]), std::fabs(lo[2]), std::fabs(hi[0]), std::fabs(hi[1]),
                    std::fabs(hi[2])}) < 1e30)) {
        std::printf("| %s | skipped: its bounds (size %g) are beyond what Embree's float rays take |\n", name.c_str(),
                    size);
        return;
    }
    const double centre[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
    // Up is the axis the scene is thinnest along (z for the cities, y for most glTF scenes).
    int up_axis = 0;
    for (int k = 1; k < 3; ++k)
        if (hi[k] - lo[k] < hi[up_axis] - lo[up_axis]) up_axis = k;
    const int a1 = (up_axis + 1) % 3, a2 = (up_axis + 2) % 3;
    double eye[3], fw[3], right[3], up[3] = {0, 0, 0}, len = 0;
    eye[a1] = centre[a1] + 0.9 * size;
    eye[a2] = centre[a2] + 0.6 * size;
    eye[up_axis] = centre[up_axis] + 0.8 * size;
    up[up_axis] = 1;
    for (int k = 0; k < 3; ++k) {
        fw[k] = centre[k] - eye[k];
        len += fw[k] * fw[k];
    }
    for (double& x : fw) x /= std::sqrt(len);
    cb::math::cross3(fw, up, right);
    len = std::sqrt(cb::math::dot3(right, right));
    for (double& x : right) x /= len;
    cb::math::cross3(right, fw, up);
    RTCScene any = e.flat ? e.flat : e.instanced;
    const std::vector<double> pts = cb::bench::first_hits(any, eye, fw, right, up, s.view, 0.6);
    const size_t n = pts.size() / 3;
    if (n == 0) return;

    double lights[6][3];
    for (int k = 0; k < 3; ++k) {
        lights[0][k] = centre[k];
        lights[1][k] = centre[k];
        lights[2][k] = centre[k];
        lights[3][k] = centre[k];
    }
    lights[0][a1] -= 0.7 * size;
    lights[0][a2] += 0.4 * size;
    lights[0][up_axis] = hi[up_axis] + 0.8 * size;  // outside
    lights[1][a1] += 0.05 * size;
    lights[1][up_axis] = hi[up_axis] + 0.5 * size;  // overhead
    lights[2][a1] -= 1.5 * size;
    lights[2][up_axis] = lo[up_axis] + 0.02 * (hi[up_axis] - lo[up_axis]) + 1e-3 * size;  // grazing
    lights[3][a1] += 0.1 * size;
    lights[3][a2] -= 0.07 * size;
    lights[3][up_axis] = lo[up_axis] + 0.3 * (hi[up_axis] - lo[up_axis]);  // inside
    // Suns: the directions from the centre toward the outside and the grazing lights.
    for (int k = 0; k < 3; ++k) {
        lights[4][k] = lights[0][k] - centre[k];
        lights[5][k] = lights[2][k] - centre[k];
    }
    const char* light_names[6] = {"outside", "overhead", "grazing", "inside", "sun high", "sun low"};

    uint32_t in_scene = 0;
    for (const cb::Instance& inst : scene.instances) in_scene += uint32_t(scene.meshes[inst.mesh].triangle_count());
    cb::LevelShadow shadow;
    std::vector<uint8_t> ours(n), ours_t(n), ref(n), other(n), counted(n);
    const unsigned threads = std::max(1u, s.threads);
    for (int li = 0; li < 6; ++li) {
        const double* light = lights[li];
        const bool sun = li >= 4;
        if ((sun && s.lights == "points") || (!sun && s.lights == "suns")) continue;
        if (s.lights != "all" && s.lights != "points" && s.lights != "suns" && s.lights != light_names[li]) continue;
        // Embree's four ways (flat or instanced, packets of 1 or 16), one thread and `threads`.
        std::vector<double> our_t, our_tt, embree_t[4], embree_tt[4];
        size_t met = 0, built = 0, bytes = 0;
        for (int r = 0; r < std::max(1, s.runs); ++r) {
            our_t.push_back(our_pass(shadow, level, light, pts, s.options, 1, ours, sun));
            met = shadow.instances_met();
            built = shadow.build_count();
            bytes = shadow.memory_bytes();
            our_tt.push_back(our_pass(shadow, level, light, pts, s.options, threads, ours_t, sun));
            for (int way = 0; way < 4; ++way) {
                RTCScene scene = way < 2 ? e.flat : e.instanced;
                if (!scene) continue;
                std::vector<uint8_t>& out = way == 0 || (way == 2 && !e.flat) ? ref : other;
                embree_t[way].push_back(
                    embree_pass(scene, pts, light, level.shadow_bias(), way % 2 ? 16 : 1, 1, out, sun));
                embree_tt[way].push_back(
                    embree_pass(scene, pts, light, level.shadow_bias(), way % 2 ? 16 : 1, threads, other, sun));
            }
        }
        double best = INFINITY, best_t = INFINITY, way_ms[4];
        for (int way = 0; way < 4; ++way) {
            way_ms[way] = embree_t[way].empty() ? NAN : cb::median(embree_t[way]) * 1e3;
            if (!embree_t[way].empty()) {
                best = std::min(best, cb::median(embree_t[way]));
                best_t = std::min(best_t, cb::median(embree_tt[way]));
            }
        }
        // The work behind our answers, counted in a pass of its own (counting is not free): fine clusters and
        // triangles tested per point, what looser cluster boxes would add to.
        cb::QueryStats work;
        our_pass(shadow, level, light, pts, s.options, 1, counted, sun, &work);
        const double o = cb::median(our_t), ot = cb::median(our_tt);
        size_t differ = 0, dark = 0, threads_differ = 0;
        for (size_t k = 0; k < n; ++k) {
            differ += ours[k] != ref[k];
            dark += ours[k];
            threads_differ += ours[k] != ours_t[k] || ours[k] != counted[k];
        }
        (sun ? sun_ratios : ratios).push_back(o / best);
        (sun ? sun_threaded_ratios : threaded_ratios).push_back(ot / best_t);
        auto ms = [](double v) {
            char text[32] = "-";
            if (v == v) std::snprintf(text, sizeof text, "%.2f", v);
            return std::string(text);
        };
        std::printf(
            "| %s | %zu / %zu / %u | %s | %zu | %.1f%% | %.2f | %s / %s | %s / %s | **%.2f** | %.2f / %.2f / **%.2f** "
            "| %.2f | %.2f / %.2f | %zu | %.1f | %.1f / %.1f | %zu / %zu |\n",
            name.c_str(), scene.meshes.size(), scene.instances.size(), in_scene, light_names[li], n, 100.0 * dark / n,
            o * 1e3, ms(way_ms[0]).c_str(), ms(way_ms[1]).c_str(), ms(way_ms[2]).c_str(), ms(way_ms[3]).c_str(),
            o / best, ot * 1e3, best_t * 1e3, ot / best_t, double(n) / o / 1e6,
            double(work.clusters_tested) / double(n), double(work.triangles_tested) / double(n), built,
            double(met) / double(shadow.tile_count()), double(level.memory_bytes() + bytes) / (1 << 20),
            double(e.flat ? e.flat_bytes : e.instanced_bytes) / (1 << 20), differ, threads_differ);
        std::fflush(stdout);
    }
    // Moving 1,000 instances (or all, when fewer) and committing: a refit.
    std::mt19937_64 rng(5);
    std::vector<double> move_t;
    const uint32_t movers = std::min<uint32_t>(1000, level.instance_count());
    for (int r = 0; r < 5; ++r) {
        auto t0 = std::chrono::steady_clock::now();
        for (uint32_t k = 0; k < movers; ++k) {
            const uint32_t h = uint32_t(rng() % level.handle_limit());
            double m[12];
            std::copy(level.transform_of(h), level.transform_of(h) + 12, m);
            m[9] += 0.01;
            m[10] -= 0.01;
            level.move(h, m);
        }
        level.commit();
        move_t.push_back(cb::seconds_since(t0));
    }
    std::printf("| %s | level made in %.2f ms; moving %u instances and committing: %.3f ms (median of 5) |\n",
                name.c_str(), level_seconds * 1e3, movers, cb::median(move_t) * 1e3);
    std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
    Settings s;
    fs::path data = CB_SHARED_DATA;
    for (int i = 1; i + 1 < argc; i += 2) {
        const std::string a = argv[i], v = argv[i + 1];
        if (a == "--data")
            data = v;
        else if (a == "--view")
            s.view = std::stoi(v);
        else if (a == "--runs")
            s.runs = std::stoi(v);
        else if (a == "--threads")
            s.threads = unsigned(std::stoul(v));
        else if (a == "--only")
            s.only = v;
        else if (a == "--lights" &&
                 (v == "all" || v == "points" || v == "suns" || v == "outside" || v == "overhead" || v == "grazing" ||
                  v == "inside" || v == "sun high" || v == "sun low"))
            s.lights = v;
        else if (a == "--obb") {
            if (!cb::parse_obb_method(v, s.obb)) {
                std::fprintf(stderr, "unknown box fitter %s\n", v.c_str());
                return 2;
            }
        } else if (a == "--one-sided")
            s.options.one_sided = v == "1";
        else if (a == "--traversal") {
            if (!cb::parse_traversal(v, s.options.traversal)) {
                std::fprintf(stderr, "unknown traversal %s\n", v.c_str());
                return 2;
            }
        } else if (a == "--cities") {
            s.cities.clear();
            for (size_t at = 0; at < v.size();) {
                size_t comma = v.find(',', at);
                s.cities.push_back(uint32_t(std::stoul(v.substr(at, comma - at))));
                at = comma == std::string::npos ? v.size() : comma + 1;
            }
        } else {
            std::fprintf(stderr, "unknown option %s\n", a.c_str());
            return 2;
        }
    }
    std::printf(
        "%s traversal%s, boxes %s, view %d x %d, medians of %d rounds. Ours: order + cull + set-up + queries "
        "per light; Embree: rtcOccluded1 / rtcOccluded16 over a flat BVH of every instance's triangles and over "
        "two-level instancing, BVH builds not counted. ratio = ours / the fastest of Embree's four, on one thread "
        "and on %u (ours ms / Embree's fastest ms / ratio). Answers differing: ours against Embree's rtcOccluded1 "
        "(flat when built; float ties), and ours on 1 thread against ours on %u and against the counting pass.\n\n",
        cb::traversal_name(s.options.traversal), s.options.one_sided ? ", one-sided" : "", cb::obb_method_name(s.obb),
        s.view, s.view, s.runs, s.threads, s.threads);
    std::printf(
        "| scene | meshes / instances / triangles in scene | light | points | shadowed | ours ms, 1 thread | Embree "
        "flat ms occluded1 / 16 | Embree inst ms occluded1 / 16 | ratio, 1 thread | %u threads: ours ms / Embree "
        "ms / ratio | our M points/s | clusters / triangles tested per point | instances set up | instances met "
        "per tile | memory MB ours / Embree | answers differing: from Embree's / 1 and %u threads |\n",
        s.threads, s.threads);
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    auto wanted = [&](const std::string& name) { return s.only.empty() || name.find(s.only) != std::string::npos; };
    for (uint32_t c : s.cities) {
        const std::string name = "city " + std::to_string(c);
        if (wanted(name)) run(name, cb::generate::city(c, 1), s);
    }
    std::vector<fs::path> files;
    const fs::path here = fs::path(CB_SOURCE_DIR) / "data" / "default_scene.glb";
    if (fs::exists(here)) files.push_back(here);
    if (fs::exists(data)) {
        for (const auto& entry : fs::recursive_directory_iterator(data)) {
            const std::string ext = entry.path().extension().string();
            if (ext == ".gltf" || ext == ".glb" || ext == ".obj" || ext == ".ply" || ext == ".off" || ext == ".stl" ||
                ext == ".STL")
                files.push_back(entry.path());
        }
    } else {
        std::printf("(no %s: the shared scenes are skipped)\n", data.string().c_str());
    }
    std::sort(files.begin() + (files.empty() ? 0 : 1), files.end());
    for (const fs::path& f : files) {
        const std::string name = f.filename().string();
        if (!wanted(name)) continue;
        cb::Scene scene;
        try {
            scene = cb::load_scene(f.string());
        } catch (const std::exception& ex) {
            continue;  // the shared data holds broken files on purpose
        }
        if (scene.instances.empty()) continue;
        run(name, scene, s);
    }
    auto summary = [&](const char* what, const std::vector<double>& one, const std::vector<double>& many) {
        if (one.empty()) return;
        std::vector<double> sorted = one;
        std::sort(sorted.begin(), sorted.end());
        std::printf("\nratio ours / Embree over %zu scene-%s, one thread: median %.2f, worst %.2f, best %.2f\n",
                    sorted.size(), what, cb::median(one), sorted.back(), sorted.front());
        sorted = many;
        std::sort(sorted.begin(), sorted.end());
        std::printf("ratio ours / Embree, %u threads: median %.2f, worst %.2f, best %.2f\n", s.threads,
                    cb::median(many), sorted.back(), sorted.front());
    };
    summary("point lights", ratios, threaded_ratios);
    summary("suns", sun_ratios, sun_threaded_ratios);
    return 0;
}
