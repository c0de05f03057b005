// The subcommands, one file each: add_X adds subcommand X and its options to the app and returns what runs
// it once the arguments are parsed, giving its exit code.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>

namespace cb::cli {

struct Command {
    CLI::App* subcommand;
    std::function<int()> run;
};

Command add_info(CLI::App& app);     // info.cpp
Command add_cluster(CLI::App& app);  // bake.cpp: cluster and bake
Command add_bake(CLI::App& app);
Command add_batch(CLI::App& app);        // batch.cpp
Command add_stats(CLI::App& app);        // stats.cpp
Command add_report(CLI::App& app);       // report.cpp
Command add_heatmap(CLI::App& app);      // heatmap.cpp
Command add_validate(CLI::App& app);     // validate.cpp
Command add_query(CLI::App& app);        // query.cpp
Command add_export_gltf(CLI::App& app);  // export_gltf.cpp
Command add_render(CLI::App& app);       // render.cpp

}  // namespace cb::cli
