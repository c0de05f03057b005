// clusterbake heatmap: a PNG of the useless cluster tests per pixel, k-means beside VCO.
#include <cstdio>
#include <memory>
#include <stdexcept>

#include "args.h"
#include "asset_writer.h"
#include "commands.h"
#include "heatmap.h"
#include "load.h"

namespace cb::cli {
namespace {

struct HeatmapArgs {
    std::string file, out, light, obb = "refined";
    cb::HeatmapOptions options;
};

int run_heatmap(HeatmapArgs a) {
    if (!a.light.empty()) {
        if (!parse_light(a.light, a.options.light)) return exit_usage;
        a.options.has_light = true;
    }
    if (!parse_obb(a.obb, a.options.obb)) return exit_usage;
    if (a.options.size < 8 || a.options.size > 4096) {
        std::fprintf(stderr, "clusterbake: --size takes 8 to 4096\n");
        return exit_usage;
    }
    cb::Heatmap h;
    try {
        h = cb::render_heatmap(cb::load_scene(a.file), a.options);
        if (h.png.empty()) throw std::runtime_error(a.file + ": no triangles to draw");
        cb::write_file_atomic(a.out, h.png);
    } catch (const std::runtime_error& e) {
        std::fprintf(stderr, "%s\n", e.what());
        return exit_bad_input;
    }
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
    c->add_option("--size", a->options.size, "Panel size in pixels (default 256)");
    c->add_option("--light", a->light, "Light position X,Y,Z (default: above the scene, as the report's first light)");
    c->add_option("--fine", a->options.clustering.fine_size, "Maximum triangles per fine cluster, 1 to 85 (default 16)")
        ->check(CLI::Range(1, 85));
    c->add_option("--coarse", a->options.clustering.coarse_size, "Triangles per coarse cluster (default 2048)");
    c->add_option("--obb", a->obb, "refined (default), pca, pca-area, or cgal");
    c->add_flag("--one-sided", a->options.one_sided, "One-sided occluders");
    c->add_option("--threads", a->options.clustering.threads, "Worker threads, 0 = all");
    return {c, [a] { return run_heatmap(*a); }};
}

}  // namespace cb::cli
