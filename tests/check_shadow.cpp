// A long correctness run, outside ctest: shadow queries on every scene of ../shared/data (or on the given
// files), answered by the runtime's shadow trees (each Traversal) and by its reference walk, each
// compared with the fast exact oracle (scene_oracle.h), in two-sided and one-sided mode.
// Lights per scene: outside the bounds, grazing their top, beside them exactly level with the topmost
// vertex, inside them, exactly on a vertex, and exactly on a triangle's plane beside the triangle. Points:
// surface points seen from cameras outside the bounds, vertices, points just behind (or far behind)
// triangles, random points in and around the bounds, and for the plane light points on that plane. Files
// that do not load are skipped with the reason.
// Exit code 1 on any disagreement (the first ones are printed in full), 2 when nothing was checked.
//
//   check_shadow [--queries N] [--threads T] [--brute-force-every K] [FILE...]
//     N queries in all, spread evenly over the scenes (default 1000000); T = 0: every core; with K, every K-th
//     query also asks the oracle without its AABB trees (every triangle), which must give the same answer.
#include <cb_instance_shadow.h>
#include <detail/cb_math.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "load.h"
#include "scene_oracle.h"

namespace fs = std::filesystem;
using cb::test::SceneOracle;
using cb::test::WorldSample;
using Point = std::array<double, 3>;

namespace {

struct Options {
    size_t queries = 1000000;
    unsigned threads = 1;
    size_t brute_every = 0;  // also check the oracle's candidates against all triangles on every such query
    std::vector<std::string> files;
};

struct Light {
    const char* kind;
    Point at;
};

struct Answer {
    cb::test::OracleAnswer exact;
    // Tiled batches (fine scan, fine trees, one tree); walks per point (fine scan, fine trees); the reference walk.
    bool scan = false, tree2 = false, tree1 = false, walk = false, walk2 = false, reference = false;
    // Metric trees (one level, two levels: batches; one level: walks per point), on the fitted volumes.
    bool metric = false, metric2 = false, metric_walk = false;
    bool brute_checked = false, brute_agrees = true;
};

struct Tally {
    size_t queries = 0, shadowed = 0, touching = 0, only_touching = 0, bad_scan = 0, bad_tree2 = 0, bad_tree1 = 0,
           bad_walk = 0, bad_walk2 = 0, bad_reference = 0, bad_metric = 0;
    size_t missed_shadow = 0;  // some runtime answer says lit where the oracle says shadow
    size_t bad_touching = 0;   // disagreements on queries the oracle calls touching
    size_t brute_checked = 0, brute_bad = 0;

