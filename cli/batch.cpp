// clusterbake batch: bake every scene of folders, files and manifests into a mirrored output tree, several
// files at once, skipping outputs that are up to date; a progress line or one line per file, a summary
// table and OUTDIR/summary.json.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <numeric>
#include <thread>

#include "args.h"
#include "asset_writer.h"
#include "commands.h"
#include "plan.h"
#include "progress.h"
#include "run.h"
#include "timing.h"

namespace fs = std::filesystem;

namespace cb::cli {
namespace {

struct BatchArgs {
    std::vector<std::string> inputs;
    std::string outdir;
    ClusterArgs bake;
    unsigned jobs = 0;
    bool force = false, quiet = false, json = false, plan = false, commands = false;
};

// The per-file options of a manifest line over the batch's own; the error line, or empty.
std::string job_request(const CLI::App* batch_app, const BatchArgs& a, const BatchJob& job, BakeRequest& out) {
    ClusterArgs args = a.bake;
    args.options.threads = 0;  // the batch's --threads is the cores it shares; a line may cap its own file
    CLI::App line;
    add_clustering_flags(&line, args);
    add_bounds_flags(&line, args);
    if (!job.args.empty()) {
        std::vector<std::string> reversed(job.args.rbegin(), job.args.rend());  // CLI11 takes them backwards
        try {
            line.parse(reversed);
        } catch (const CLI::ParseError& e) {
            return job.origin + ": " + e.what();
        }
    }
    std::string error = request_error(args, out);
    // An option of another method than this file's, on its line or the batch's own command line.
    if (error.empty()) error = unused_by_method_error(&line, out.clustering.method);
    if (error.empty()) error = unused_by_method_error(batch_app, out.clustering.method);
    if (!error.empty()) return job.origin + ": " + error;
    out.input = job.input;
    out.output = job.output;
    out.if_changed = !a.force;
    out.load.root = job.root;
    return {};
}

// The `clusterbake bake` command line that makes the same output as the batch does for this job.
std::vector<std::string> bake_argv(const BakeRequest& r, bool force) {
    std::vector<std::string> argv = {"bake", r.input, "-o", r.output};
    std::string options = options_text(r.clustering, r.bounds, r.fit);
    for (size_t at = options.find(' '); at != std::string::npos;) {  // after the leading "bake"
        size_t end = options.find(' ', at + 1);
        argv.push_back(options.substr(at + 1, end == std::string::npos ? std::string::npos : end - at - 1));
        at = end;
    }
    // What the file is trusted with: the batch's input root, and the load flags when not the defaults.
    if (!r.load.root.empty()) argv.insert(argv.end(), {"--files-root", r.load.root});
    if (r.load.allow_outside_files) argv.push_back("--allow-outside-files");
    if (r.load.memory_budget != default_memory_budget)
        argv.insert(argv.end(), {"--memory-budget", std::to_string(r.load.memory_budget)});
    argv.push_back(force ? "--force" : "--if-changed");
    argv.push_back("--json");
    return argv;
}

std::string shell_quoted(const std::string& s) {
    if (!s.empty() &&
        s.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789-_./,=:+") ==
            std::string::npos)
        return s;
    std::string out = "'";
    for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out + "'";
}

std::string thousands(uint64_t n) {
    std::string digits = std::to_string(n), out;
    for (size_t i = 0; i < digits.size(); ++i) {
        if (i && (digits.size() - i) % 3 == 0) out += ',';
        out += digits[i];
    }
    return out;
}

int run_batch_command(const CLI::App* c, const BatchArgs& a) {
    std::vector<BatchJob> jobs;
    try {
        jobs = plan_batch(a.inputs, a.outdir, &std::cin);
    } catch (const PlanError& e) {
        std::fprintf(stderr, "clusterbake: %s\n", e.what());
        return exit_usage;
    }
    std::vector<BakeRequest> requests(jobs.size());
    for (size_t i = 0; i < jobs.size(); ++i) {
        std::string error = job_request(c, a, jobs[i], requests[i]);
        if (!error.empty()) {
            std::fprintf(stderr, "clusterbake: %s\n", error.c_str());
            return exit_usage;
        }
    }
    if (a.plan || a.commands) {
        for (size_t i = 0; i < jobs.size(); ++i) {
            std::vector<std::string> argv = bake_argv(requests[i], a.force);
            if (a.plan) {
                nlohmann::json j = {{"name", jobs[i].name},
                                    {"input", jobs[i].input},
                                    {"root", jobs[i].root},
                                    {"output", jobs[i].output},
                                    {"argv", argv}};
                std::cout << j.dump() << "\n";
            } else {
                std::string line = "clusterbake";
                for (const std::string& word : argv) line += " " + shell_quoted(word);
                std::cout << line << "\n";
            }
        }
        return 0;
    }

    // The output tree, made before any work: a path in the way is a usage error, not a failed file.
    if (!usage_ok(output_folder_error(a.outdir))) return exit_usage;
    std::error_code ec;
    for (const BatchJob& job : jobs) {
        fs::path folder = fs::path(job.output).parent_path();
        if (fs::create_directories(folder, ec), ec) {
            std::fprintf(stderr, "clusterbake: %s: cannot make the folder (%s)\n", folder.string().c_str(),
                         ec.message().c_str());
            return exit_usage;
        }
    }

    // Largest files first, so that the longest one does not start last.
    std::vector<size_t> order(jobs.size());
    std::iota(order.begin(), order.end(), size_t(0));
    std::stable_sort(order.begin(), order.end(),
                     [&](size_t x, size_t y) { return jobs[x].input_size > jobs[y].input_size; });
    BatchRun run;
    run.cores = a.bake.options.threads ? a.bake.options.threads : std::max(1u, std::thread::hardware_concurrency());
    run.jobs = a.jobs ? a.jobs : run.cores;

    uint64_t total_bytes = 0, done_bytes = 0, done_triangles = 0;
    for (const BatchJob& job : jobs) total_bytes += job.input_size;
    size_t done = 0;
    std::string current;
    ProgressLine progress(!a.quiet);
    bool lines = !a.quiet && !progress.on();
    auto t0 = std::chrono::steady_clock::now();
    auto draw = [&](bool force) {
        double seconds = seconds_since(t0);
        char text[160];
        std::snprintf(text, sizeof text, "%zu/%zu files  %.2f M triangles/s  %s", done, jobs.size(),
                      seconds > 0 ? double(done_triangles) / seconds / 1e6 : 0.0, current.c_str());
        progress.show(total_bytes ? double(done_bytes) / double(total_bytes) : double(done) / double(jobs.size()), text,
                      force);
    };
    std::vector<BakeResult> results = run_batch(
        requests, order, run,
        [&](size_t i) {
            current = jobs[i].name;
            draw(false);
        },
        [&](size_t i, const BakeResult& r) {
            ++done;
            done_bytes += jobs[i].input_size;
            if (r.status == BakeStatus::baked) done_triangles += r.triangles;
            if (lines) {
                if (r.status == BakeStatus::failed)
                    std::fprintf(stderr, "failed      %s\n", r.error.c_str());
                else if (!r.warning.empty())
                    std::fprintf(stderr, "warning     %s\n", r.warning.c_str());
                else
                    std::fprintf(stderr, "%-11s %s -> %s  %s triangles  %.3f s\n", status_name(r.status),
                                 jobs[i].name.c_str(), jobs[i].output.c_str(), thousands(r.triangles).c_str(),
                                 r.seconds);
            }
            draw(done == jobs.size());
        });
    progress.clear();
    double wall = seconds_since(t0);

    // summary.json: one record per file, sorted by name.
    size_t counts[3] = {};
    uint64_t triangles[3] = {};
    double seconds[3] = {};
    nlohmann::json files = nlohmann::json::array();
    for (size_t i = 0; i < jobs.size(); ++i) {
        const BakeResult& r = results[i];
        int s = int(r.status);
        ++counts[s], triangles[s] += r.triangles, seconds[s] += r.seconds;
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
    size_t baked = counts[int(BakeStatus::baked)], fresh = counts[int(BakeStatus::up_to_date)],
           failed = counts[int(BakeStatus::failed)];
    nlohmann::json summary = {{"tool", tool_version()},
                              {"format", asset_version},
                              {"engine", "local"},
                              {"jobs", run.jobs},
                              {"cores", run.cores},
                              {"seconds", wall},
                              {"counts", {{"baked", baked}, {"up_to_date", fresh}, {"failed", failed}}},
                              {"files", files}};
    std::string summary_path = (fs::path(a.outdir) / "summary.json").string();
    std::string text = summary.dump(2) + "\n";
    try {
        write_file_atomic(summary_path, std::vector<uint8_t>(text.begin(), text.end()));
    } catch (const std::exception& e) {
        std::fprintf(stderr, "clusterbake: %s\n", e.what());
        return exit_bad_input;
    }

    if (a.json) {
        std::cout << text;
    } else {
        std::printf("%-12s %7s %14s %10s\n", "status", "files", "triangles", "seconds");
        const char* names[3] = {"baked", "up to date", "failed"};
        for (int s = 0; s < 3; ++s)
            std::printf("%-12s %7zu %14s %10.2f\n", names[s], counts[s], thousands(triangles[s]).c_str(), seconds[s]);
        std::printf("%zu files in %.2f s wall (%.1f files/s, %.2f M triangles/s baked), %u at once on %u cores\n",
                    jobs.size(), wall, wall > 0 ? double(jobs.size()) / wall : 0.0,
                    wall > 0 ? double(triangles[0]) / wall / 1e6 : 0.0, run.jobs, run.cores);
        std::printf("summary: %s\n", summary_path.c_str());
        size_t warned = 0;
        for (size_t i = 0; i < jobs.size(); ++i)
            if (!results[i].warning.empty())
                std::printf(warned++ ? "  %s\n" : "warnings:\n  %s\n", results[i].warning.c_str());
        if (failed) {
            std::printf("failed:\n");
            for (size_t i = 0; i < jobs.size(); ++i)
                if (results[i].status == BakeStatus::failed) std::printf("  %s\n", results[i].error.c_str());
        }
    }
    return failed ? exit_bad_input : 0;
}

}  // namespace

Command add_batch(CLI::App& app) {
    auto a = std::make_shared<BatchArgs>();
    a->bake.fit = true;
    CLI::App* c = app.add_subcommand(
        "batch", "Bake every scene of files, folders and manifests into a mirrored tree, skipping up-to-date outputs");
    c->add_option("inputs", a->inputs,
                  "Scene files, folders (every scene below them) and manifests (a scene path a line, then its own bake "
                  "options; - reads one from standard input)")
        ->required();
    c->add_option("-o,--output", a->outdir, "Output folder: a/b/scene.glb is baked to OUTDIR/a/b/scene.cbk")
        ->required();
    add_clustering_flags(c, a->bake);
    add_bounds_flags(c, a->bake);
    add_load_flags(c, a->bake.load);
    c->add_option("-j,--jobs", a->jobs, "Files baked at once (default: one per core)");
    c->add_flag("--force", a->force, "Bake every file, even when its output is up to date");
    c->add_flag("--plan", a->plan,
                "Bake nothing: print each file's job as a JSON line (name, input, root, output, argv of its bake)");
    c->add_flag("--commands", a->commands, "Bake nothing: print each file's `clusterbake bake` command line");
    c->add_flag("--json", a->json, "Print summary.json on stdout instead of the table");
    c->add_flag("-q,--quiet", a->quiet, "No progress line and no line per file");
    return {c, [c, a] { return run_batch_command(c, *a); }};
}

}  // namespace cb::cli
