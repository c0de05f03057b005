// A batch as a command line asks for it: each job's bake request (the batch's options, then its manifest
// line's), the `clusterbake bake` command line that makes the same output, the output tree made before
// any work, the order the jobs start in, and the summary of a run (OUTDIR/summary.json).
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "bake_file.h"
#include "plan.h"
#include "run.h"

namespace cb {

struct BatchOptions {
    BakeRequest bake;                // the batch's own options; input and output are each job's
    std::vector<std::string> given;  // the flags of the bake options given for the whole batch
    bool force = false;              // bake every file, even when its output is up to date
};

// Job's request: the batch's options with its manifest line's over them, checked (bake_options.h): the
// rules, then an option that would change nothing, on the line or for the whole batch. The batch's
// --threads is the cores it shares, so a job runs on all of them unless its line caps it. The one-line
// error naming the job's origin, or empty.
std::string job_request(const BatchOptions& batch, const BatchJob& job, BakeRequest& out);

// The `clusterbake bake` command line (without the program) that makes the same output as the batch
// makes for this request.
std::vector<std::string> bake_argv(const BakeRequest& r, bool force);

// Makes the folder of every job's output: the one-line error of the first that cannot be made, or empty.
std::string make_output_folders(const std::vector<BatchJob>& jobs);

// The jobs' indices, largest input first, so that the longest file does not start last.
std::vector<size_t> largest_first(const std::vector<BatchJob>& jobs);

// Files, triangles and seconds of each status (indexed by BakeStatus).
struct BatchTotals {
    size_t files[3] = {};
    uint64_t triangles[3] = {};
    double seconds[3] = {};
};
BatchTotals batch_totals(const std::vector<BakeResult>& results);

// OUTDIR/summary.json's content: the tool, the run, the counts and one record a file, in
// the jobs' order.
nlohmann::json batch_summary(const std::vector<BatchJob>& jobs, const std::vector<BakeResult>& results,
                             const BatchRun& run, double wall_seconds);

}  // namespace cb
