// One scene file to one asset file, as `clusterbake bake` and `clusterbake batch` both do it: load, cluster,
// fit, encode with a source section, write atomically. With `if_changed`, an output made from the same
// input bytes, options and build of the tool is kept and the bake skipped.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "bake.h"
#include "bounds.h"
#include "load.h"
#include "cluster.h"
#include "source_files.h"

namespace cb {

// "clusterbake 0.1.2": the tool version written into every source section.
const char* tool_version();

// The build id, 16 lowercase hex digits: a hash of the sources the bake and the command line are compiled
// from (bake/CMakeLists.txt), the same for every build of one source tree. Written into every source
// section, so that an output another build made is not taken as up to date.
const char* build_id();

struct BakeRequest {
    std::string input, output;
    ClusterOptions clustering;
    BoundsOptions bounds = {bounds_auto};  // what `clusterbake bake` fits unless told otherwise
    bool fit = true;                       // false: geometry and hierarchy only (`clusterbake cluster`)
    bool if_changed = false;               // keep an up-to-date output
    LoadOptions load;                      // what the scene is trusted with (external files, memory)
    // Threads that cluster, fit and write, 0 = all hardware threads: the asset is the same for any count.
    unsigned threads = 0;
};

enum class BakeStatus { baked, up_to_date, failed };
const char* status_name(BakeStatus s);  // "baked", "up-to-date", "failed"

struct BakeResult {
    BakeStatus status = BakeStatus::failed;
    std::string error;    // one line naming the file, when failed
    std::string warning;  // naming the file, when baked but worth a look (no triangles, an extension not read)
    uint64_t input_bytes = 0, output_bytes = 0;
    uint64_t triangles = 0, fine_clusters = 0, coarse_clusters = 0;
    uint64_t meshes = 0, instances = 0;
    double load_seconds = 0, write_seconds = 0, seconds = 0;  // seconds: the whole call
    BakeStats stats;                                          // clustering and fitting (baked only)
};

// The options that shape the asset, as a `bake` (or `cluster`) command line: "bake" then options_argv's
// words (bake_options.h): the method, the cluster sizes, the method's own options and, when fitting, the
// bounds options. Not the thread count, which changes nothing in the output, nor another method's options.
std::string options_text(const ClusterOptions& clustering, const BoundsOptions& bounds, bool fit);

// The source section's text (docs/FORMAT.md): the tool and its build id, the options, the input hash and the
// files.
std::string source_text(const SourceFiles& source, const ClusterOptions& clustering, const BoundsOptions& bounds,
                        bool fit);

// What a process baking one file may hold beyond the file's memory budget and its threads' stacks under
// limit_process_memory: the allocator's slack and the libraries' buffers. Every scene of the test data
// bakes with its budget set to bake_file's own estimate for it and no margin at all.
constexpr uint64_t memory_limit_margin = uint64_t(16) << 20;

// Makes the memory budget a hard limit on this process, which is to bake one file on `threads` threads (0:
// every hardware thread): its private writable memory (RLIMIT_DATA: heap, arrays, thread stacks; not the
// program, its libraries or a mapped input file) may grow by the budget, plus memory_limit_margin and a
// thread stack for each thread the bake may start, over what it holds now. A bake that needs more fails
// with one line ("FILE: out of memory: over the memory budget of 4 GiB (--memory-budget)") instead of
// taking the machine's memory. Returns the limit set, or 0 when none is: a lower limit is already in force,
// /proc cannot be read, or a sanitizer build (whose shadow memory is no scene's).
uint64_t limit_process_memory(uint64_t budget, unsigned threads);

// Throws LoadError, naming r.input, when baking `scene` would take more than r.load.memory_budget by
// bake_file's estimate (what the scene holds, and 128 bytes per triangle for the bake): checked before any
// clustering, as bake_file checks it.
void check_bake_memory(const Scene& scene, const BakeRequest& r);

// Checks the request's options first (request_options_error, bake_options.h): broken ones fail before
// any work. Never throws: every failure (bad input, unwritable output, out of memory) comes back as `failed` with
// its line, and leaves whatever was at the output untouched.
BakeResult bake_file(const BakeRequest& request, const BakeProgress& progress = {});

}  // namespace cb
