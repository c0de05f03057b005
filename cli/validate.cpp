// clusterbake validate: check an asset as the runtime does and print its counts and bounds sections.
#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>

#include "args.h"
#include "commands.h"

namespace cb::cli {
namespace {

int run_validate(const std::string& file) {
    cb::LoadedAsset asset;
    if (!load_asset(file, asset)) return exit_bad_input;
    const cb::AssetView& view = asset.view;
    std::printf("%s: valid clusterbake asset v%u, %zu bytes\n", file.c_str(), cb::asset_version, asset.size);
    std::printf("  meshes %u, instances %u, vertices %u, triangles %u, fine clusters %u, coarse clusters %u\n",
                view.mesh_count, view.instance_count, view.vertex_count, view.triangle_count, view.fine_count,
                view.coarse_count);
    if (view.mesh_flags) {
        uint32_t closed = 0;
        for (uint32_t m = 0; m < view.mesh_count; ++m) closed += view.mesh_flags[m] & cb::mesh_closed ? 1 : 0;
        size_t sided = 0;
        for (size_t t = 0; t < view.triangle_count; ++t) sided += view.double_sided(t);
        std::printf(
            "  closed meshes %u of %u (one-sided shadows equal two-sided ones outside them); double-sided triangles "
            "%zu\n",
            closed, view.mesh_count, sided);
    }
    for (auto [name, level] : {std::pair{"fine", &view.fine_bounds}, std::pair{"coarse", &view.coarse_bounds}}) {
        std::string kinds;
        if (level->obbs) kinds += " obb";
        if (level->spheres) kinds += " sphere";
        if (level->capsules) kinds += " capsule";
        if (level->cones) kinds += " cone";
        if (level->slabs) kinds += " slab";
        std::printf("  %s bounds:%s\n", name, kinds.empty() ? " none" : kinds.c_str());
    }
    if (view.source) {  // printable text only: the section may hold any bytes
        std::string text(view.source, view.source_size);
        for (char& ch : text)
            if ((static_cast<unsigned char>(ch) < 0x20 && ch != '\n') || ch == 0x7f) ch = '?';
        std::printf("  made from:\n");
        for (size_t at = 0; at < text.size();) {
            size_t end = std::min(text.find('\n', at), text.size());
            std::printf("    %s\n", text.substr(at, end - at).c_str());
            at = end + 1;
        }
    }
    return 0;
}

}  // namespace

Command add_validate(CLI::App& app) {
    auto file = std::make_shared<std::string>();
    CLI::App* c = app.add_subcommand("validate", "Check an asset's structure, ranges and checksum");
    c->add_option("file", *file, "Asset file")->required();
    return {c, [file] { return run_validate(*file); }};
}

}  // namespace cb::cli
