// clusterbake heatmap: a PNG of the useless cluster tests per pixel, k-means beside VCO.
#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>
#include <memory>
#include <stdexcept>

#include "args.h"
#include "asset_writer.h"
#include "commands.h"
#include "heatmap.h"
#include "load.h"
#include "progress.h"

namespace cb::cli {
namespace {

struct HeatmapArgs {
    std::string file, out, light, sun;
    BakeFlags flags;  // --coarse, --fine, --obb, --threads
    cb::HeatmapOptions options;
    cb::LoadOptions load;
    bool json = false, quiet = false;
};

// The options as the renderer takes them, and the input and output usable; false after one line on stderr.
bool parse_heatmap(HeatmapArgs& a) {
    if (!a.light.empty() && !a.sun.empty()) return usage_ok("--sun and --light name two lights; give one");
    if (!a.light.empty()) {
        if (!parse_light(a.light, a.options.light)) return false;
        a.options.has_light = true;
    }
    if (!a.sun.empty()) {
        if (!parse_sun(a.sun, a.options.light)) return false;
        a.options.has_light = a.options.sun = true;
    }
    cb::BakeRequest request;
    if (!usage_ok(apply_flags(a.flags, request))) return false;
    a.options.clustering = request.clustering;
    a.options.obb = request.bounds.obb;
    a.options.threads = request.threads;
    if (a.options.size < 8 || a.options.size > 4096) {
        std::fprintf(stderr, "clusterbake: --size takes 8 to 4096\n");
        return false;
    }
    return usage_ok(scene_input_error(a.file, "heatmap")) && usage_ok(output_file_error(a.out));
}

void print_json(const HeatmapArgs& a, const cb::Heatmap& h) {
    nlohmann::json j = {{"tool", cb::tool_version()},
                        {"file", a.file},
                        {"output", a.out},
                        {"width", h.width},
                        {"height", h.height},
                        {h.sun ? "sun" : "light", {h.light[0], h.light[1], h.light[2]}},
                        {"fine_size", a.options.clustering.fine_size},
                        {"coarse_size", a.options.clustering.coarse_size},
                        {"obb", given_or_default(a.flags, "--obb")},
                        {"one_sided", a.options.one_sided},
                        {"pixels", h.pixels},
                        {"mean_useless", {{"kmeans", h.mean_useless[0]}, {"vco", h.mean_useless[1]}}},
                        {"scale_max", h.scale_max}};
    std::cout << j.dump(2) << "\n";
}

int run_heatmap(HeatmapArgs a) {
    if (!parse_heatmap(a)) return exit_usage;
    ProgressLine progress(!a.quiet);
    cb::Heatmap h;
    try {
        progress.stage("loading " + a.file);
        cb::Scene scene = cb::load_scene(a.file, a.load);
        h = cb::render_heatmap(scene, a.options, [&](const std::string& stage) { progress.stage(stage); });
        progress.clear();
        if (h.png.empty()) throw std::runtime_error(a.file + ": no triangles to draw");
        cb::write_file_atomic(a.out, h.png);
    } catch (const std::runtime_error& e) {
        progress.clear();
        std::fprintf(stderr, "%s\n", e.what());
        return exit_bad_input;
    }
    if (a.json)
        print_json(a, h);
    else
        std::printf("%s -> %s (%ux%u)\n  %s\n", a.file.c_str(), a.out.c_str(), h.width, h.height, h.caption().c_str());
    return 0;
}

}  // namespace

Command add_heatmap(CLI::App& app) {
    auto a = std::make_shared<HeatmapArgs>();
    CLI::App* c = app.add_subcommand(
        "heatmap",
        "PNG heat map of useless cluster tests per pixel for a camera and a light: k-means (left) beside VCO (right)");
    c->add_option("file", a->file, "Scene file")->required();
    c->add_option("-o,--output", a->out, "Output PNG (written atomically)")->required();
    add_load_flags(c, a->load);
    c->add_option("--size", a->options.size, "Panel size in pixels (default 256)");
    c->add_option("--light", a->light, "Light position X,Y,Z (default: above the scene, as the report's first light)");
    c->add_option("--sun", a->sun, "A sun in place of the light: X,Y,Z the world direction toward it (any length)");
    add_bake_flags(c, a->flags, [](const cb::BakeOption& o) {
        const std::string flag = o.flag;
        return flag == "--coarse" || flag == "--fine" || flag == "--obb" || flag == "--threads";
    });
    c->add_flag("--one-sided", a->options.one_sided, "One-sided occluders");
    c->add_flag("--json", a->json, "Print the summary as JSON");
    c->add_flag("-q,--quiet", a->quiet, "No progress on stderr");
    return {c, [a] { return run_heatmap(*a); }};
}

}  // namespace cb::cli