    void add(const Tally& t) {
        queries += t.queries;
        shadowed += t.shadowed;
        touching += t.touching;
        only_touching += t.only_touching;
        bad_scan += t.bad_scan;
        bad_tree2 += t.bad_tree2;
        bad_tree1 += t.bad_tree1;
        bad_walk += t.bad_walk;
        bad_walk2 += t.bad_walk2;
        bad_metric += t.bad_metric;
        bad_reference += t.bad_reference;
        missed_shadow += t.missed_shadow;
        bad_touching += t.bad_touching;
        brute_checked += t.brute_checked;
        brute_bad += t.brute_bad;
    }
    size_t bad() const {
        return bad_scan + bad_tree2 + bad_tree1 + bad_walk + bad_walk2 + bad_reference + bad_metric + brute_bad;
    }
};

constexpr size_t max_reports = 20;  // disagreements printed in full per scene

// Every file under `root` whose extension names a scene format, in a fixed order.
std::vector<std::string> scene_files(const fs::path& root) {
    std::vector<std::string> out;
    if (!fs::exists(root)) return out;
    for (const auto& e : fs::recursive_directory_iterator(root))
        if (e.is_regular_file() && cb::format_from_path(e.path().string()) != cb::FileFormat::unknown)
            out.push_back(e.path().string());
    std::sort(out.begin(), out.end());
    return out;
}

Point normalized(Point v) {
    double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    return {v[0] / l, v[1] / l, v[2] / l};
}

Point cross(const Point& a, const Point& b) {
    Point c;
    cb::math::cross3(a.data(), b.data(), c.data());
    return c;
}

// Surface points seen from three cameras outside the bounds (one from below): rays through a grid x grid
// raster over the bounding sphere, first hits through the oracle's CGAL trees, in double.
std::vector<Point> camera_points(const SceneOracle& oracle, const WorldSample& w, int grid) {
    Point c = {0.5 * (w.lo[0] + w.hi[0]), 0.5 * (w.lo[1] + w.hi[1]), 0.5 * (w.lo[2] + w.hi[2])};
    double r = 0.5 *
        std::sqrt((w.hi[0] - w.lo[0]) * (w.hi[0] - w.lo[0]) + (w.hi[1] - w.lo[1]) * (w.hi[1] - w.lo[1]) +
                  (w.hi[2] - w.lo[2]) * (w.hi[2] - w.lo[2]));
    if (!(r > 0)) r = 1;
    std::vector<Point> out;
    for (Point d : {Point{1, 0.8, 0.6}, Point{-0.7, 0.5, -1}, Point{0.3, -0.9, 0.8}}) {
        d = normalized(d);
        Point eye = {c[0] + 2.5 * r * d[0], c[1] + 2.5 * r * d[1], c[2] + 2.5 * r * d[2]};
        Point right = normalized(cross(d, {0, 1, 0})), up = cross(right, d);
        for (int i = 0; i < grid; ++i)
            for (int j = 0; j < grid; ++j) {
                double u = (2 * (i + 0.5) / grid - 1) * r, v = (2 * (j + 0.5) / grid - 1) * r, dir[3], hit[3];
                for (int k = 0; k < 3; ++k) dir[k] = c[k] + u * right[k] + v * up[k] - eye[k];
                if (oracle.first_hit(eye.data(), dir, hit)) out.push_back({hit[0], hit[1], hit[2]});
            }
    }
    return out;
}

// Points on the plane light's triangle's plane (a + i (b - a) + j (c - a)), kept when the runtime's
// mapping into the mesh frame leaves them exactly on it: their segments to the light lie in that plane.
std::vector<Point> in_plane_points(const cb::Scene& scene, const cb::test::PlaneLight& pl) {
    std::vector<Point> out;
    if (!pl.found) return out;
    std::array<double, 12> m = cb::test::instance_3x4(scene.instances[pl.instance].world);
    const auto& c = pl.corner;
    cb::test::Epick::Point_3 a(c[0][0], c[0][1], c[0][2]), b(c[1][0], c[1][1], c[1][2]), d(c[2][0], c[2][1], c[2][2]);
    for (int i = -3; i <= 4; ++i)
        for (int j = -3; j <= 4; ++j) {
            double local[3], world[3], back[3];
            for (int k = 0; k < 3; ++k) local[k] = c[0][k] + i * (c[1][k] - c[0][k]) + j * (c[2][k] - c[0][k]);
            cb::apply_instance(m.data(), local, world);
            if (cb::test::world_to_mesh(scene.instances[pl.instance], world, back) &&
                CGAL::orientation(a, b, d, cb::test::Epick::Point_3(back[0], back[1], back[2])) == CGAL::COPLANAR)
                out.push_back({world[0], world[1], world[2]});
        }
    return out;
}

// The scene's lights; `note` says which kinds could not be placed exactly.
std::vector<Light> scene_lights(const cb::Scene& scene, const WorldSample& w, double size, cb::test::PlaneLight& plane,
                                std::string& note) {
    const double *lo = w.lo, *hi = w.hi;
    std::vector<Light> lights = {
        {"outside", {lo[0] - size, hi[1] + 2 * size, lo[2] - 0.5 * size}},
        {"grazing", {0.5 * (lo[0] + hi[0]), hi[1] + 1e-3 * size, 0.5 * (lo[2] + hi[2])}},
        {"level", {lo[0] - 0.5 * size, hi[1], 0.5 * (lo[2] + hi[2])}},  // beside the bounds, level with the top vertex
        {"inside", {lo[0] + 0.45 * (hi[0] - lo[0]), lo[1] + 0.55 * (hi[1] - lo[1]), lo[2] + 0.5 * (hi[2] - lo[2])}}};
    Light vertex{"vertex", {}};
    if (cb::test::vertex_light(scene, 2027, vertex.at.data()))
        lights.push_back(vertex);
    else
        note += " no-vertex-light";
    plane = cb::test::plane_light(scene, 4099);
    if (plane.found)
        lights.push_back({"plane", {plane.light[0], plane.light[1], plane.light[2]}});
    else
        note += " no-plane-light";
    if (plane.found && scene.instances[plane.instance].world != cb::identity_transform())
        note += " plane-light-on-transformed-instance-" + std::to_string(plane.instance);
    return lights;
}

// The query points of one light: 40% seen by the cameras, 20% vertices, 20% through triangles, 20% random
// in and around the bounds (half of those on the plane for the plane light).
std::vector<Point> light_points(size_t n, uint32_t salt, const std::vector<Point>& seen, const WorldSample& w,
                                double size, const std::vector<Point>& through, const std::vector<Point>& flat) {
    std::mt19937 rng(101 + salt);
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<Point> out(n);
    for (size_t k = 0; k < n; ++k) {
        size_t kind = k % 5, pick = k * 7919 + salt * 104729;
        if (kind <= 1 && !seen.empty())
            out[k] = seen[pick % seen.size()];
        else if (kind == 2 && !w.surface.empty())
            out[k] = w.surface[pick % w.surface.size()];
        else if (kind == 3 && !through.empty())
            out[k] = through[(k / 5) % through.size()];
        else if (k % 10 == 4 && !flat.empty())
            out[k] = flat[pick % flat.size()];
        else
            for (int j = 0; j < 3; ++j) {
                double margin =
                    0.1 * (w.hi[j] - w.lo[j]) + (k % 2 ? 0.05 * size : 0.0);  // flat scenes: off their plane too
                out[k][j] = w.lo[j] - margin + (w.hi[j] - w.lo[j] + 2 * margin) * u(rng);
            }
    }
    return out;
}

// Runs f(begin, end) over [0, n) on `threads` threads, in contiguous ranges.
template <class F>
void parallel(size_t n, unsigned threads, F&& f) {
    if (threads <= 1 || n < 1000) return f(size_t(0), n);
    std::vector<std::thread> pool;
    for (unsigned t = 0; t < threads; ++t) pool.emplace_back(f, n * t / threads, n * (t + 1) / threads);
    for (std::thread& t : pool) t.join();
}

// Every point against one light in one mode: the runtime's trees (each Traversal) and reference walk, and
// the oracle.
std::vector<Answer> answer_all(const cb::AssetView& v, const SceneOracle& oracle, const Light& light, bool one_sided,
                               const std::vector<Point>& points, unsigned threads, size_t brute_every) {
    using cb::Traversal;
    std::vector<cb::InstanceShadow> scan(v.instance_count), two(v.instance_count), one(v.instance_count),
        metric(v.instance_count), metric2(v.instance_count);
    const double bias = cb::test::asset_bias(v);
    for (uint32_t i = 0; i < v.instance_count; ++i) {
        const double* at = light.at.data();
        scan[i].build(v, i, at, {.traversal = Traversal::scan, .one_sided = one_sided, .bias = bias});
        two[i].build(v, i, at, {.traversal = Traversal::top_two, .one_sided = one_sided, .bias = bias});
        one[i].build(v, i, at, {.traversal = Traversal::top_one, .one_sided = one_sided, .bias = bias});
        metric[i].build(v, i, at, {.traversal = Traversal::mtsv_one, .one_sided = one_sided, .bias = bias});
        metric2[i].build(v, i, at, {.traversal = Traversal::mtsv_two, .one_sided = one_sided, .bias = bias});
    }
    std::vector<Answer> answers(points.size());
    parallel(points.size(), threads, [&](size_t begin, size_t end) {
        // Batches: the tiled walks over this thread's slice of the points, as callers use them.
        size_t n = end - begin;
        std::vector<uint32_t> scratch(std::max(
            {cb::batch_scratch_size(scan.data(), scan.size(), n), cb::batch_scratch_size(two.data(), two.size(), n),
             cb::batch_scratch_size(one.data(), one.size(), n), cb::batch_scratch_size(metric.data(), metric.size(), n),
             cb::batch_scratch_size(metric2.data(), metric2.size(), n)}));
        std::vector<uint8_t> ts(n), t2(n), t1(n), tm(n), tm2(n);
        cb::occluded_batch(metric.data(), metric.size(), points[begin].data(), n, tm.data(), scratch.data());
        cb::occluded_batch(metric2.data(), metric2.size(), points[begin].data(), n, tm2.data(), scratch.data());
        cb::occluded_batch(scan.data(), scan.size(), points[begin].data(), n, ts.data(), scratch.data());
        cb::occluded_batch(two.data(), two.size(), points[begin].data(), n, t2.data(), scratch.data());
        cb::occluded_batch(one.data(), one.size(), points[begin].data(), n, t1.data(), scratch.data());
        for (size_t k = begin; k < end; ++k) {
            const double* p = points[k].data();
            answers[k].scan = ts[k - begin];
            answers[k].tree2 = t2[k - begin];
            answers[k].tree1 = t1[k - begin];
            answers[k].metric = tm[k - begin];
            answers[k].metric2 = tm2[k - begin];
            for (const cb::InstanceShadow& tree : metric)
                answers[k].metric_walk = answers[k].metric_walk || tree.occluded(p, scratch.data());
            for (const cb::InstanceShadow& tree : scan)
                answers[k].walk = answers[k].walk || tree.occluded(p, scratch.data());
            for (const cb::InstanceShadow& tree : two)
                answers[k].walk2 = answers[k].walk2 || tree.occluded(p, scratch.data());
            answers[k].reference = cb::occluded_reference(v, p, light.at.data(), bias, one_sided);
            answers[k].exact = oracle.occluded(p, light.at.data(), one_sided);
            if (brute_every && k % brute_every == 0) {
                cb::test::OracleAnswer b = oracle.occluded_brute_force(p, light.at.data(), one_sided);
                answers[k].brute_checked = true;
                answers[k].brute_agrees = b.blocked == answers[k].exact.blocked &&
                    b.touching == answers[k].exact.touching && b.only_touching == answers[k].exact.only_touching;
            }
        }
    });
    return answers;
}

void report(const std::string& scene, const Light& light, bool one_sided, const Point& p, const Answer& a) {
    std::printf(
        "DISAGREEMENT %s: light %s (%.17g, %.17g, %.17g), %s, point (%.17g, %.17g, %.17g): oracle %d (touching %d), "
        "scan %d, fine trees %d, one tree %d, scan walk %d, fine trees walk %d, reference %d\n",
        scene.c_str(), light.kind, light.at[0], light.at[1], light.at[2], one_sided ? "one-sided" : "two-sided", p[0],
        p[1], p[2], a.exact.blocked, a.exact.touching, a.scan, a.tree2, a.tree1, a.walk, a.walk2, a.reference);
    std::printf("  metric tree %d, two levels %d, walk %d\n", a.metric, a.metric2, a.metric_walk);
}

Tally tally(const std::vector<Answer>& answers, const std::vector<Point>& points, const std::string& scene,
            const Light& light, bool one_sided, size_t& reported) {
    Tally t;
    for (size_t k = 0; k < answers.size(); ++k) {
        const Answer& a = answers[k];
        bool exact = a.exact.blocked;
        t.queries++;
        t.shadowed += exact;
        t.touching += a.exact.touching;
        t.only_touching += a.exact.only_touching;
        t.bad_scan += a.scan != exact;
        t.bad_tree2 += a.tree2 != exact;
        t.bad_tree1 += a.tree1 != exact;
        t.bad_walk += a.walk != exact;
        t.bad_walk2 += a.walk2 != exact;
        t.bad_reference += a.reference != exact;
        const bool metric_wrong = a.metric != exact || a.metric2 != exact || a.metric_walk != exact;
        t.bad_metric += metric_wrong;
        bool wrong = metric_wrong || a.scan != exact || a.tree2 != exact || a.tree1 != exact || a.walk != exact ||
            a.walk2 != exact || a.reference != exact;
        t.missed_shadow += exact &&
            !(a.scan && a.tree2 && a.tree1 && a.walk && a.walk2 && a.reference && a.metric && a.metric2 &&
              a.metric_walk);
        t.bad_touching += a.exact.touching && wrong;
        t.brute_checked += a.brute_checked;
        t.brute_bad += !a.brute_agrees;
        if (!a.brute_agrees)
            std::printf("ORACLE TREES MISSED A TRIANGLE %s: light %s, %s, point (%.17g, %.17g, %.17g)\n", scene.c_str(),
                        light.kind, one_sided ? "one-sided" : "two-sided", points[k][0], points[k][1], points[k][2]);
        if (wrong && reported++ < max_reports) report(scene, light, one_sided, points[k], a);
    }
    return t;
}

// One scene: bake, the oracle, the lights and points, every light in both modes.
Tally check_scene(const std::string& name, const cb::Scene& scene, size_t budget, const Options& o, std::string& note) {
    cb::test::Baked b = cb::test::bake_scene(scene, {}, cb::bounds_all);  // the metric trees read the fitted volumes
    if (b.view.mesh_count == 0 && !scene.meshes.empty()) {
        note += " bake-failed";
        return {};
    }
    SceneOracle oracle(scene, cb::test::asset_bias(b.view));
    WorldSample w = cb::test::sample_scene(scene, 1);
    double size = w.size() > 0 ? w.size() : 1.0;
    cb::test::PlaneLight plane;
    std::vector<Light> lights = scene_lights(scene, w, size, plane, note);
    size_t per_variant = (budget + 2 * lights.size() - 1) / (2 * lights.size());
    int grid = std::clamp(int(std::sqrt(double(budget) / 3)), 16, 300);
    std::vector<Point> seen = camera_points(oracle, w, grid), flat = in_plane_points(scene, plane);
    Tally t;
    size_t reported = 0;
    for (uint32_t l = 0; l < lights.size(); ++l) {
        std::vector<Point> through = cb::test::through_points(scene, lights[l].at.data(), per_variant / 5 + 1, l);
        bool on_plane = std::string(lights[l].kind) == "plane";
        std::vector<Point> points =
            light_points(per_variant, l, seen, w, size, through, on_plane ? flat : std::vector<Point>{});
        for (bool one_sided : {false, true}) {
            std::vector<Answer> answers =
                answer_all(b.view, oracle, lights[l], one_sided, points, o.threads, o.brute_every);
            Tally v = tally(answers, points, name, lights[l], one_sided, reported);
            if (v.bad())
                std::printf(
                    "disagreements %s: light %s, %s: scan %zu, tree2 %zu, tree1 %zu, walk %zu, walk2 %zu, reference "
                    "%zu, metric trees %zu of %zu "
                    "queries; %zu said lit in shadow, %zu touching\n",
                    name.c_str(), lights[l].kind, one_sided ? "one-sided" : "two-sided", v.bad_scan, v.bad_tree2,
                    v.bad_tree1, v.bad_walk, v.bad_walk2, v.bad_reference, v.bad_metric, v.queries, v.missed_shadow,
                    v.bad_touching);
            t.add(v);
        }
    }
    if (seen.empty()) note += " no-camera-hits";
    return t;
}

size_t triangles_in_scene(const cb::Scene& s) {
    size_t n = 0;
    for (const cb::Instance& i : s.instances) n += s.meshes[i.mesh].triangle_count();
    return n;
}

void print_row(const std::string& name, size_t triangles, const Tally& t, double seconds, const std::string& note) {
    std::printf("%-58s %9zu %9zu %9zu %9zu %7zu %6zu %6zu %6zu %6zu %6zu %6zu %6zu %8.1f %s\n", name.c_str(), triangles,
                t.queries, t.shadowed, t.touching, t.only_touching, t.bad_scan, t.bad_tree2, t.bad_tree1, t.bad_walk,
                t.bad_walk2, t.bad_reference, t.bad_metric, seconds, note.c_str());
    std::fflush(stdout);
}

bool parse(int argc, char** argv, Options& o) {
    for (int i = 1; i < argc; ++i) {
        std::string a = argv[i];
        if (a == "--queries" && i + 1 < argc)
            o.queries = std::stoul(argv[++i]);
        else if (a == "--threads" && i + 1 < argc)
            o.threads = unsigned(std::stoul(argv[++i]));
        else if (a == "--brute-force-every" && i + 1 < argc)
            o.brute_every = std::stoul(argv[++i]);
        else if (a.rfind("--", 0) == 0)
            return false;
        else
            o.files.push_back(a);
    }
    if (o.threads == 0) o.threads = std::max(1u, std::thread::hardware_concurrency());
    return true;
}

// A file's name in the table: relative to the shared data folder when it is there.
std::string display_name(const std::string& file) {
    std::error_code e;
    fs::path rel = fs::relative(file, CB_SHARED_DATA, e);
    return e || rel.empty() || *rel.begin() == ".." ? fs::path(file).filename().string() : rel.string();
}

}  // namespace

