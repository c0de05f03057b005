#include "bake_options.h"

#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <limits>

namespace cb {
namespace {

std::string mask_text(uint32_t mask) {
    static const char* names[] = {"obb", "sphere", "capsule", "cone", "slab"};
    std::string out;
    for (int b = 0; b < 5; ++b)
        if (mask & (1u << b)) {
            if (!out.empty()) out += ',';
            out += names[b];
        }
    return out.empty() ? "none" : out;
}

// A whole number read as the command line's parser has always read one (strtoull, base 0: decimal, 0x
// hexadecimal, a leading 0 octal), no sign but '+', at most `max`.
bool parse_whole(const std::string& text, uint64_t max, uint64_t& out) {
    if (text.empty() || text[0] == '-' || !(std::isdigit((unsigned char)text[0]) || text[0] == '+')) return false;
    errno = 0;
    char* end = nullptr;
    const unsigned long long v = std::strtoull(text.c_str(), &end, 0);
    if (errno != 0 || *end != '\0' || v > max) return false;
    out = v;
    return true;
}

template <class T>
std::string set_whole(const char* flag, const std::string& value, T& field) {
    uint64_t v = 0;
    if (!parse_whole(value, std::numeric_limits<T>::max(), v))
        return std::string(flag) + " takes a whole number from 0 to " + std::to_string(std::numeric_limits<T>::max()) +
            " (got '" + value + "')";
    field = T(v);
    return {};
}

std::string set_real(const char* flag, const std::string& value, double& field) {
    char* end = nullptr;
    const double v = value.empty() ? 0 : std::strtod(value.c_str(), &end);
    if (value.empty() || *end != '\0') return std::string(flag) + " takes a number (got '" + value + "')";
    field = v;
    return {};
}

// Seventeen significant digits: the text reads back as the same double.
std::string real_text(double v) {
    char text[32];
    std::snprintf(text, sizeof text, "%.17g", v);
    return text;
}

std::vector<BakeOption> make_table() {
    using R = const BakeRequest&;
    using W = BakeRequest&;
    using S = const std::string&;
    const std::string fine_limit = std::to_string(max_fine_size);
    return {
        {"--method", "method", OptionUse::clustering, true, "TEXT", "kmeans",
         "Clustering method: kmeans, vco or morton", [](R r) { return std::string(method_name(r.clustering.method)); },
         [](W r, S v) {
             return parse_method(v, r.clustering.method) ? std::string()
                                                         : "unknown method '" + v + "' (kmeans, vco, morton)";
         }},
        {"--coarse", "coarse_size", OptionUse::clustering, true, "UINT", "2048", "Triangles per coarse cluster",
         [](R r) { return std::to_string(r.clustering.coarse_size); },
         [](W r, S v) { return set_whole("--coarse", v, r.clustering.coarse_size); }},
        {"--fine", "fine_size", OptionUse::clustering, true, "UINT", "16",
         "Maximum triangles per fine cluster, 1 to " + fine_limit,
         [](R r) { return std::to_string(r.clustering.fine_size); },
         [](W r, S v) { return set_whole("--fine", v, r.clustering.fine_size); }},
        {"--seed", "seed", OptionUse::kmeans, true, "UINT", "1", "Seed of k-means++",
         [](R r) { return std::to_string(r.clustering.seed); },
         [](W r, S v) { return set_whole("--seed", v, r.clustering.seed); }},
        {"--k0", "kmeans_branching", OptionUse::kmeans, true, "UINT", "8", "k-means children per node",
         [](R r) { return std::to_string(r.clustering.kmeans_branching); },
         [](W r, S v) { return set_whole("--k0", v, r.clustering.kmeans_branching); }},
        {"--iterations", "kmeans_max_iterations", OptionUse::kmeans, true, "UINT", "16",
         "Cap on Lloyd iterations per node", [](R r) { return std::to_string(r.clustering.kmeans_max_iterations); },
         [](W r, S v) { return set_whole("--iterations", v, r.clustering.kmeans_max_iterations); }},
        {"--presplit", "kmeans_presplit", OptionUse::kmeans, true, "UINT", "65536",
         "kmeans: triangles per Morton chunk the trees grow in, in parallel; 0: one tree",
         [](R r) { return std::to_string(r.clustering.kmeans_presplit); },
         [](W r, S v) { return set_whole("--presplit", v, r.clustering.kmeans_presplit); }},
        {"--coarse-morton", "kmeans_coarse_from_tree", OptionUse::kmeans, false, "", "",
         "kmeans: Morton chunks as the coarse level instead of the top of the k-means trees",
         [](R r) { return std::string(r.clustering.kmeans_coarse_from_tree ? "false" : "true"); },
         [](W r, S) {
             r.clustering.kmeans_coarse_from_tree = false;
             return std::string();
         }},
        {"--cache", "vco_cache_size", OptionUse::vco, true, "UINT", "32", "vco: vertex cache size",
         [](R r) { return std::to_string(r.clustering.vco_cache_size); },
         [](W r, S v) { return set_whole("--cache", v, r.clustering.vco_cache_size); }},
        {"--bounds", "mask", OptionUse::bounds, true, "TEXT", "auto",
         "Volumes to fit: auto (what the shadow runtime reads: obb,cone), all, or a list of "
         "obb,sphere,capsule,cone,slab",
         [](R r) { return mask_text(r.bounds.mask); },
         [](W r, S v) {
             return parse_bounds_mask(v, r.bounds.mask)
                 ? std::string()
                 : "--bounds takes auto, all or a list of obb,sphere,capsule,cone,slab (got '" + v + "')";
         }},
        {"--obb", "obb", OptionUse::bounds, true, "TEXT", "refined",
         "Box fitter: refined, pca, pca-area, or cgal (CGAL's optimum: slow)",
         [](R r) { return std::string(obb_method_name(r.bounds.obb)); },
         [](W r, S v) {
             return parse_obb_method(v, r.bounds.obb) ? std::string()
                                                      : "--obb takes refined, pca, pca-area or cgal (got '" + v + "')";
         }},
        {"--capsule-ratio", "capsule_ratio", OptionUse::bounds, true, "FLOAT", "2",
         "Fit a capsule when the box's longest side is this many times each other",
         [](R r) { return real_text(r.bounds.capsule_ratio); },
         [](W r, S v) { return set_real("--capsule-ratio", v, r.bounds.capsule_ratio); }},
        {"--threads", "threads", OptionUse::run, true, "UINT", "0",
         "Worker threads, 0 = all hardware threads; the output is identical for any count",
         [](R r) { return std::to_string(r.threads); }, [](W r, S v) { return set_whole("--threads", v, r.threads); }},
    };
}

}  // namespace

const std::vector<BakeOption>& bake_options() {
    static const std::vector<BakeOption> table = make_table();
    return table;
}

const BakeOption* find_bake_option(const std::string& flag) {
    for (const BakeOption& o : bake_options())
        if (flag == o.flag) return &o;
    return nullptr;
}

std::string flag_of_field(const char* field) {
    for (const BakeOption& o : bake_options())
        if (std::string(field) == o.field) return o.flag;
    return field;
}

bool shapes_clusters(const BakeOption& o) {
    return o.use == OptionUse::clustering || o.use == OptionUse::kmeans || o.use == OptionUse::vco;
}

std::string ignored_because(const BakeOption& o, const BakeRequest& r) {
    const std::string method = method_name(r.clustering.method);
    switch (o.use) {
        case OptionUse::kmeans:
            if (r.clustering.method != ClusterMethod::kmeans) return "an option of kmeans, and the method is " + method;
            if (std::string(o.flag) == "--presplit" && !r.clustering.kmeans_coarse_from_tree)
                return "with --coarse-morton no k-means tree grows in presplit chunks";
            return {};
        case OptionUse::vco:
            return r.clustering.method == ClusterMethod::vco ? std::string()
                                                             : "an option of vco, and the method is " + method;
        case OptionUse::bounds: return r.fit ? std::string() : "an option of bake, and this run fits no bounds";
        case OptionUse::clustering:
        case OptionUse::run: return {};
    }
    return {};
}

std::string ignored_option_error(const std::vector<std::string>& given, const BakeRequest& r) {
    for (const BakeOption& o : bake_options()) {
        bool was_given = false;
        for (const std::string& g : given) was_given = was_given || g == o.flag;
        if (!was_given) continue;
        const std::string why = ignored_because(o, r);
        if (!why.empty()) return std::string(o.flag) + " does nothing here: " + why;
    }
    return {};
}

std::string request_options_error(const BakeRequest& r) {
    auto flag = [](const char* field) { return flag_of_field(field); };
    std::string error = describe(check_options(r.clustering), flag);
    if (error.empty()) error = describe(check_options(r.bounds), flag);
    return error;
}

std::string apply_options(const std::vector<std::string>& args, BakeRequest& r, std::vector<std::string>* given) {
    std::vector<std::string> seen;
    for (size_t i = 0; i < args.size(); ++i) {
        std::string flag = args[i], value;
        const size_t equals = flag.find('=');
        const bool inline_value = flag.compare(0, 2, "--") == 0 && equals != std::string::npos;
        if (inline_value) {
            value = flag.substr(equals + 1);
            flag.resize(equals);
        }
        const BakeOption* o = find_bake_option(flag);
        if (!o) return args[i] + " is not a bake option";
        for (const std::string& s : seen)
            if (s == flag) return flag + " is given twice";
        seen.push_back(flag);
        if (o->takes_value && !inline_value) {
            if (i + 1 == args.size()) return flag + " needs a value";
            value = args[++i];
        } else if (!o->takes_value && inline_value) {
            return flag + " takes no value";
        }
        std::string error = o->set(r, value);
        if (!error.empty()) return error;
        if (given) given->push_back(flag);
    }
    return {};
}

std::vector<std::string> options_argv(const BakeRequest& r) {
    std::vector<std::string> argv;
    for (const BakeOption& o : bake_options()) {
        if (o.use == OptionUse::run || !ignored_because(o, r).empty()) continue;
        const std::string value = o.text(r);
        if (!o.takes_value) {
            if (value == "true") argv.push_back(o.flag);
            continue;
        }
        argv.push_back(o.flag);
        argv.push_back(value);
    }
    return argv;
}

}  // namespace cb
