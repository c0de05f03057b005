// clusterbake command line: parses arguments, calls the libraries, prints. No algorithm lives here: each
// subcommand is a file of its own (commands.h).
#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>

#include "commands.h"

int main(int argc, char** argv) {
    CLI::App app{"clusterbake: clusters triangle scenes, fits bounding volumes and bakes a compact asset"};
    app.require_subcommand(1);
    using namespace cb::cli;
    const Command commands[] = {add_info(app),   add_cluster(app), add_bake(app),     add_stats(app),
                                add_report(app), add_heatmap(app), add_validate(app), add_query(app)};

    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e) == 0 ? 0 : 1;  // --help is a success; every bad option is exit code 1
    }

    try {
        for (const Command& c : commands)
            if (*c.subcommand) return c.run();
    } catch (const std::exception& e) {
        std::fprintf(stderr, "clusterbake: %s\n", e.what());
        return 1;
    }
    return 0;
}
