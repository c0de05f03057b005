// clusterbake report: the sweep of clustering method x fine size x box fitter, as a table and report files.
#include <cstdio>
#include <iostream>
#include <memory>
#include <stdexcept>

#include "args.h"
#include "cluster.h"
#include "commands.h"
#include "report.h"

namespace cb::cli {
namespace {

std::vector<std::string> split_commas(const std::string& text) {
    std::vector<std::string> out;
    size_t start = 0;
    while (start <= text.size()) {
        size_t comma = text.find(',', start);
        if (comma == std::string::npos) comma = text.size();
        out.push_back(text.substr(start, comma - start));
        start = comma + 1;
    }
    return out;
}

struct ReportArgs {
    std::vector<std::string> files;
    std::string out, methods = "kmeans,vco,morton", fine = "8,16,24,32", obbs = "refined,pca",
                     traversals = "scan,mtsv-one";
    cb::ReportOptions options;
    bool quiet = false, json = false;
};

// Each comma-separated item of `text` through parse(item, value) into `out`; at the first bad item, a
// one-line error that starts with `what` and names it, and false.
template <class T, class Parse>
bool parse_list(const std::string& text, const char* what, Parse parse, std::vector<T>& out) {
    for (const std::string& item : split_commas(text)) {
        T value{};
        if (!parse(item, value)) {
            std::fprintf(stderr, "clusterbake: %s (got '%s')\n", what, item.c_str());
            return false;
        }
        out.push_back(value);
    }
    return true;
}

// Every check that needs no sweep: the inputs are scene files, no option is given in vain, the output
// folder can be made. False after one line on stderr.
bool usable(const CLI::App* c, const ReportArgs& a) {
    for (const std::string& file : a.files)
        if (!usage_ok(scene_input_error(file, "report"))) return false;
    if (!a.options.heatmap && refuse_given(c, {"--heatmap-size"}, "no heat map is drawn without --heatmap"))
        return false;
    return usage_ok(output_folder_error(a.out));
}

int run_report(const CLI::App* c, ReportArgs a) {
    cb::ReportOptions& o = a.options;
    o.methods.clear();
    o.fine_sizes.clear();
    o.obbs.clear();
    o.traversals.clear();
    auto fine_size = [](const std::string& f, uint32_t& v) {
        cb::BakeRequest r;
        if (!cb::find_bake_option("--fine")->set(r, f).empty()) return false;
        v = r.clustering.fine_size;
        return true;
    };
    if (!parse_list(a.methods, "--method takes a list of kmeans, vco, morton", cb::parse_method, o.methods) ||
        !parse_list(a.fine, "--fine takes a list of whole numbers", fine_size, o.fine_sizes) ||
        !parse_list(a.obbs, "--obb takes a list of refined, pca, pca-area, cgal", cb::parse_obb_method, o.obbs) ||
        !parse_list(a.traversals, "--traversal takes a list of scan, top-two, top-one, mtsv-one, mtsv-two",
                    cb::parse_traversal, o.traversals))
        return exit_usage;
    if (o.runs < 1 || o.query_runs < 1 || o.view < 1 || o.frame_view < 1) {
        std::fprintf(stderr, "clusterbake: --runs, --query-runs, --view and --frame-view must be at least 1\n");
        return exit_usage;
    }
    if (o.lights + o.suns < 1) {
        std::fprintf(stderr, "clusterbake: --lights and --suns are both 0: nothing lights the queries\n");
        return exit_usage;
    }
    // Every configuration of the sweep keeps the clustering's rules, checked before any work.
    for (uint32_t fine : o.fine_sizes) {
        cb::ClusterOptions clustering;
        clustering.coarse_size = o.coarse_size;
        clustering.fine_size = fine;
        const std::string error = cb::describe(cb::check_options(clustering), cb::flag_of_field);
        if (!error.empty()) {
            std::fprintf(stderr, "clusterbake: the sweep's --coarse %u --fine %u: %s\n", o.coarse_size, fine,
                         error.c_str());
            return exit_usage;
        }
    }
    if (o.heatmap_size < 8 || o.heatmap_size > 4096) {
        std::fprintf(stderr, "clusterbake: --heatmap-size takes 8 to 4096\n");
        return exit_usage;
    }
    if (!usable(c, a)) return exit_usage;
    cb::Report r;
    try {
        r = cb::run_report(a.files, o, [&](const std::string& msg) {
            if (!a.quiet) std::fprintf(stderr, "\r%-70s", msg.c_str());
        });
        if (!a.quiet) std::fprintf(stderr, "\n");
        cb::write_report(r, a.out);
    } catch (const std::runtime_error& e) {
        if (!a.quiet) std::fprintf(stderr, "\n");
        std::fprintf(stderr, "%s\n", e.what());
        return exit_bad_input;
    }
    if (a.json) {
        std::cout << cb::report_json(r).dump(2) << "\n";
        return 0;
    }
    std::fputs(cb::report_table(r).c_str(), stdout);
    std::printf("wrote %s/report.html, report.json, report.csv\n", a.out.c_str());
    return 0;
}

}  // namespace

Command add_report(CLI::App& app) {
    auto a = std::make_shared<ReportArgs>();
    CLI::App* c = app.add_subcommand("report",
                                     "Sweep clustering method x fine size x box fitter: bake time, tightness and "
                                     "runtime cost; writes DIR/report.html, .json, .csv");
    c->add_option("files", a->files, "Scene files")->required();
    c->add_option("-o,--output", a->out, "Output folder (created before the sweep)")->required();
    add_load_flags(c, a->options.load);
    c->add_option("--method", a->methods, "Comma list of clustering methods: kmeans, vco, morton (default all three)");
    c->add_option("--fine", a->fine,
                  "Comma list of maximum triangles per fine cluster, 1 to " + std::to_string(cb::max_fine_size) +
                      " (default 8,16,24,32)");
    c->add_option("--obb", a->obbs, "Comma list of box fitters: refined, pca, pca-area, cgal (default refined,pca)");
    c->add_option("--traversal", a->traversals,
                  "Comma list of runtime traversals, each a configuration: scan, top-two, top-one, mtsv-one, "
                  "mtsv-two (default scan,mtsv-one; the metric trees' assets carry spheres, capsules and slabs "
                  "too)");
    c->add_option("--coarse", a->options.coarse_size, "Triangles per coarse cluster (default 2048)");
    c->add_option("--runs", a->options.runs, "Bake timings are the median of this many runs (default 3)");
    c->add_option(
        "--query-runs", a->options.query_runs,
        "Runtime timings are the median of this many rounds, each measuring every configuration once (default 7)");
    c->add_option("--view", a->options.view, "Camera resolution; its visible points are the queries (default 128)");
    c->add_option("--frame-view", a->options.frame_view,
                  "Frame time is for a view of this resolution: build + its visible points' queries (default 1024)");
    c->add_option("--lights", a->options.lights, "Lights around each scene (default 2)");
    c->add_option("--suns", a->options.suns,
                  "Suns (fixed directions, high first) measured beside the lights (default 0)");
    c->add_flag("--one-sided", a->options.one_sided, "Query with one-sided occluders");
    c->add_option("--samples", a->options.stats.samples, "Shadow-volume samples per cluster and light (default 8)");
    c->add_option("--sample-lights", a->options.stats.lights,
                  "Random lights for the shadow-volume samples (default 4)");
    c->add_option("--threads", a->options.threads, threads_help("queries are timed on one thread all the same"));
    c->add_flag("--heatmap", a->options.heatmap,
                "Also draw each scene's heat map of useless cluster tests (k-means beside VCO)");
    c->add_option("--heatmap-size", a->options.heatmap_size, "Heat map panel size in pixels (default 256)");
    c->add_flag("--json", a->json, "Print report.json on stdout instead of the table");
    c->add_flag("-q,--quiet", a->quiet, "No progress on stderr");
    return {c, [a, c] { return run_report(c, *a); }};
}

}  // namespace cb::cli
