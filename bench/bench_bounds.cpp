// Bounds benchmark: microseconds per cluster and tightness of each fitting method on the fine clusters of
// the scanned meshes, against CGAL's optimal box, Ritter's sphere and meshopt_computeMeshletBounds, and the
// containment misses of float spheres far from the origin.
//
//   bench_bounds [--data DIR] [--fine 16] [--runs 3] [--only NAME]
#include <meshoptimizer.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "bench_common.h"
#include "bounds.h"
#include "cluster.h"
#include "load.h"

namespace fs = std::filesystem;

namespace {

struct Cluster {
    std::vector<double> local;  // distinct vertices around `origin`
    double origin[3];
    std::vector<uint32_t> tris;      // triangle ids
    std::vector<uint32_t> vertices;  // distinct vertex ids (meshlet vertex list)
    std::vector<uint8_t> local_tris;
};

template <class F>
double median_us_per(size_t items, int runs, F&& f) {
    return cb::bench::median_seconds(runs, f) * 1e6 / double(items);
}

std::vector<Cluster> make_clusters(const cb::Mesh& m, uint32_t fine) {
    cb::ClusterOptions o;
    o.fine_size = fine;
    cb::Hierarchy h =
        cb::build_hierarchy(m.positions.data(), m.vertex_count(), m.indices.data(), m.triangle_count(), o);
    std::vector<Cluster> out(h.fine_count());
    for (size_t f = 0; f < h.fine_count(); ++f) {
        Cluster& c = out[f];
        c.tris.assign(h.order.begin() + h.fine_offsets[f], h.order.begin() + h.fine_offsets[f + 1]);
        for (uint32_t t : c.tris)
            for (int k = 0; k < 3; ++k) c.vertices.push_back(m.indices[size_t(t) * 3 + k]);
        std::vector<uint32_t> corner = c.vertices;
        std::sort(c.vertices.begin(), c.vertices.end());
        c.vertices.erase(std::unique(c.vertices.begin(), c.vertices.end()), c.vertices.end());
        for (uint32_t v : corner)
            c.local_tris.push_back(
                uint8_t(std::lower_bound(c.vertices.begin(), c.vertices.end(), v) - c.vertices.begin()));
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (uint32_t v : c.vertices)
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], double(m.positions[v * 3 + k]));
                hi[k] = std::max(hi[k], double(m.positions[v * 3 + k]));
            }
        for (int k = 0; k < 3; ++k) c.origin[k] = 0.5 * (lo[k] + hi[k]);
        for (uint32_t v : c.vertices)
            for (int k = 0; k < 3; ++k) c.local.push_back(m.positions[v * 3 + k] - c.origin[k]);
    }
    return out;
}

struct Ratio {
    std::vector<double> all;
    double sum = 0, worst = 0;
    void add(double r) {
        if (!std::isfinite(r)) return;
        sum += r;
        worst = std::max(worst, r);
        all.push_back(r);
    }
    double mean() const { return all.empty() ? NAN : sum / double(all.size()); }
    double median() const {  // flat clusters make volume ratios heavy-tailed: the median says more
        return all.empty() ? NAN : cb::median(all);
    }
};

