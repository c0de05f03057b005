#include "bake_file.h"

#include <pthread.h>
#include <sys/resource.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <memory>
#include <new>
#include <sstream>
#include <system_error>
#include <thread>

#include "asset_file.h"
#include "bake_options.h"
#include "free_storage.h"
#include "load.h"
#include "parallel.h"
#include "timing.h"

namespace cb {
namespace {

// The budget limit_process_memory enforces in this process, 0 when none: a failed allocation is then that.
std::atomic<uint64_t> hard_budget{0};

// VmData of /proc/self/status: the process's private writable memory, which RLIMIT_DATA bounds; 0 if unknown.
uint64_t data_bytes() {
    std::ifstream status("/proc/self/status");
    for (std::string line; std::getline(status, line);)
        if (line.compare(0, 7, "VmData:") == 0) return std::strtoull(line.c_str() + 7, nullptr, 10) << 10;
    return 0;
}

// The stack each new thread gets: private writable memory, so counted against RLIMIT_DATA.
uint64_t thread_stack_bytes() {
    pthread_attr_t attr;
    size_t size = 8u << 20;
    if (pthread_getattr_default_np(&attr) == 0) {
        pthread_attr_getstacksize(&attr, &size);
        pthread_attr_destroy(&attr);
    }
    return size;
}

// The file names a source section lists, in order.
std::vector<std::string> source_names(const char* text, size_t size) {
    std::vector<std::string> names;
    std::istringstream lines(std::string(text, size));
    for (std::string line; std::getline(lines, line);)
        if (line.compare(0, 5, "file ") == 0) names.push_back(line.substr(5));
    return names;
}

// True, with the result filled from the stored asset, when `output` holds an asset whose source section is
// the one this request would write: the same build id (line 1), options and input bytes. An asset written
// before source sections carried a build id, or by another build, is baked again.
bool up_to_date(const BakeRequest& r, BakeResult& result) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(r.output, ec)) return false;
    LoadedAsset asset;
    std::string error;
    if (!read_asset_file(r.output, asset, error) || !asset.view.source) return false;
    SourceFiles now;
    std::vector<std::string> names = source_names(asset.view.source, asset.view.source_size);
    if (names.empty() || !hash_source_files(r.input, names, now, error)) return false;
    if (source_text(now, r.clustering, r.bounds, r.fit) != std::string(asset.view.source, asset.view.source_size))
        return false;
    result.status = BakeStatus::up_to_date;
    result.input_bytes = now.bytes;
    result.output_bytes = asset.size;
    result.triangles = asset.view.triangle_count;
    result.fine_clusters = asset.view.fine_count;
    result.coarse_clusters = asset.view.coarse_count;
    result.meshes = asset.view.mesh_count;
    result.instances = asset.view.instance_count;
    return true;
}

// Bytes a bake holds per triangle of the scene's meshes at its peak besides the loaded scene (clustering,
// fitting and encoding side by side; the scene's indices are freed once its mesh is clustered). Measured as
// peak resident bytes less the scene's and the idle process's, on 2 M triangles of dragon copies (1 and 2
// threads): 26-31, and 89-93 when k-means grows one tree over a whole mesh (`--presplit 0`). Meshes with
// more vertices per triangle, or other methods and bounds, hold more: the estimates keep a margin.
uint64_t bake_bytes_per_triangle(const ClusterOptions& c) {
    const bool one_tree =
        c.method == ClusterMethod::kmeans && (c.kmeans_presplit == 0 || c.kmeans_presplit > (uint32_t(1) << 20));
    return one_tree ? 112 : 64;
}

