#include "args.h"

#include <cmath>
#include <cstdio>

namespace cb::cli {

void add_clustering_flags(CLI::App* c, ClusterArgs& a) {
    c->add_option("--method", a.method, "kmeans (default), vco or morton");
    c->add_option("--coarse", a.options.coarse_size, "Triangles per coarse cluster (default 2048)");
    // 85 triangles have at most 255 distinct corners: every cluster fits the asset's 8-bit local indices.
    c->add_option("--fine", a.options.fine_size, "Maximum triangles per fine cluster, 1 to 85 (default 16)")
        ->check(CLI::Range(1, 85));
    c->add_option("--threads", a.options.threads, "Worker threads, 0 = all (output is identical for any count)");
    c->add_option("--seed", a.options.seed, "Seed of k-means++ (default 1)");
    c->add_option("--k0", a.options.kmeans_branching, "k-means children per node (default 8)");
    c->add_option("--iterations", a.options.kmeans_max_iterations, "Cap on Lloyd iterations per node (default 16)");
    c->add_flag_callback(
        "--coarse-morton", [&a] { a.options.kmeans_coarse_from_tree = false; },
        "kmeans: Morton chunks as the coarse level instead of the top of the k-means trees");
    c->add_option("--presplit", a.options.kmeans_presplit,
                  "kmeans: triangles per Morton chunk the trees grow in, in parallel (default 65536; 0: one tree)");
    c->add_option("--cache", a.options.vco_cache_size, "vco: vertex cache size (default 32)");
}

bool parse_obb(const std::string& text, cb::ObbMethod& out) {
    if (cb::parse_obb_method(text, out)) return true;
    std::fprintf(stderr, "clusterbake: --obb takes refined, pca, pca-area or cgal (got '%s')\n", text.c_str());
    return false;
}

bool parse_clustering(const ClusterArgs& a, cb::ClusterOptions& clustering, cb::BoundsOptions& bounds) {
    clustering = a.options;
    // Ranges no algorithm can work with, refused before any work: one line each.
    auto refuse = [](const char* what) {
        std::fprintf(stderr, "clusterbake: %s\n", what);
        return false;
    };
    if (clustering.coarse_size == 0) return refuse("--coarse must be at least 1");
    if (clustering.coarse_size < clustering.fine_size) return refuse("--coarse must be at least --fine");
    if (clustering.kmeans_branching < 2) return refuse("--k0 must be at least 2 (children per k-means node)");
    if (clustering.vco_cache_size < 3) return refuse("--cache must be at least 3 (a triangle's corners)");
    if (!(a.capsule_ratio >= 1 && std::isfinite(a.capsule_ratio)))
        return refuse("--capsule-ratio must be a finite number of at least 1");
    if (!cb::parse_method(a.method, clustering.method)) {
        std::fprintf(stderr, "clusterbake: unknown method '%s' (kmeans, vco, morton)\n", a.method.c_str());
        return false;
    }
    bounds.capsule_ratio = a.capsule_ratio;
    return parse_obb(a.obb, bounds.obb);
}

bool parse_light(const std::string& text, double* light) {
    char extra;
    if (std::sscanf(text.c_str(), "%lf,%lf,%lf%c", &light[0], &light[1], &light[2], &extra) == 3 &&
        std::isfinite(light[0]) && std::isfinite(light[1]) && std::isfinite(light[2]))
        return true;
    std::fprintf(stderr, "clusterbake: --light takes X,Y,Z (got '%s')\n", text.c_str());
    return false;
}

bool load_asset(const std::string& file, cb::LoadedAsset& out) {
    std::string error;
    if (cb::read_asset_file(file, out, error)) return true;
    std::fprintf(stderr, "%s\n", error.c_str());
    return false;
}

}  // namespace cb::cli