void run(const std::string& name, const cb::Mesh& m, uint32_t fine, int runs) {
    std::vector<Cluster> clusters = make_clusters(m, fine);
    size_t n = clusters.size();
    std::vector<cb::Obb> pca(n), area(n), refined(n), optimal(n, cb::Obb{});
    std::vector<cb::Sphere> exact(n), ritter(n);
    std::vector<cb::ClusterBounds> full(n);

    auto obb_time = [&](cb::ObbMethod method, std::vector<cb::Obb>& out) {
        return median_us_per(n, runs, [&] {
            for (size_t i = 0; i < n; ++i)
                out[i] =
                    cb::fit_obb(clusters[i].local.data(), clusters[i].vertices.size(), clusters[i].origin, method,
                                m.positions.data(), m.indices.data(), clusters[i].tris.data(), clusters[i].tris.size());
        });
    };
    double t_pca = obb_time(cb::ObbMethod::pca, pca);
    double t_area = obb_time(cb::ObbMethod::pca_area, area);
    double t_refined = obb_time(cb::ObbMethod::refined, refined);
    // CGAL's optimum takes milliseconds a cluster: time and compare on an evenly spaced sample of 400.
    size_t stride = std::max<size_t>(1, n / 400), sampled = 0;
    double t_cgal = median_us_per((n + stride - 1) / stride, 1, [&] {
        for (size_t i = 0; i < n; i += stride, ++sampled)
            optimal[i] = cb::fit_obb(clusters[i].local.data(), clusters[i].vertices.size(), clusters[i].origin,
                                     cb::ObbMethod::cgal_optimal);
    });
    double t_exact = median_us_per(n, runs, [&] {
        for (size_t i = 0; i < n; ++i)
            exact[i] = cb::fit_sphere(clusters[i].local.data(), clusters[i].vertices.size(), clusters[i].origin);
    });
    double t_ritter = median_us_per(n, runs, [&] {
        for (size_t i = 0; i < n; ++i)
            ritter[i] = cb::ritter_sphere(clusters[i].local.data(), clusters[i].vertices.size(), clusters[i].origin);
    });
    cb::BoundsOptions all;
    double t_all = median_us_per(n, runs, [&] {
        for (size_t i = 0; i < n; ++i)
            full[i] = cb::fit_bounds(m.positions.data(), m.indices.data(), clusters[i].tris.data(),
                                     clusters[i].tris.size(), all);
    });
    std::vector<meshopt_Bounds> mb(n);
    double t_meshopt = median_us_per(n, runs, [&] {
        for (size_t i = 0; i < n; ++i)
            mb[i] = meshopt_computeMeshletBounds(clusters[i].vertices.data(), clusters[i].local_tris.data(),
                                                 clusters[i].tris.size(), m.positions.data(), m.vertex_count(), 12);
    });

    Ratio r_pca, r_area, r_refined, r_ritter, r_meshopt_sphere, r_capsule, r_sphere_obb, angle;
    size_t capsules = 0, cones = 0, meshopt_cones = 0;
    for (size_t i = 0; i < n; ++i) {
        double best = i % stride == 0 ? cb::obb_volume(optimal[i]) : 0;
        if (best > 0) {
            r_pca.add(cb::obb_volume(pca[i]) / best);
            r_area.add(cb::obb_volume(area[i]) / best);
            r_refined.add(cb::obb_volume(refined[i]) / best);
        }
        if (exact[i].radius > 0) {
            r_ritter.add(double(ritter[i].radius) / exact[i].radius);
            r_meshopt_sphere.add(double(mb[i].radius) / exact[i].radius);
        }
        double box = cb::obb_volume(full[i].obb);
        if (box > 0) {
            double sphere = 4.0 / 3.0 * M_PI * std::pow(double(full[i].sphere.radius), 3);
            r_sphere_obb.add(sphere / box);
            if (full[i].has_capsule) {
                const cb::Capsule& c = full[i].capsule;
                double len = std::sqrt(std::pow(double(c.b[0]) - c.a[0], 2) + std::pow(double(c.b[1]) - c.a[1], 2) +
                                       std::pow(double(c.b[2]) - c.a[2], 2));
                double r = c.radius;
                r_capsule.add((M_PI * r * r * len + 4.0 / 3.0 * M_PI * r * r * r) / box);
            }
        }
        capsules += full[i].has_capsule;
        if (full[i].cone.valid) {
            ++cones;
            angle.add(std::atan2(double(full[i].cone.sin_half_angle), double(full[i].cone.cos_half_angle)) * 180 /
                      M_PI);
        }
        meshopt_cones += mb[i].cone_cutoff < 1.0f;  // meshopt marks "no cone" with cutoff 1
    }
    std::printf("| %-22s | %6zu | %5.2f | %5.2f | %5.2f | %7.1f | %5.3f / %5.2f | %5.3f / %5.2f | %5.3f / %5.2f |\n",
                name.c_str(), n, t_pca, t_area, t_refined, t_cgal, r_pca.mean(), r_pca.worst, r_area.mean(),
                r_area.worst, r_refined.mean(), r_refined.worst);
    std::printf(
        "|   spheres: exact %.2f us, Ritter %.2f us (exact/Ritter time %.2f); Ritter radius / exact %.4f (worst %.3f); "
        "meshopt radius / exact %.4f (worst %.3f)\n",
        t_exact, t_ritter, t_exact / t_ritter, r_ritter.mean(), r_ritter.worst, r_meshopt_sphere.mean(),
        r_meshopt_sphere.worst);
    std::printf(
        "|   all volumes %.2f us/cluster (meshopt_computeMeshletBounds %.2f us); sphere/OBB volume %.2f; "
        "capsules %zu (%.0f%%), capsule/OBB volume %.2f (medians); cones valid %.0f%% (meshopt %.0f%%), mean "
        "half-angle %.1f deg\n",
        t_all, t_meshopt, r_sphere_obb.median(), capsules, 100.0 * double(capsules) / double(n), r_capsule.median(),
        100.0 * double(cones) / double(n), 100.0 * double(meshopt_cones) / double(n), angle.mean());
}