void bake_unguarded(const BakeRequest& r, const BakeProgress& progress, BakeResult& result) {
    auto t0 = std::chrono::steady_clock::now();
    LoadOptions load = r.load;
    load.threads = r.threads;  // a large mesh file's records and checks split across the bake's threads
    Scene scene = load_scene(r.input, load);
    check_bake_memory(scene, r);
    result.load_seconds = seconds_since(t0);
    result.input_bytes = scene.report.source.bytes;
    result.meshes = scene.meshes.size();
    result.instances = scene.instances.size();

    std::vector<AssetMesh> meshes =
        cluster_scene_releasing(scene, r.clustering, result.stats, progress.clustering, r.threads);
    if (r.fit) size_scene_bounds(meshes, r.bounds);  // laid out before they are filled

    // The geometry's encoding (vertex renumbering, serial) and its writing to the file read only what fitting
    // reads and write nothing fitting reads: on a thread of its own beside the fitting when there is a core
    // for it, taken from the batch's budget when there is one. The encoded copy is freed once written.
    const std::string source = source_text(scene.report.source, r.clustering, r.bounds, r.fit);
    std::unique_ptr<AssetWriter> writer;
    std::exception_ptr encode_failed;
    auto encode = [&](bool fitting_done) {
        try {
            std::vector<EncodedMesh> geometry = encode_geometry(meshes);
            // Once fitted, nothing reads the meshes' own copies: freed before the file takes fresh pages, which
            // the system then finds among theirs (0.1 s of the 10 M bake on one thread).
            if (fitting_done)
                for (AssetMesh& m : meshes) {
                    free_storage(m.positions);
                    free_storage(m.triangles);
                }
            writer = std::make_unique<AssetWriter>(r.output, meshes, std::move(geometry), scene.instances, source);
        } catch (...) {
            encode_failed = std::current_exception();
        }
    };
    const unsigned threads = threads_or_all(r.threads);
    CoreBudget* budget = thread_core_budget();
    std::thread encoding;
    // Joined however this scope is left (a fitting that throws, out of memory, must not leave it running),
    // before the writer goes.
    struct Joined {
        std::thread& thread;
        CoreBudget* budget;
        void join() {
            if (!thread.joinable()) return;
            thread.join();
            if (budget) budget->give();
        }
        ~Joined() { join(); }
    } joined{encoding, budget};
    if (r.fit && threads > 1 && (!budget || budget->try_take())) {
        try {
            encoding = std::thread(encode, false);
        } catch (const std::system_error&) {  // no thread to be had: encoded below, on this one
            if (budget) budget->give();
        }
    }
    if (r.fit) fit_scene_bounds(meshes, r.bounds, r.threads, result.stats, progress.bounds);

    auto t1 = std::chrono::steady_clock::now();
    if (encoding.joinable())
        joined.join();
    else
        encode(true);
    if (encode_failed) std::rethrow_exception(encode_failed);
    result.output_bytes = writer->finish(meshes, r.threads);
    result.write_seconds = seconds_since(t1);
    result.triangles = result.stats.triangles;
    result.fine_clusters = result.stats.fine_clusters;
    result.coarse_clusters = result.stats.coarse_clusters;
    result.status = BakeStatus::baked;
    // Kept, as a valid asset, since a pipeline may expect one asset per scene; said, since it is rarely meant.
    if (result.triangles == 0)
        result.warning = r.input + ": no triangles (" + std::to_string(scene.report.skipped_primitives) +
            " point or line primitives skipped): the asset holds no geometry";
    // What the loader could not honour (an optional extension it does not know that could change the
    // geometry), each already naming the file.
    for (const std::string& w : scene.report.warnings) result.warning += (result.warning.empty() ? "" : "; ") + w;
}

// ": over the memory budget of 4 GiB (--memory-budget)" when a hard limit is in force, for a failed
// allocation; empty otherwise.
std::string over_budget_text() {
    const uint64_t budget = hard_budget;
    return budget ? ": over the memory budget of " + byte_size_text(budget) + " (--memory-budget)" : std::string();
}

}  // namespace

void check_bake_memory(const Scene& scene, const BakeRequest& r) {
    uint64_t triangles = 0, held = 0;
    for (const Mesh& m : scene.meshes) {
        triangles += m.triangle_count();
        held += m.positions.size() * sizeof(float) + m.indices.size() * sizeof(uint32_t);
    }
    held += scene.instances.size() * sizeof(Instance);
    const uint64_t need = held + triangles * bake_bytes_per_triangle(r.clustering);
    if (need <= r.load.memory_budget) return;
    throw LoadError(r.input + ": " + std::to_string(triangles) + " triangles need about " + byte_size_text(need) +
                    " to bake, over the memory budget of " + byte_size_text(r.load.memory_budget) +
                    " (--memory-budget)");
}

