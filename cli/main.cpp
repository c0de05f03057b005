// clusterbake command line: parses arguments, calls the libraries, prints. No algorithm lives here: each
// subcommand is a file of its own (commands.h).
#include <malloc.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <exception>
#include <new>
#include <string>

#include <cb_asset.h>

#include "args.h"
#include "commands.h"
#include "scene_query.h"

int main(int argc, char** argv) {
#if defined(__GLIBC__)
    // Arrays of a megabyte or more get pages of their own, given back when freed. glibc otherwise raises
    // this threshold to the largest block freed so far, and a bake's freed stages stay resident.
    mallopt(M_MMAP_THRESHOLD, 1 << 20);
#endif
    CLI::App app{"clusterbake: clusters triangle scenes, fits bounding volumes and bakes a compact asset"};
    app.require_subcommand(1);
    app.set_version_flag("--version", [] {
        std::string lanes;
        try {
            lanes = cb::query_lanes();
        } catch (const std::exception& e) {
            lanes = e.what();
        }
        return "clusterbake " CB_VERSION " (asset format " + std::to_string(cb::asset_version) + ", build " +
            cb::build_id() + ", shadow queries on " + lanes + " lanes)";
    });
    using namespace cb::cli;
    const Command commands[] = {add_info(app),  add_cluster(app),     add_bake(app),    add_batch(app),
                                add_stats(app), add_report(app),      add_heatmap(app), add_validate(app),
                                add_query(app), add_export_gltf(app), add_render(app)};

    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForVersion& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {  // one line, as every other usage error
        std::string text = e.what();
        std::replace(text.begin(), text.end(), '\n', ' ');
        std::fprintf(stderr, "clusterbake: %s (see clusterbake --help)\n", text.c_str());
        return cb::cli::exit_usage;
    }

    try {
        for (const Command& c : commands)
            if (*c.subcommand) return c.run();
    } catch (const std::bad_alloc&) {
        std::fprintf(stderr, "clusterbake: out of memory\n");
        return cb::cli::exit_bad_input;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "clusterbake: %s\n", e.what());
        return cb::cli::exit_bad_input;
    }
    return 0;
}
