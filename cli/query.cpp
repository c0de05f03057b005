// clusterbake query: point-light shadow queries on an asset, one 0/1 line per point.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>

#include "args.h"
#include "commands.h"
#include "scene_query.h"

namespace cb::cli {
namespace {

struct QueryArgs {
    std::string asset, light, points, out, fine = "scan";
    bool binary = false, stats = false, reference = false, one_sided = false;
    unsigned threads = 1;
};

// Points from text lines "x y z" (blank lines and # comments skipped) or raw little-endian float32 triples.
bool read_points(const QueryArgs& a, std::vector<double>& pts) {
    std::ifstream in(a.points, std::ios::binary);
    if (!in) {
        std::fprintf(stderr, "%s: cannot open\n", a.points.c_str());
        return false;
    }
    if (a.binary) {
        std::vector<char> raw((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        if (raw.size() % 12 != 0) {
            std::fprintf(stderr, "%s: %zu bytes is not a whole number of float32 triples\n", a.points.c_str(),
                         raw.size());
            return false;
        }
        for (size_t i = 0; i < raw.size(); i += 4) {
            float f;
            std::memcpy(&f, raw.data() + i, 4);
            pts.push_back(f);
        }
    } else {
        std::string line;
        for (size_t n = 1; std::getline(in, line); ++n) {
            size_t hash = line.find('#');
            if (hash != std::string::npos) line.resize(hash);
            if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
            double x, y, z;
            char extra;
            if (std::sscanf(line.c_str(), "%lf %lf %lf %c", &x, &y, &z, &extra) != 3) {
                std::fprintf(stderr, "%s: line %zu: expected 'x y z'\n", a.points.c_str(), n);
                return false;
            }
            pts.insert(pts.end(), {x, y, z});
        }
    }
    for (size_t i = 0; i < pts.size(); ++i)
        if (!std::isfinite(pts[i])) {
            std::fprintf(stderr, "%s: point %zu: coordinate is not finite\n", a.points.c_str(), i / 3);
            return false;
        }
    return true;
}

int run_query(const QueryArgs& a) {
    double light[3];
    if (!parse_light(a.light, light)) return exit_usage;
    cb::LoadedAsset asset;
    if (!load_asset(a.asset, asset)) return exit_bad_input;
    std::vector<double> pts;
    if (!read_points(a, pts)) return exit_bad_input;

    cb::SceneQueryOptions options;
    cb::parse_traversal(a.fine, options.traversal);  // CLI11 checked the name
    options.one_sided = a.one_sided, options.threads = a.threads, options.reference = a.reference;
    size_t n = pts.size() / 3;
    cb::SceneQueryResult q = cb::query_scene(asset.view, light, pts.data(), n, options);
    std::string answers;
    answers.reserve(n * 2);
    size_t shadowed = 0;
    for (uint8_t s : q.shadowed) answers += s ? "1\n" : "0\n", shadowed += s;
    std::fwrite(answers.data(), 1, answers.size(), stdout);
    if (a.stats) {
        if (!a.reference)
            std::fprintf(
                stderr,
                "build %.3f s: %zu trees, %zu nodes, %zu clusters tested for every point (light inside or level "
                "with their box), %zu skipped (one-sided, light in their front cone)\n",
                q.build_seconds, q.trees, q.nodes, q.always_tested, q.skipped);
        std::fprintf(stderr,
                     "%zu queries, %zu in shadow, %.3f s (%.0f queries/s); per query %.1f clusters and %.1f triangles "
                     "tested\n",
                     n, shadowed, q.query_seconds, n / std::max(q.query_seconds, 1e-9),
                     n ? double(q.stats.clusters_tested) / double(n) : 0.0,
                     n ? double(q.stats.triangles_tested) / double(n) : 0.0);
        if (a.reference)
            std::fprintf(stderr, "%llu queries with a touching contact\n", (unsigned long long)q.stats.touching);
    }
    return 0;
}

}  // namespace

Command add_query(CLI::App& app) {
    auto a = std::make_shared<QueryArgs>();
    CLI::App* c = app.add_subcommand("query",
                                     "Answer point-light shadow queries (exact; two-sided occluders unless "
                                     "--one-sided): one 0/1 line per point on stdout");
    c->add_option("asset", a->asset, "Asset (.cbk)")->required();
    c->add_option("--light", a->light, "Light position X,Y,Z in world space")->required();
    c->add_option("--points", a->points, "Points: text lines 'x y z', or float32 triples with --binary")->required();
    c->add_flag("--binary", a->binary, "Points file holds raw little-endian float32 x, y, z triples");
    c->add_flag("--one-sided", a->one_sided,
                "One-sided occluders: a triangle blocks only when the light is behind it "
                "(double-sided glTF primitives stay two-sided)");
    c->add_flag("--stats", a->stats, "Print build and query time and traversal counts on stderr");
    c->add_flag("--reference", a->reference,
                "Use the reference traversal (every cluster box the segment may touch) "
                "instead of the clustered shadow volumes; same answers");
    c->add_option("--threads", a->threads,
                  "Build and query threads, 0 = all (default 1); the answers do not depend on it");
    c->add_option("--fine", a->fine,
                  "How queries find the clusters: 'scan' (default: no per-light tree; the coarse clusters' "
                  "spheres, then the entered ones' fine spheres), 'trees' (per light, a tree over the coarse "
                  "clusters and one per coarse cluster over its fine clusters) or 'one-tree' (one tree over "
                  "the fine clusters); same answers")
        ->check(CLI::IsMember({"scan", "trees", "one-tree"}));
    return {c, [a] { return run_query(*a); }};
}

}  // namespace cb::cli