int main(int argc, char** argv) {
    Options o;
    if (!parse(argc, argv, o)) {
        std::fprintf(stderr, "usage: check_shadow [--queries N] [--threads T] [--brute-force-every K] [FILE...]\n");
        return 2;
    }
    if (o.files.empty()) o.files = scene_files(CB_SHARED_DATA);
    // Load everything first: the budget is spread over the scenes that load.
    std::vector<std::pair<std::string, cb::Scene>> scenes;
    for (const std::string& f : o.files) {
        try {
            scenes.emplace_back(display_name(f), cb::load_scene(f));
        } catch (const std::exception& e) {
            std::string why = e.what();  // starts with the path as given: print the short name instead
            if (why.rfind(f, 0) == 0) why = display_name(f) + why.substr(f.size());
            std::printf("skipped: %s\n", why.c_str());
        }
    }
    if (scenes.empty()) {
        std::printf("no scene loaded\n");
        return 2;
    }
    size_t budget = (o.queries + scenes.size() - 1) / scenes.size();
    std::printf("%zu scenes, %zu queries each (lights x both modes), %u threads\n", scenes.size(), budget, o.threads);
    std::printf("%-58s %9s %9s %9s %9s %7s %6s %6s %6s %6s %6s %6s %6s %8s\n", "scene", "triangles", "queries",
                "in shadow", "touching", "t-only", "scan", "tree2", "tree1", "walk", "walk2", "ref", "mtsv", "seconds");
    Tally total;
    size_t total_triangles = 0;
    auto start = std::chrono::steady_clock::now();
    for (auto& [name, scene] : scenes) {
        auto t0 = std::chrono::steady_clock::now();
        std::string note;
        Tally t = check_scene(name, scene, budget, o, note);
        double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        print_row(name, triangles_in_scene(scene), t, s, note);
        total.add(t);
        total_triangles += triangles_in_scene(scene);
        scene = cb::Scene{};  // free as we go
    }
    double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    print_row("total", total_triangles, total, s, "");
    std::printf(
        "columns: in shadow, touching (the segment touches a triangle: edge, vertex or an end on its plane) and t-only "
        "(in shadow through touching contacts only) per the exact oracle; scan, tree2, tree1, walk, walk2, ref: "
        "disagreements "
        "with it of the tiled batches with fine scans (the default), fine trees and one tree, of walks point by point "
        "with fine "
        "scans and with fine trees, and of the reference walk; mtsv: queries where a metric tree (its batch of one "
        "and of two levels, or its walk) disagrees\n");
    std::printf("queries the oracle calls touching: %zu of %zu; disagreements among them: %zu\n", total.touching,
                total.queries, total.bad_touching);
    if (o.brute_every)
        std::printf("the oracle's trees against all triangles on every %zu-th query: %zu checked, %zu disagreements\n",
                    o.brute_every, total.brute_checked, total.brute_bad);
    return total.bad() ? 1 : 0;
}