uint64_t limit_process_memory(uint64_t budget, unsigned threads) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
    return 0;  // the sanitizer's shadow and quarantine are memory of its own, out of any budget
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || __has_feature(memory_sanitizer)
    return 0;
#endif
#endif
    const uint64_t now = data_bytes();
    if (now == 0) return 0;
    // The threads a bake starts besides this one: parallel_for's helpers and the encoder side by side, and
    // one more for the writer that follows them; none on one thread.
    const unsigned count = threads_or_all(threads);
    const uint64_t stacks = count > 1 ? uint64_t(count + 1) * thread_stack_bytes() : 0;
    const uint64_t limit = now + budget + memory_limit_margin + stacks;
    if (limit < budget) return 0;  // wrapped: a budget no machine has, nothing to enforce
    struct rlimit current;
    if (getrlimit(RLIMIT_DATA, &current) != 0) return 0;
    if (current.rlim_cur != RLIM_INFINITY && current.rlim_cur <= limit) return 0;  // a lower limit of the user's
    struct rlimit wanted = current;
    wanted.rlim_cur = rlim_t(limit);
    if (setrlimit(RLIMIT_DATA, &wanted) != 0) return 0;
    hard_budget = budget;
    return limit;
}

const char* tool_version() { return "clusterbake " CB_VERSION; }

const char* status_name(BakeStatus s) {
    switch (s) {
        case BakeStatus::baked: return "baked";
        case BakeStatus::up_to_date: return "up-to-date";
        case BakeStatus::failed: return "failed";
    }
    return "?";
}

std::string options_text(const ClusterOptions& clustering, const BoundsOptions& bounds, bool fit) {
    BakeRequest r;
    r.clustering = clustering;
    r.bounds = bounds;
    r.fit = fit;
    std::string out = fit ? "bake" : "cluster";
    for (const std::string& word : options_argv(r)) out += " " + word;
    return out;
}

std::string source_text(const SourceFiles& source, const ClusterOptions& clustering, const BoundsOptions& bounds,
                        bool fit) {
    std::string out = std::string(tool_version()) + ", asset format " + std::to_string(asset_version) + ", build " +
        build_id() + "\n";
    out += options_text(clustering, bounds, fit) + "\n";
    out += "input xxh3-128 " + source.hash + ", " + std::to_string(source.bytes) + " bytes\n";
    for (const std::string& name : source.names) out += "file " + name + "\n";
    return out;
}

BakeResult bake_file(const BakeRequest& request, const BakeProgress& progress) {
    auto t0 = std::chrono::steady_clock::now();
    BakeResult result;
    const std::string options_error = request_options_error(request);
    if (!options_error.empty()) {  // before any work: nothing read, nothing written
        result.error = request.input + ": " + options_error;
        result.seconds = seconds_since(t0);
        return result;
    }
    try {
        if (!(request.if_changed && up_to_date(request, result))) bake_unguarded(request, progress, result);
    } catch (const LoadOutOfMemory& e) {
        result.error = e.what() + over_budget_text();
    } catch (const LoadError& e) {
        result.error = e.what();  // already "FILE: ELEMENT: PROBLEM"
    } catch (const std::bad_alloc&) {
        result.error = request.input + ": out of memory" + over_budget_text();
    } catch (const std::system_error& e) {  // a thread not started: under a limit, memory ran out
        const bool resources =
            e.code() == std::errc::resource_unavailable_try_again || e.code() == std::errc::not_enough_memory;
        result.error =
            request.input + ": " + (resources && hard_budget ? "out of memory" + over_budget_text() : e.what());
    } catch (const std::exception& e) {
        std::string what = e.what();
        // write_file_atomic names the output; anything else is about the input.
        result.error = what.find(request.output) != std::string::npos ? what : request.input + ": " + what;
    }
    if (!result.error.empty()) {
        std::string error = LoadError::printable(result.error);
        result = BakeResult{};  // nothing of a bake that failed half-way
        result.error = error;
    }
    result.seconds = seconds_since(t0);
    return result;
}

}  // namespace cb
