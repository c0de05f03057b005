// Bake benchmark: the whole `clusterbake bake` (load, cluster, bounds auto, write) of one large binary PLY
// made of copies of the shared dragon side by side, at several sizes and thread counts: each stage's time,
// the process's peak memory, and whether the asset bytes depend on the thread count; beside
// meshoptimizer's buildMeshlets + computeMeshletBounds (one thread, its API) on the same mesh.
//
//   bench_bake [--data DIR] [--tool PATH] [--millions 1,10,30] [--threads 1,2] [--runs 3] [--keep DIR]
//
// The bake runs as its own process, as a user runs it, and reports its own peak resident memory (`--json`'s
// peak_resident_bytes; a spawned child's ru_maxrss would count this process's memory before the exec).
// --keep DIR keeps the generated PLY files there (and reuses them on the next run).
// Prints tables; asserts nothing. Times are medians of --runs rounds, each round running every thread count
// in turn; "vs 1 thread" is the median of the rounds' ratios to the first thread count.
#include <meshoptimizer.h>
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_common.h"
#include "load.h"

extern char** environ;

namespace fs = std::filesystem;

namespace {

struct Options {
    fs::path data = fs::path(CB_SHARED_DATA);
    std::string tool = CB_TOOL_PATH;
    std::vector<double> millions = {1, 10};
    std::vector<unsigned> threads = {1, 2};
    int runs = 3;
    fs::path keep;
};

template <class T>
std::vector<T> parse_list(const std::string& s) {
    std::vector<T> out;
    std::stringstream in(s);
    for (std::string item; std::getline(in, item, ',');) out.push_back(T(std::stod(item)));
    if (out.empty()) throw std::runtime_error("empty list '" + s + "'");
    return out;
}

Options parse(int argc, char** argv) {
    Options o;
    for (int i = 1; i < argc; ++i) {
        std::string a = argv[i];
        if (i + 1 >= argc) throw std::runtime_error("option " + a + " needs a value");
        std::string v = argv[++i];
        if (a == "--data")
            o.data = v;
        else if (a == "--tool")
            o.tool = v;
        else if (a == "--millions")
            o.millions = parse_list<double>(v);
        else if (a == "--threads")
            o.threads = parse_list<unsigned>(v);
        else if (a == "--runs")
            o.runs = std::max(1, std::stoi(v));
        else if (a == "--keep")
            o.keep = v;
        else
            throw std::runtime_error("unknown option " + a);
    }
    cb::bench::require_data(o.data);
    return o;
}

// A binary little-endian PLY of the mesh: float xyz, faces as uchar count + int indices.
void write_ply(const cb::Mesh& m, const fs::path& path) {
    fs::path partial = path.string() + ".partial";
    std::ofstream out(partial, std::ios::binary);
    out << "ply\nformat binary_little_endian 1.0\nelement vertex " << m.vertex_count()
        << "\nproperty float x\nproperty float y\nproperty float z\nelement face " << m.triangle_count()
        << "\nproperty list uchar int vertex_indices\nend_header\n";
    out.write(reinterpret_cast<const char*>(m.positions.data()), std::streamsize(m.positions.size() * sizeof(float)));
    std::vector<char> faces(m.triangle_count() * 13);
    for (size_t t = 0; t < m.triangle_count(); ++t) {
        faces[t * 13] = 3;
        std::memcpy(&faces[t * 13 + 1], &m.indices[t * 3], 12);
    }
    out.write(faces.data(), std::streamsize(faces.size()));
    if (!out.flush()) throw std::runtime_error("cannot write " + partial.string());
    out.close();
    fs::rename(partial, path);
}

struct Run {
    double wall = 0, load = 0, cluster = 0, fit = 0, write = 0;
    double peak_mb = 0;
    std::string asset_bytes;  // the output, to compare thread counts
};

double json_number(const std::string& text, const char* key) {
    std::string k = std::string("\"") + key + "\": ";
    size_t at = text.find(k);
    if (at == std::string::npos) throw std::runtime_error(std::string("bake printed no ") + key);
    return std::strtod(text.c_str() + at + k.size(), nullptr);
}

std::string read_all(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

// `clusterbake bake PLY -o OUT --threads T --json -q` as a child process.
Run bake(const Options& o, const fs::path& ply, const fs::path& dir, unsigned threads) {
    fs::path out = dir / "bench.cbk", json = dir / "bench.json";
    // A budget past the default's 4 GB, as a user baking 30 M triangles or more gives one (docs/SECURITY.md).
    std::vector<std::string> args = {
        o.tool, "bake",    ply.string(),      "-o",  out.string(), "--threads", std::to_string(threads), "--json",
        "-q",   "--force", "--memory-budget", "64GB"};
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t files;
    posix_spawn_file_actions_init(&files);
    posix_spawn_file_actions_addopen(&files, 1, json.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    auto start = std::chrono::steady_clock::now();
    pid_t pid = 0;
    if (posix_spawn(&pid, o.tool.c_str(), &files, nullptr, argv.data(), environ) != 0)
        throw std::runtime_error("cannot run " + o.tool);
    posix_spawn_file_actions_destroy(&files);
    int status = 0;
    waitpid(pid, &status, 0);
    Run r;
    r.wall = cb::seconds_since(start);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) throw std::runtime_error("bake of " + ply.string() + " failed");
    std::string text = read_all(json);
    r.load = json_number(text, "load_seconds");
    r.cluster = json_number(text, "cluster_seconds");
    r.fit = json_number(text, "fit_seconds");
    r.write = json_number(text, "write_seconds");
    r.peak_mb = json_number(text, "peak_resident_bytes") / (1024.0 * 1024.0);
    r.asset_bytes = read_all(out);
    return r;
}

Run median_run(std::vector<Run> runs) {
    Run m;
    auto med = [&](double Run::*f) {
        std::vector<double> v;
        for (const Run& r : runs) v.push_back(r.*f);
        return cb::median(v);
    };
    m.wall = med(&Run::wall);
    m.load = med(&Run::load);
    m.cluster = med(&Run::cluster);
    m.fit = med(&Run::fit);
    m.write = med(&Run::write);
    m.peak_mb = med(&Run::peak_mb);
    m.asset_bytes = runs[0].asset_bytes;
    return m;
}

// meshoptimizer's nearest equivalent of a bake on one thread: meshlets of at most 16 triangles and 48
// vertices (our fine size), then a bounding sphere and normal cone for each.
double meshopt_seconds(const cb::Mesh& m, int runs) {
    const size_t max_v = 48, max_t = 16;
    size_t bound = meshopt_buildMeshletsBound(m.indices.size(), max_v, max_t);
    std::vector<meshopt_Meshlet> meshlets(bound);
    std::vector<unsigned> mv(bound * max_v);
    std::vector<unsigned char> mt(bound * max_t * 3);
    return cb::bench::median_seconds(runs, [&] {
        size_t count = meshopt_buildMeshlets(meshlets.data(), mv.data(), mt.data(), m.indices.data(), m.indices.size(),
                                             m.positions.data(), m.vertex_count(), 12, max_v, max_t, 0.0f);
        float checksum = 0;
        for (size_t i = 0; i < count; ++i) {
            const meshopt_Meshlet& ml = meshlets[i];
            meshopt_Bounds b =
                meshopt_computeMeshletBounds(&mv[ml.vertex_offset], &mt[ml.triangle_offset], ml.triangle_count,
                                             m.positions.data(), m.vertex_count(), 12);
            checksum += b.radius;
        }
        if (!(checksum >= 0)) std::fprintf(stderr, "meshopt: odd bounds\n");
    });
}

int run(int argc, char** argv) {
    Options o = parse(argc, argv);
    fs::path base_file = o.data / "scanned/dragon_vrip_res2_binary.ply";
    cb::Scene base_scene = cb::load_scene(base_file.string());
    const cb::Mesh& base = base_scene.meshes.at(0);
    fs::path dir = o.keep.empty() ? fs::temp_directory_path() / ("bench_bake." + std::to_string(getpid())) : o.keep;
    fs::create_directories(dir);

    std::printf(
        "clusterbake bake (load, k-means, bounds auto, write) of N copies of %s (%zu triangles), "
        "median of %d rounds alternating the thread counts; peak = the bake process's peak resident memory\n\n",
        base_file.filename().string().c_str(), base.triangle_count(), o.runs);
    std::printf(
        "| triangles | threads | load s | cluster s | bounds s | write s | wall s | M tri/s | peak MB | "
        "B/tri | vs 1 thread | same bytes | meshopt M tri/s (1 thread) |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    struct Scaling {
        double triangles, seconds;
        unsigned threads;
    };
    std::vector<Scaling> scaling;
    for (double millions : o.millions) {
        int copies = std::max(1, int(std::ceil(millions * 1e6 / double(base.triangle_count()))));
        cb::Mesh mesh = cb::bench::merged_copies(base, copies);
        fs::path ply = dir / ("dragons_" + std::to_string(copies) + ".ply");
        if (!fs::exists(ply)) write_ply(mesh, ply);
        double meshopt = meshopt_seconds(mesh, o.runs);
        double tris = double(mesh.triangle_count());
        mesh = cb::Mesh{};  // the bake process gets the memory
        // Rounds alternate the thread counts, so that a slow spell of this shared machine falls on all of them;
        // the ratio to the first count is the median of the rounds' own ratios.
        std::vector<std::vector<Run>> runs(o.threads.size());
        for (int r = 0; r < o.runs; ++r)
            for (size_t t = 0; t < o.threads.size(); ++t) runs[t].push_back(bake(o, ply, dir, o.threads[t]));
        const std::string reference = runs[0][0].asset_bytes;
        for (size_t t = 0; t < o.threads.size(); ++t) {
            Run m = median_run(runs[t]);
            bool same = true;
            std::vector<double> ratios;
            for (int r = 0; r < o.runs; ++r) {
                same = same && runs[t][size_t(r)].asset_bytes == reference;
                ratios.push_back(runs[0][size_t(r)].wall / runs[t][size_t(r)].wall);
            }
            const double ratio = cb::median(ratios);
            std::printf("| %.0f | %u | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %.0f | %.0f | %.2f | %s | %.2f |\n",
                        tris, o.threads[t], m.load, m.cluster, m.fit, m.write, m.wall, tris / m.wall / 1e6, m.peak_mb,
                        m.peak_mb * 1024 * 1024 / tris, ratio, same ? "yes" : "NO", tris / meshopt / 1e6);
            std::fflush(stdout);
            scaling.push_back({tris, m.wall, o.threads[t]});
        }
        if (o.keep.empty()) fs::remove(ply);
    }
    std::printf("\nGrowth: wall seconds per million triangles, and its ratio to the smallest size's\n\n");
    for (unsigned t : o.threads) {
        std::printf("%u thread%s:", t, t == 1 ? "" : "s");
        double first = 0;
        for (const Scaling& s : scaling) {
            if (s.threads != t) continue;
            double per = s.seconds / (s.triangles / 1e6);
            if (first == 0) first = per;
            std::printf("  %.1f M: %.3f s/M (x%.2f)", s.triangles / 1e6, per, per / first);
        }
        std::printf("\n");
    }
    if (o.keep.empty()) fs::remove_all(dir);
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    return cb::bench::guarded_main("bench_bake", [&] { return run(argc, argv); });
}
