#include "batch.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <numeric>
#include <thread>

#include "asset_writer.h"
#include "bake_options.h"
#include "timing.h"

namespace cb {

std::string plan_jobs(const std::vector<std::string>& inputs, const std::string& outdir, std::istream* manifest_stdin,
                      BatchPlan& out) {
    try {
        out.jobs = plan_batch(inputs, outdir, manifest_stdin);
    } catch (const PlanError& e) {
        return e.what();
    }
    return {};
}

std::string make_requests(const BatchOptions& batch, BatchPlan& plan) {
    plan.requests.assign(plan.jobs.size(), BakeRequest{});
    for (size_t i = 0; i < plan.jobs.size(); ++i) {
        std::string error = job_request(batch, plan.jobs[i], plan.requests[i]);
        if (!error.empty()) return error;
    }
    return {};
}

std::string job_request(const BatchOptions& batch, const BatchJob& job, BakeRequest& out) {
    out = batch.bake;
    out.threads = 0;  // the batch's --threads is the cores it shares; a line may cap its own file
    std::vector<std::string> line_given;
    std::string error = apply_options(job.args, out, &line_given);
    if (error.empty()) error = request_options_error(out);
    // An option that does nothing for this file, on its line or on the batch's own command line.
    if (error.empty()) error = ignored_option_error(line_given, out);
    if (error.empty()) error = ignored_option_error(batch.given, out);
    if (!error.empty()) return job.origin + ": " + error;
    out.input = job.input;
    out.output = job.output;
    out.if_changed = !batch.force;
    out.load.root = job.root;
    return {};
}

std::vector<std::string> bake_argv(const BakeRequest& r, bool force) {
    std::vector<std::string> argv = {"bake", r.input, "-o", r.output};
    const std::vector<std::string> options = options_argv(r);
    argv.insert(argv.end(), options.begin(), options.end());
    // What the file is trusted with: the batch's input root, and the load flags when not the defaults.
    if (!r.load.root.empty()) argv.insert(argv.end(), {"--files-root", r.load.root});
    if (r.load.allow_outside_files) argv.push_back("--allow-outside-files");
    if (r.load.memory_budget != default_memory_budget)
        argv.insert(argv.end(), {"--memory-budget", std::to_string(r.load.memory_budget)});
    argv.push_back(force ? "--force" : "--if-changed");
    argv.push_back("--json");
    return argv;
}

std::string make_output_folders(const std::vector<BatchJob>& jobs) {
    namespace fs = std::filesystem;
    for (const BatchJob& job : jobs) {
        const fs::path folder = fs::path(job.output).parent_path();
        std::error_code ec;
        fs::create_directories(folder, ec);
        if (ec) return folder.string() + ": cannot make the folder (" + ec.message() + ")";
    }
    return {};
}

std::vector<size_t> largest_first(const std::vector<BatchJob>& jobs) {
    std::vector<size_t> order(jobs.size());
    std::iota(order.begin(), order.end(), size_t(0));
    std::stable_sort(order.begin(), order.end(),
                     [&](size_t x, size_t y) { return jobs[x].input_size > jobs[y].input_size; });
    return order;
}

BatchOutcome bake_batch(const BatchPlan& plan, BatchRun run, const std::function<void(const BatchProgress&)>& started,
                        const std::function<void(const BatchProgress&, size_t job, const BakeResult&)>& finished) {
    const std::vector<BatchJob>& jobs = plan.jobs;
    BatchOutcome outcome;
    outcome.run.cores = run.cores ? run.cores : std::max(1u, std::thread::hardware_concurrency());
    outcome.run.jobs = run.jobs ? run.jobs : outcome.run.cores;
    BatchProgress progress;
    progress.files = jobs.size();
    for (const BatchJob& job : jobs) progress.bytes += job.input_size;
    const auto t0 = std::chrono::steady_clock::now();
    outcome.results = run_batch(
        plan.requests, largest_first(jobs), outcome.run,
        [&](size_t i) {
            progress.current = jobs[i].name;
            progress.seconds = seconds_since(t0);
            started(progress);
        },
        [&](size_t i, const BakeResult& r) {
            ++progress.done;
            progress.done_bytes += jobs[i].input_size;
            if (r.status == BakeStatus::baked) progress.baked_triangles += r.triangles;
            progress.seconds = seconds_since(t0);
            finished(progress, i, r);
        });
    outcome.seconds = seconds_since(t0);
    return outcome;
}

BatchTotals batch_totals(const std::vector<BakeResult>& results) {
    BatchTotals t;
    for (const BakeResult& r : results) {
        const int s = int(r.status);
        ++t.files[s];
        t.triangles[s] += r.triangles;
        t.seconds[s] += r.seconds;
    }
    return t;
}

nlohmann::json batch_summary(const std::vector<BatchJob>& jobs, const std::vector<BakeResult>& results,
                             const BatchRun& run, double wall_seconds) {
    nlohmann::json files = nlohmann::json::array();
    for (size_t i = 0; i < jobs.size(); ++i) {
        const BakeResult& r = results[i];
        files.push_back({{"name", jobs[i].name},
                         {"input", jobs[i].input},
                         {"output", jobs[i].output},
                         {"status", status_name(r.status)},
                         {"input_bytes", r.status == BakeStatus::failed ? jobs[i].input_size : r.input_bytes},
                         {"triangles", r.triangles},
                         {"clusters", r.fine_clusters},
                         {"coarse_clusters", r.coarse_clusters},
                         {"seconds", r.seconds},
                         {"output_bytes", r.output_bytes},
                         {"error", r.error},
                         {"warning", r.warning}});
    }
    const BatchTotals t = batch_totals(results);
    return {{"tool", tool_version()},
            {"format", asset_version},
            {"engine", "local"},
            {"jobs", run.jobs},
            {"cores", run.cores},
            {"seconds", wall_seconds},
            {"counts",
             {{"baked", t.files[int(BakeStatus::baked)]},
              {"up_to_date", t.files[int(BakeStatus::up_to_date)]},
              {"failed", t.files[int(BakeStatus::failed)]}}},
            {"files", files}};
}

BatchSummaryFile write_batch_summary(const std::string& outdir, const BatchPlan& plan, const BatchOutcome& outcome) {
    BatchSummaryFile file;
    file.path = (std::filesystem::path(outdir) / "summary.json").string();
    file.text = batch_summary(plan.jobs, outcome.results, outcome.run, outcome.seconds).dump(2) + "\n";
    write_file_atomic(file.path, std::vector<uint8_t>(file.text.begin(), file.text.end()));
    return file;
}

}  // namespace cb
