// The options of a bake in one table: each flag with the field it sets, the clustering method it belongs
// to, its default and its help. The command line's flags, its refusals of options that would change
// nothing, the source section's options text and the command lines a batch prints all come from it, and
// a batch's manifest lines are read with it.
#pragma once

#include <string>
#include <vector>

#include "bake_file.h"

namespace cb {

// What an option changes.
enum class OptionUse {
    clustering,  // the clusters, whatever the method
    kmeans,      // the clusters, with the kmeans method only
    vco,         // the clusters, with the vco method only
    bounds,      // the fitted volumes: only a bake that fits them (not `clusterbake cluster`)
    run,         // how the bake runs, not what it makes: the asset is the same for any value
};

struct BakeOption {
    const char* flag;   // "--coarse"
    const char* field;  // the field it sets, as the libraries' errors name it: "coarse_size"
    OptionUse use;
    bool takes_value;           // false: a switch, given alone (--coarse-morton)
    const char* value_type;     // what the help shows after the flag: "UINT", "TEXT", "FLOAT"; empty for a switch
    const char* default_value;  // as written on a command line; empty for a switch (off by default)
    std::string help;           // without the default, which default_value gives
    // The value in `r` as written on a command line; for a switch, "true" when on and "false" when off.
    std::string (*text)(const BakeRequest& r);
    // Sets the field from `value` (a switch ignores it and turns on): the one-line error, or empty.
    std::string (*set)(BakeRequest& r, const std::string& value);
};

// Every option, in the order the options text writes them: --method, --coarse, --fine, kmeans's, vco's,
// the bounds options, then --threads.
const std::vector<BakeOption>& bake_options();

// The option of that flag, or null.
const BakeOption* find_bake_option(const std::string& flag);

// The flag that sets `field` ("fine_size" -> "--fine"), or the field itself when no option sets it: what
// the libraries' errors name a field by on a command line.
std::string flag_of_field(const char* field);

// Whether the option shapes the clusters (clustering, kmeans or vco).
bool shapes_clusters(const BakeOption& option);

// Why `option` would change nothing in a bake of `r` ("an option of vco, and the method is kmeans"), or
// empty when it is used.
std::string ignored_because(const BakeOption& option, const BakeRequest& r);

// The first of the flags `given` that would change nothing in a bake of `r`, as "FLAG does nothing here:
// WHY"; empty when every one is used. A caller refuses it rather than dropping an option silently.
std::string ignored_option_error(const std::vector<std::string>& given, const BakeRequest& r);

// What is wrong with the request's options (the clustering's rules, then the bounds'), in one line naming
// each field by its flag; empty when nothing is. Every caller checks it before any work.
std::string request_options_error(const BakeRequest& r);

// `args` (flags, each followed by its value unless a switch; "--flag=value" too) applied onto `r` in their
// order, the flags given appended to `given` when set: the one-line error of the first that is unknown,
// given twice or has a bad value, or empty. Not checked against the rules: request_options_error does it.
std::string apply_options(const std::vector<std::string>& args, BakeRequest& r,
                          std::vector<std::string>* given = nullptr);

// The options that shape the asset, as a command line's words after the subcommand: every option that is
// used (ignored_because empty) and is not a run option, in the table's order; a switch only when on.
std::vector<std::string> options_argv(const BakeRequest& r);

}  // namespace cb
