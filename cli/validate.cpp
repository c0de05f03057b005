// clusterbake validate: check an asset as the runtime does and print its counts and bounds sections.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "args.h"
#include "commands.h"

namespace cb::cli {
namespace {

struct ValidateArgs {
    std::string file;
    bool json = false, quiet = false;
};

// The bounds kinds a level stores, by name.
std::vector<std::string> level_kinds(const cb::LevelBounds& level) {
    std::vector<std::string> kinds;
    if (level.obbs) kinds.push_back("obb");
    if (level.spheres) kinds.push_back("sphere");
    if (level.capsules) kinds.push_back("capsule");
    if (level.cones) kinds.push_back("cone");
    if (level.slabs) kinds.push_back("slab");
    return kinds;
}

// The source section's lines, printable text only: the section may hold any bytes.
std::vector<std::string> source_lines(const cb::AssetView& view) {
    std::vector<std::string> lines;
    if (!view.source) return lines;
    std::string text(view.source, view.source_size);
    for (char& ch : text)
        if ((static_cast<unsigned char>(ch) < 0x20 && ch != '\n') || ch == 0x7f) ch = '?';
    for (size_t at = 0; at < text.size();) {
        size_t end = std::min(text.find('\n', at), text.size());
        lines.push_back(text.substr(at, end - at));
        at = end + 1;
    }
    return lines;
}

struct Sidedness {
    uint32_t closed_meshes = 0;
    size_t double_sided = 0;
};

Sidedness sidedness(const cb::AssetView& view) {
    Sidedness s;
    for (uint32_t m = 0; m < view.mesh_count; ++m) s.closed_meshes += view.mesh_flags[m] & cb::mesh_closed ? 1 : 0;
    for (size_t t = 0; t < view.triangle_count; ++t) s.double_sided += view.double_sided(t);
    return s;
}

nlohmann::json asset_json(const std::string& file, const cb::LoadedAsset& asset) {
    const cb::AssetView& view = asset.view;
    nlohmann::json j = {{"tool", cb::tool_version()},
                        {"file", file},
                        {"valid", true},
                        {"format", cb::asset_version},
                        {"bytes", asset.size},
                        {"meshes", view.mesh_count},
                        {"instances", view.instance_count},
                        {"vertices", view.vertex_count},
                        {"triangles", view.triangle_count},
                        {"fine_clusters", view.fine_count},
                        {"coarse_clusters", view.coarse_count},
                        {"fine_bounds", level_kinds(view.fine_bounds)},
                        {"coarse_bounds", level_kinds(view.coarse_bounds)},
                        {"source", source_lines(view)}};
    if (view.mesh_flags) {
        Sidedness s = sidedness(view);
        j["closed_meshes"] = s.closed_meshes;
        j["double_sided_triangles"] = s.double_sided;
    }
    return j;
}

void print_asset(const std::string& file, const cb::LoadedAsset& asset) {
    const cb::AssetView& view = asset.view;
    std::printf("%s: valid clusterbake asset v%u, %zu bytes\n", file.c_str(), cb::asset_version, asset.size);
    std::printf("  meshes %u, instances %u, vertices %u, triangles %u, fine clusters %u, coarse clusters %u\n",
                view.mesh_count, view.instance_count, view.vertex_count, view.triangle_count, view.fine_count,
                view.coarse_count);
    if (view.mesh_flags) {
        Sidedness s = sidedness(view);
        std::printf(
            "  closed meshes %u of %u (one-sided shadows equal two-sided ones outside them); double-sided triangles "
            "%zu\n",
            s.closed_meshes, view.mesh_count, s.double_sided);
    }
    for (auto [name, level] : {std::pair{"fine", &view.fine_bounds}, std::pair{"coarse", &view.coarse_bounds}}) {
        std::string kinds;
        for (const std::string& kind : level_kinds(*level)) kinds += " " + kind;
        std::printf("  %s bounds:%s\n", name, kinds.empty() ? " none" : kinds.c_str());
    }
    std::vector<std::string> lines = source_lines(view);
    if (!lines.empty()) std::printf("  made from:\n");
    for (const std::string& line : lines) std::printf("    %s\n", line.c_str());
}

int run_validate(const ValidateArgs& a) {
    cb::LoadedAsset asset;
    std::string error;
    if (!cb::read_asset_file(a.file, asset, error)) {
        std::fprintf(stderr, "%s\n", error.c_str());
        if (a.json)
            std::cout << nlohmann::json{{"tool", cb::tool_version()},
                                        {"file", a.file},
                                        {"valid", false},
                                        {"error", error}}
                             .dump(2)
                      << "\n";
        return exit_bad_input;
    }
    if (a.json)
        std::cout << asset_json(a.file, asset).dump(2) << "\n";
    else
        print_asset(a.file, asset);
    return 0;
}

}  // namespace

Command add_validate(CLI::App& app) {
    auto a = std::make_shared<ValidateArgs>();
    CLI::App* c = app.add_subcommand("validate", "Check an asset's structure, ranges and checksum");
    c->add_option("file", a->file, "Asset file")->required();
    c->add_flag("--json", a->json, "Print one JSON object (\"valid\": false and the error when it is not valid)");
    c->add_flag("-q,--quiet", a->quiet, "No progress on stderr (validate prints none; errors are always printed)");
    return {c, [a] { return run_validate(*a); }};
}

}  // namespace cb::cli
