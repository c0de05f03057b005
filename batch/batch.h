// A batch as a command line asks for it: each job's bake request (the batch's options, then its manifest
// line's), the `clusterbake bake` command line that makes the same output, the output tree made before
// any work, the order the jobs start in, and the summary of a run (OUTDIR/summary.json).
#pragma once

#include <nlohmann/json.hpp>

#include <functional>
#include <iosfwd>
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

// A batch ready to run: the jobs of its inputs, each with its checked request.
struct BatchPlan {
    std::vector<BatchJob> jobs;
    std::vector<BakeRequest> requests;  // requests[i] bakes jobs[i]
};

// The plan's jobs: the inputs expanded (plan_batch, a manifest "-" read from `manifest_stdin`). The
// one-line error of a bad input, or empty.
std::string plan_jobs(const std::vector<std::string>& inputs, const std::string& outdir, std::istream* manifest_stdin,
                      BatchPlan& out);

// The plan's requests: each job's (job_request). The one-line error of the first bad job, or empty.
std::string make_requests(const BatchOptions& batch, BatchPlan& plan);

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

// How far a running batch has got, as its callbacks see it.
struct BatchProgress {
    size_t files = 0, done = 0;          // jobs in all, and jobs finished
    uint64_t bytes = 0, done_bytes = 0;  // the scene files' sizes: of every job, of the finished ones
    uint64_t baked_triangles = 0;        // triangles of the files baked so far (not those up to date)
    std::string current;                 // the name of the job started last
    double seconds = 0;                  // since the batch started
};

// A finished batch: each job's result, in the plan's order, how it ran and how long it took.
struct BatchOutcome {
    std::vector<BakeResult> results;
    BatchRun run;  // the jobs at once and the cores, as run
    double seconds = 0;
};

// Bakes the plan's jobs, largest first (run_batch), `run.jobs` at once on `run.cores` cores (0: one job per
// core, all hardware threads). `started` and `finished` are called as each job starts and ends, on the
// calling thread, with the progress so far (`finished` also with the job's index and result). The output
// folders must exist (make_output_folders). Throws as run_batch.
BatchOutcome bake_batch(const BatchPlan& plan, BatchRun run, const std::function<void(const BatchProgress&)>& started,
                        const std::function<void(const BatchProgress&, size_t job, const BakeResult&)>& finished);

// OUTDIR/summary.json's content: the tool, the run, the counts and one record per file, in
// the jobs' order.
nlohmann::json batch_summary(const std::vector<BatchJob>& jobs, const std::vector<BakeResult>& results,
                             const BatchRun& run, double wall_seconds);

// Writes the outcome's summary (batch_summary) to OUTDIR/summary.json, atomically: its path and text.
// Throws std::exception with one line when it cannot be written.
struct BatchSummaryFile {
    std::string path, text;
};
BatchSummaryFile write_batch_summary(const std::string& outdir, const BatchPlan& plan, const BatchOutcome& outcome);

}  // namespace cb
