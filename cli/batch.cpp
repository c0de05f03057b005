// clusterbake batch: bake every scene of folders, files and manifests into a mirrored output tree, several
// files at once, skipping outputs that are up to date; a progress line or one line per file, a summary
// table and OUTDIR/summary.json.
#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>
#include <memory>

#include "args.h"
#include "batch.h"
#include "commands.h"
#include "progress.h"

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

// --plan and --commands: each job's bake as a JSON line or as a command line.
void print_jobs(const BatchArgs& a, const BatchPlan& plan) {
    for (size_t i = 0; i < plan.jobs.size(); ++i) {
        const BatchJob& job = plan.jobs[i];
        std::vector<std::string> argv = bake_argv(plan.requests[i], a.force);
        if (a.plan) {
            nlohmann::json j = {
                {"name", job.name}, {"input", job.input}, {"root", job.root}, {"output", job.output}, {"argv", argv}};
            std::cout << j.dump() << "\n";
        } else {
            std::string line = "clusterbake";
            for (const std::string& word : argv) line += " " + shell_quoted(word);
            std::cout << line << "\n";
        }
    }
}

// A file's line as it finishes, when there is no progress line.
void print_result(const BatchJob& job, const BakeResult& r) {
    if (r.status == BakeStatus::failed)
        std::fprintf(stderr, "failed      %s\n", r.error.c_str());
    else if (!r.warning.empty())
        std::fprintf(stderr, "warning     %s\n", r.warning.c_str());
    else
        std::fprintf(stderr, "%-11s %s -> %s  %s triangles  %.3f s\n", status_name(r.status), job.name.c_str(),
                     job.output.c_str(), thousands(r.triangles).c_str(), r.seconds);
}

// The table of counts by status, the run, the summary's path, then the warnings and the failures.
void print_summary(const BatchPlan& plan, const BatchOutcome& outcome, const std::string& summary_path) {
    const BatchTotals totals = batch_totals(outcome.results);
    const double wall = outcome.seconds;
    const size_t files = plan.jobs.size();
    std::printf("%-12s %7s %14s %10s\n", "status", "files", "triangles", "seconds");
    const char* names[3] = {"baked", "up to date", "failed"};
    for (int s = 0; s < 3; ++s)
        std::printf("%-12s %7zu %14s %10.2f\n", names[s], totals.files[s], thousands(totals.triangles[s]).c_str(),
                    totals.seconds[s]);
    std::printf("%zu files in %.2f s wall (%.1f files/s, %.2f M triangles/s baked), %u at once on %u cores\n", files,
                wall, wall > 0 ? double(files) / wall : 0.0, wall > 0 ? double(totals.triangles[0]) / wall / 1e6 : 0.0,
                outcome.run.jobs, outcome.run.cores);
    std::printf("summary: %s\n", summary_path.c_str());
    size_t warned = 0;
    for (const BakeResult& r : outcome.results)
        if (!r.warning.empty()) std::printf(warned++ ? "  %s\n" : "warnings:\n  %s\n", r.warning.c_str());
    if (totals.files[int(BakeStatus::failed)]) {
        std::printf("failed:\n");
        for (const BakeResult& r : outcome.results)
            if (r.status == BakeStatus::failed) std::printf("  %s\n", r.error.c_str());
    }
}

int run_batch_command(const BatchArgs& a) {
    BatchPlan plan;
    if (!usage_ok(plan_jobs(a.inputs, a.outdir, &std::cin, plan))) return exit_usage;
    BatchOptions batch;
    batch.force = a.force;
    batch.given = given_flags(a.bake.flags);
    batch.bake.load = a.bake.load;
    if (!usage_ok(apply_flags(a.bake.flags, batch.bake)) || !usage_ok(make_requests(batch, plan))) return exit_usage;
    if (a.plan || a.commands) {
        print_jobs(a, plan);
        return 0;
    }
    // The output tree, made before any work: a path in the way is a usage error, not a failed file.
    if (!usage_ok(output_folder_error(a.outdir)) || !usage_ok(make_output_folders(plan.jobs))) return exit_usage;

    ProgressLine progress(!a.quiet);
    const bool lines = !a.quiet && !progress.on();
    auto draw = [&](const BatchProgress& p, bool force) {
        char text[160];
        std::snprintf(text, sizeof text, "%zu/%zu files  %.2f M triangles/s  %s", p.done, p.files,
                      p.seconds > 0 ? double(p.baked_triangles) / p.seconds / 1e6 : 0.0, p.current.c_str());
        progress.show(p.bytes ? double(p.done_bytes) / double(p.bytes) : double(p.done) / double(p.files), text, force);
    };
    const BatchOutcome outcome = bake_batch(
        plan, BatchRun{a.jobs, batch.bake.threads}, [&](const BatchProgress& p) { draw(p, false); },
        [&](const BatchProgress& p, size_t i, const BakeResult& r) {
            if (lines) print_result(plan.jobs[i], r);
            draw(p, p.done == p.files);
        });
    progress.clear();

    BatchSummaryFile summary;
    try {
        summary = write_batch_summary(a.outdir, plan, outcome);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "clusterbake: %s\n", e.what());
        return exit_bad_input;
    }
    if (a.json)
        std::cout << summary.text;
    else
        print_summary(plan, outcome, summary.path);
    return batch_totals(outcome.results).files[int(BakeStatus::failed)] ? exit_bad_input : 0;
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
