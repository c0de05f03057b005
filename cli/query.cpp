// clusterbake query: shadow queries of a point light or a sun on an asset, one 0/1 line per point.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>

#include "args.h"
#include "commands.h"
#include "scene_query.h"

namespace cb::cli {
namespace {

struct QueryArgs {
    std::string asset, light, sun, points, traversal = "scan", fine, metric_build = "heuristic";
    double capsule_aspect = 4.0, bias = 0;
    bool binary = false, stats = false, reference = false, one_sided = false, json = false, quiet = false;
    unsigned threads = 0;
};

// How errors name the points' source.
std::string points_name(const std::string& path) { return path == "-" ? "standard input" : path; }

// Raw float32 triples, a block at a time: no copy of the whole input beside the points.
bool read_binary_points(std::istream& in, const std::string& name, std::vector<double>& pts) {
    char block[1 << 16];  // whole floats: a read comes up short only at the end of the input
    size_t bytes = 0;
    while (in) {
        in.read(block, sizeof block);
        const size_t n = size_t(in.gcount());
        bytes += n;
        for (size_t i = 0; i + 4 <= n; i += 4) {
            float f;
            std::memcpy(&f, block + i, 4);
            pts.push_back(f);
        }
    }
    if (bytes % 12 != 0) {
        std::fprintf(stderr, "%s: %zu bytes is not a whole number of float32 triples\n", name.c_str(), bytes);
        return false;
    }
    return true;
}

// Text lines "x y z"; blank lines and # comments skipped.
bool read_text_points(std::istream& in, const std::string& name, std::vector<double>& pts) {
    std::string line;
    for (size_t n = 1; std::getline(in, line); ++n) {
        size_t hash = line.find('#');
        if (hash != std::string::npos) line.resize(hash);
        if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
        double x, y, z;
        char extra;
        if (std::sscanf(line.c_str(), "%lf %lf %lf %c", &x, &y, &z, &extra) != 3) {
            std::fprintf(stderr, "%s: line %zu: expected 'x y z'\n", name.c_str(), n);
            return false;
        }
        pts.insert(pts.end(), {x, y, z});
    }
    return true;
}

// Points from the file, or standard input for "-": text lines or raw little-endian float32 triples.
bool read_points(const QueryArgs& a, std::vector<double>& pts) {
    const std::string name = points_name(a.points);
    std::ifstream file;
    if (a.points != "-") {
        std::error_code ec;
        if (std::filesystem::is_directory(a.points, ec)) {
            std::fprintf(stderr, "%s: is a folder, not a points file\n", name.c_str());
            return false;
        }
        file.open(a.points, std::ios::binary);
        if (!file) {
            std::fprintf(stderr, "%s: cannot open\n", name.c_str());
            return false;
        }
    }
    std::istream& in = a.points == "-" ? std::cin : file;
    if (!(a.binary ? read_binary_points(in, name, pts) : read_text_points(in, name, pts))) return false;
    if (in.bad()) {
        std::fprintf(stderr, "%s: read error\n", name.c_str());
        return false;
    }
    for (size_t i = 0; i < pts.size(); ++i)
        if (!std::isfinite(pts[i])) {
            std::fprintf(stderr, "%s: point %zu: coordinate is not finite\n", name.c_str(), i / 3);
            return false;
        }
    return true;
}

nlohmann::json stats_json(const QueryArgs& a, const cb::SceneQueryResult& q, size_t n) {
    nlohmann::json j = {{"lanes", cb::query_lanes()},
                        {"query_seconds", q.query_seconds},
                        {"queries_per_second", n / std::max(q.query_seconds, 1e-9)},
                        {"clusters_tested", q.stats.clusters_tested},
                        {"triangles_tested", q.stats.triangles_tested}};
    if (a.reference) {
        j["touching"] = q.stats.touching;
    } else {
        j["build_seconds"] = q.build_seconds;
        j["trees"] = q.structures;
        j["nodes"] = q.nodes;
        j["tree_bytes"] = q.structure_bytes;
        j["always_tested"] = q.always_tested;
        j["skipped"] = q.skipped;
    }
    return j;
}

void print_json(const QueryArgs& a, cb::Traversal traversal, const double* light, const cb::SceneQueryResult& q,
                size_t shadowed) {
    size_t n = q.shadowed.size();
    nlohmann::json j = {{"tool", cb::tool_version()},
                        {"asset", a.asset},
                        {a.sun.empty() ? "light" : "sun", {light[0], light[1], light[2]}},
                        {"traversal", a.reference ? "reference" : cb::traversal_name(traversal)},
                        {"one_sided", a.one_sided},
                        {"bias", q.bias},
                        {"points", n},
                        {"shadowed", shadowed},
                        {"answers", q.shadowed}};
    if (a.stats) j["stats"] = stats_json(a, q, n);
    std::cout << j.dump() << "\n";
}

void print_stats(const QueryArgs& a, const cb::SceneQueryResult& q, size_t shadowed) {
    size_t n = q.shadowed.size();
    if (!a.reference)
        std::fprintf(stderr,
                     "build %.3f s: %zu trees, %zu nodes (%.1f KB), %zu clusters tested for every point (light inside "
                     "or level with their volume), %zu skipped (one-sided, light in their front cone)\n",
                     q.build_seconds, q.structures, q.nodes, q.structure_bytes / 1024.0, q.always_tested, q.skipped);
    std::fprintf(stderr,
                 "%zu queries, %zu in shadow, %.3f s on %s lanes (%.0f queries/s); per query %.1f clusters and %.1f "
                 "triangles tested\n",
                 n, shadowed, q.query_seconds, cb::query_lanes(), n / std::max(q.query_seconds, 1e-9),
                 n ? double(q.stats.clusters_tested) / double(n) : 0.0,
                 n ? double(q.stats.triangles_tested) / double(n) : 0.0);
    if (a.reference)
        std::fprintf(stderr, "%llu queries with a touching contact\n", (unsigned long long)q.stats.touching);
}

int run_query(const CLI::App* c, const QueryArgs& a) {
    if (refuse_given(c, {"--fine"},
                     "the fine cluster size is fixed when the asset is baked (--traversal picks how a query finds "
                     "clusters)") ||
        (a.reference && refuse_given(c, {"--traversal"}, "--reference walks every cluster box instead")))
        return exit_usage;
    if (a.light.empty() == a.sun.empty()) {
        std::fprintf(stderr,
                     "clusterbake: query takes one light: --light X,Y,Z (a point) or --sun X,Y,Z (a direction)\n");
        return exit_usage;
    }
    cb::Traversal traversal = cb::Traversal::scan;
    cb::parse_traversal(a.traversal, traversal);  // the option's check read the name (or an older spelling)
    if (traversal != cb::Traversal::mtsv_one && traversal != cb::Traversal::mtsv_two &&
        refuse_given(c, {"--capsule-aspect", "--capsule-ratio", "--mtsv-build"},
                     "they set up the metric trees of --traversal mtsv-one and mtsv-two"))
        return exit_usage;
    if (!(a.bias >= 0 && a.bias < INFINITY)) {  // NaN too
        std::fprintf(stderr, "clusterbake: --bias takes a distance of at least 0 (0: the level's default)\n");
        return exit_usage;
    }
    if (!(a.capsule_aspect >= 1)) {  // NaN too
        std::fprintf(stderr, "clusterbake: %s takes a number of at least 1 (inf: spheres only)\n",
                     first_given(c, {"--capsule-aspect", "--capsule-ratio"}).c_str());
        return exit_usage;
    }
    double light[3];
    if (a.sun.empty() ? !parse_light(a.light, light) : !parse_sun(a.sun, light)) return exit_usage;
    LoadedLevel level;
    if (!load_level(a.asset, level)) return exit_bad_input;
    std::vector<double> pts;
    if (!read_points(a, pts)) return exit_bad_input;

    cb::SceneQueryOptions options;
    options.traversal = traversal;
    cb::parse_metric_build(a.metric_build, options.metric_build);  // CLI11 checked the name
    options.one_sided = a.one_sided;
    options.threads = a.threads;
    options.reference = a.reference;
    options.capsule_aspect = a.capsule_aspect;
    options.bias = a.bias;
    options.sun = !a.sun.empty();
    cb::SceneQueryResult q = cb::query_level(level.level, light, pts.data(), pts.size() / 3, options);
    size_t shadowed = size_t(std::count(q.shadowed.begin(), q.shadowed.end(), uint8_t(1)));
    if (a.json) {
        print_json(a, traversal, light, q, shadowed);
        return 0;
    }
    std::string answers;
    answers.reserve(q.shadowed.size() * 2);
    for (uint8_t s : q.shadowed) answers += s ? "1\n" : "0\n";
    std::fwrite(answers.data(), 1, answers.size(), stdout);
    if (a.stats) print_stats(a, q, shadowed);
    return 0;
}

}  // namespace

Command add_query(CLI::App& app) {
    auto a = std::make_shared<QueryArgs>();
    CLI::App* c =
        app.add_subcommand("query",
                           "Answer shadow queries of a point light or a sun (exact; two-sided occluders unless "
                           "--one-sided): one 0/1 line per point on stdout");
    c->add_option("asset", a->asset, "Asset (.cbk), or a level file placing several (JSON, docs/RUNTIME.md)")
        ->required();
    c->add_option("--light", a->light, "Point light position X,Y,Z in world space (or --sun)");
    c->add_option("--sun", a->sun,
                  "A sun: a light at infinity, X,Y,Z the world direction from the scene toward it (any length); "
                  "each point's ray runs that way (or --light)");
    c->add_option("--points", a->points,
                  "Points: text lines 'x y z', or float32 triples with --binary; - reads standard input")
        ->required();
    c->add_flag("--binary", a->binary, "Points hold raw little-endian float32 x, y, z triples");
    c->add_flag("--one-sided", a->one_sided,
                "One-sided occluders: a triangle blocks only when the light is behind it "
                "(double-sided glTF primitives stay two-sided)");
    c->add_option("--bias", a->bias,
                  "Self-shadowing bias, a world distance: contacts nearer to the point do not count (default 0: "
                  "1/65536 of the largest side of the level's world box)");
    c->add_flag("--stats", a->stats,
                "Print build and query time and traversal counts on stderr (with --json: in the JSON)");
    c->add_flag("--reference", a->reference,
                "Use the reference traversal (every cluster box the segment may touch) "
                "instead of the clustered shadow volumes; same answers");
    c->add_option("--threads", a->threads, threads_help("the answers do not depend on it"));
    c->add_option("--traversal", a->traversal,
                  "How queries find the clusters: 'scan' (default: no per-light tree; the coarse clusters' "
                  "spheres, then the entered ones' fine spheres), 'top-two' (per light, a TOP tree of planes "
                  "over the coarse clusters and one per coarse cluster over its fine clusters), 'top-one' (one "
                  "TOP tree over the fine clusters), 'mtsv-one' (per light, a metric tree over the fine "
                  "clusters' sphere and capsule cones, by angle from the light) or 'mtsv-two' (a metric tree "
                  "over the coarse clusters' cones entering one per coarse cluster); with --sun, the same "
                  "structures across the sun's direction (trees of lines about the boxes' prisms, metric trees "
                  "of the spheres' discs); same answers. The older spellings trees, one-tree and mtsv are read "
                  "as top-two, top-one and mtsv-one")
        ->check(CLI::Validator(
            [](std::string& name) {
                cb::Traversal t;
                return cb::parse_traversal(name, t)
                    ? std::string()
                    : "takes scan, top-two, top-one, mtsv-one or mtsv-two (got '" + name + "')";
            },
            "TRAVERSAL"));
    c->add_option("--capsule-aspect", a->capsule_aspect,
                  "mtsv-one and mtsv-two: a cluster's volume is its capsule when that is at least this many "
                  "times as long as wide, else its sphere (default 4; inf: spheres only; the old spelling "
                  "--capsule-ratio is still accepted)");
    c->add_option("--capsule-ratio", a->capsule_aspect)->group("");  // the old spelling of --capsule-aspect
    c->add_option("--mtsv-build", a->metric_build,
                  "mtsv-one and mtsv-two: 'heuristic' (default: shuffled insertion, split distance halved at "
                  "each near step) or 'reference' (far pivots, median split distances; slower)")
        ->check(CLI::IsMember({"heuristic", "reference"}));
    c->add_option("--fine", a->fine)->group("");  // refused with a pointer to --traversal
    c->add_flag("--json", a->json,
                "Print one JSON object: the answers as an array, the counts, and with --stats the timings");
    c->add_flag("-q,--quiet", a->quiet, "No progress on stderr (query prints none; errors are always printed)");
    return {c, [a, c] { return run_query(c, *a); }};
}

}  // namespace cb::cli