// Vertices outside the float sphere each fitter stores, with the mesh moved 1e6 from the origin.
void far_spheres(const std::string& name, cb::Mesh m, uint32_t fine, double offset) {
    for (float& p : m.positions) p = float(double(p) + offset);
    std::vector<Cluster> clusters = make_clusters(m, fine);
    size_t ours = 0, theirs = 0, vertices = 0;
    double worst_theirs = 0;
    for (const Cluster& c : clusters) {
        cb::Sphere s = cb::fit_sphere(c.local.data(), c.vertices.size(), c.origin);
        meshopt_Bounds b = meshopt_computeMeshletBounds(c.vertices.data(), c.local_tris.data(), c.tris.size(),
                                                        m.positions.data(), m.vertex_count(), 12);
        for (uint32_t v : c.vertices) {
            const float* p = &m.positions[v * 3];
            double d_ours =
                std::sqrt(std::pow(p[0] - double(s.center[0]), 2) + std::pow(p[1] - double(s.center[1]), 2) +
                          std::pow(p[2] - double(s.center[2]), 2));
            double d_theirs =
                std::sqrt(std::pow(p[0] - double(b.center[0]), 2) + std::pow(p[1] - double(b.center[1]), 2) +
                          std::pow(p[2] - double(b.center[2]), 2));
            ours += d_ours > s.radius;
            if (d_theirs > b.radius) {
                ++theirs;
                if (b.radius > 0) worst_theirs = std::max(worst_theirs, d_theirs / b.radius - 1);
            }
            ++vertices;
        }
    }
    std::printf(
        "| %-22s | offset %.0e | %zu cluster vertices | outside ours %zu | outside meshopt %zu (worst %.1f%% of its "
        "radius) |\n",
        name.c_str(), offset, vertices, ours, theirs, 100 * worst_theirs);
}

}  // namespace

static int run(int argc, char** argv) {
    cb::bench::Options defaults;
    defaults.runs = 3;
    cb::bench::Options o = cb::bench::parse_options(argc, argv, defaults);
    std::vector<fs::path> files = cb::bench::scanned_meshes(o, "bench_bounds");
    if (files.empty()) return 1;
    uint32_t fine = o.fine;
    int runs = o.runs;
    std::printf(
        "k-means fine clusters of at most %u triangles; times are microseconds per cluster (median of %d); "
        "OBB columns give volume / CGAL optimal volume as mean / worst\n\n",
        fine, runs);
    std::printf(
        "| mesh | clusters | PCA us | PCA-area us | refined us | CGAL us | PCA vol | PCA-area vol | refined vol |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|\n");
    std::vector<std::pair<std::string, cb::Mesh>> meshes;
    for (const fs::path& f : files) {
        cb::Scene s = cb::load_scene(f.string());
        run(f.filename().string(), s.meshes[0], fine, runs);
        meshes.emplace_back(f.filename().string(), s.meshes[0]);
    }
    std::printf("\n");
    for (auto& [name, mesh] : meshes) far_spheres(name, mesh, fine, 1e6);
    return 0;
}

int main(int argc, char** argv) {
    return cb::bench::guarded_main("bench_bounds", [&] { return run(argc, argv); });
}
