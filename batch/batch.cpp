#include "batch.h"

#include <algorithm>
#include <filesystem>
#include <numeric>

#include "bake_options.h"

namespace cb {

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

}  // namespace cb
