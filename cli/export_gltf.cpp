// clusterbake export-gltf: an asset's clusters as a coloured GLB that any glTF viewer shows (export/).
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <iostream>
#include <memory>
#include <stdexcept>

#include "args.h"
#include "asset_writer.h"
#include "bake_file.h"
#include "cluster_gltf.h"
#include "commands.h"
#include "progress.h"

namespace cb::cli {
namespace {

struct ExportArgs {
    std::string file, out, level = "fine", boxes;
    bool cones = false, force = false, json = false, quiet = false;
};

bool ends_with_gltf(std::string name) {
    std::transform(name.begin(), name.end(), name.begin(), [](unsigned char ch) { return char(std::tolower(ch)); });
    return name.size() >= 5 && name.compare(name.size() - 5, 5, ".gltf") == 0;
}

// What is wrong with the output path, found before any work, or empty. An existing asset there is most
// likely the input named twice: kept unless --force.
std::string output_problem(const ExportArgs& a) {
    std::string error = output_file_error(a.out);
    if (!error.empty()) return error;
    if (ends_with_gltf(a.out)) return a.out + ": export-gltf writes binary glTF; name it .glb";
    if (!a.force && cb::is_asset_file(a.out))
        return a.out + ": is a clusterbake asset; export-gltf would replace it with glTF (another name, or --force)";
    return {};
}

// The options as the exporter takes them, and the output usable; false after one line on stderr.
bool parse_export(const CLI::App* c, const ExportArgs& a, cb::ExportOptions& options) {
    if (a.level == "fine")
        options.level = cb::ExportLevel::fine;
    else if (a.level == "coarse")
        options.level = cb::ExportLevel::coarse;
    else
        return usage_ok("--level takes fine or coarse (got '" + a.level + "')");
    options.overlays = 0;
    if (!first_given(c, {"--boxes"}).empty()) {  // --boxes alone: the boxes
        uint32_t volumes = 0;
        if (!cb::parse_volume_overlays(a.boxes.empty() ? "obb" : a.boxes, volumes))
            return usage_ok("--boxes takes a list of obb,sphere,capsule (got '" + a.boxes + "')");
        options.overlays |= volumes;
    }
    if (a.cones) options.overlays |= cb::overlay_cone;
    options.generator = cb::tool_version();
    return usage_ok(output_problem(a));
}

void print_json(const ExportArgs& a, const cb::ExportSummary& s) {
    nlohmann::json j = {{"tool", cb::tool_version()},
                        {"file", a.file},
                        {"output", a.out},
                        {"level", a.level},
                        {"meshes", s.meshes},
                        {"instances", s.instances},
                        {"nodes", s.nodes},
                        {"clusters", s.clusters},
                        {"triangles", s.triangles},
                        {"primitives", s.clusters + s.line_primitives},
                        {"line_primitives", s.line_primitives},
                        {"colours", s.colours},
                        {"materials", s.materials},
                        {"cones", s.cones},
                        {"sheared_instances", s.sheared_instances},
                        {"bytes", s.bytes}};
    std::cout << j.dump(2) << "\n";
}

int run_export(const CLI::App* c, const ExportArgs& a) {
    cb::ExportOptions options;
    if (!parse_export(c, a, options)) return exit_usage;
    cb::LoadedAsset asset;
    if (!load_asset(a.file, asset)) return exit_bad_input;
    std::string error = cb::export_options_error(asset.view, options);
    if (!error.empty() && !usage_ok(a.file + ": " + error)) return exit_usage;
    ProgressLine progress(!a.quiet);
    cb::ExportSummary summary;
    std::vector<uint8_t> glb;
    try {
        progress.stage("colouring and building the glTF");
        glb = cb::export_clusters_glb(asset.view, options, &summary);
    } catch (const std::invalid_argument& e) {  // more than a GLB can hold
        progress.clear();
        std::fprintf(stderr, "%s: %s\n", a.file.c_str(), e.what());
        return exit_bad_input;
    }
    try {
        progress.stage("writing " + a.out);
        cb::write_file_atomic(a.out, glb);
    } catch (const std::runtime_error& e) {  // names the path
        progress.clear();
        std::fprintf(stderr, "%s\n", e.what());
        return exit_bad_input;
    }
    progress.clear();
    if (a.json)
        print_json(a, summary);
    else
        std::printf(
            "%s -> %s: %zu %s clusters in %zu meshes, %zu instances; %zu colours, %zu line primitives, %zu bytes\n",
            a.file.c_str(), a.out.c_str(), summary.clusters, a.level.c_str(), summary.meshes, summary.instances,
            summary.colours, summary.line_primitives, summary.bytes);
    return 0;
}

}  // namespace

Command add_export_gltf(CLI::App& app) {
    auto a = std::make_shared<ExportArgs>();
    CLI::App* c = app.add_subcommand(
        "export-gltf",
        "Write an asset's clusters as a GLB for glTF viewers: one primitive per cluster, neighbours never alike");
    c->add_option("file", a->file, "Asset file (.cbk)")->required();
    c->add_option("-o,--output", a->out, "Output GLB (written atomically)")->required();
    c->add_option("--level", a->level, "fine (default) or coarse: one primitive per cluster of that level");
    c->add_option(
         "--boxes", a->boxes,
         "Draw each cluster's box as lines in its colour; or a list of obb,sphere,capsule (--boxes=obb,sphere)")
        ->expected(0, 1);
    c->add_flag("--cones", a->cones, "Draw each valid normal cone's axis from its apex");
    c->add_flag("--force", a->force, "Write even over a clusterbake asset");
    c->add_flag("--json", a->json, "Print the summary as JSON");
    c->add_flag("-q,--quiet", a->quiet, "No progress on stderr");
    return {c, [a, c] { return run_export(c, *a); }};
}

}  // namespace cb::cli
