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
#include <thread>

#include "args.h"
#include "asset_writer.h"
#include "batch.h"
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

int run_batch_command(const BatchArgs& a) {
    std::vector<BatchJob> jobs;
    try {
        jobs = plan_batch(a.inputs, a.outdir, &std::cin);
    } catch (const PlanError& e) {
        std::fprintf(stderr, "clusterbake: %s\n", e.what());
        return exit_usage;
    }
    BatchOptions batch;
    batch.force = a.force;
    batch.given = given_flags(a.bake.flags);
    batch.bake.load = a.bake.load;
    if (!usage_ok(apply_flags(a.bake.flags, batch.bake))) return exit_usage;
    std::vector<BakeRequest> requests(jobs.size());
    for (size_t i = 0; i < jobs.size(); ++i)
        if (!usage_ok(job_request(batch, jobs[i], requests[i]))) return exit_usage;
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
    if (!usage_ok(output_folder_error(a.outdir)) || !usage_ok(make_output_folders(jobs))) return exit_usage;

    const std::vector<size_t> order = largest_first(jobs);
    BatchRun run;
    const unsigned threads = batch.bake.threads;
    run.cores = threads ? threads : std::max(1u, std::thread::hardware_concurrency());
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
    std::string summary_path = (fs::path(a.outdir) / "summary.json").string();
    std::string text = batch_summary(jobs, results, run, wall).dump(2) + "\n";
    try {
        write_file_atomic(summary_path, std::vector<uint8_t>(text.begin(), text.end()));
    } catch (const std::exception& e) {
        std::fprintf(stderr, "clusterbake: %s\n", e.what());
        return exit_bad_input;
    }

    const BatchTotals totals = batch_totals(results);
    const size_t failed = totals.files[int(BakeStatus::failed)];
    if (a.json) {
        std::cout << text;
    } else {
        std::printf("%-12s %7s %14s %10s\n", "status", "files", "triangles", "seconds");
        const char* names[3] = {"baked", "up to date", "failed"};
        for (int s = 0; s < 3; ++s)
            std::printf("%-12s %7zu %14s %10.2f\n", names[s], totals.files[s], thousands(totals.triangles[s]).c_str(),
                        totals.seconds[s]);
        std::printf("%zu files in %.2f s wall (%.1f files/s, %.2f M triangles/s baked), %u at once on %u cores\n",
                    jobs.size(), wall, wall > 0 ? double(jobs.size()) / wall : 0.0,
                    wall > 0 ? double(totals.triangles[0]) / wall / 1e6 : 0.0, run.jobs, run.cores);
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
    add_bake_flags(c, a->bake.flags, bake_takes);
    add_load_flags(c, a->bake.load);
    c->add_option("-j,--jobs", a->jobs, "Files baked at once (default: one per core)");
    c->add_flag("--force", a->force, "Bake every file, even when its output is up to date");
    c->add_flag("--plan", a->plan,
                "Bake nothing: print each file's job as a JSON line (name, input, root, output, argv of its bake)");
    c->add_flag("--commands", a->commands, "Bake nothing: print each file's `clusterbake bake` command line");
    c->add_flag("--json", a->json, "Print summary.json on stdout instead of the table");
    c->add_flag("-q,--quiet", a->quiet, "No progress line and no line per file");
    return {c, [a] { return run_batch_command(*a); }};
}

}  // namespace cb::cli
