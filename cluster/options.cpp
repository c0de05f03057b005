// The clustering methods' names and the rules every ClusterOptions keeps.
#include <string>

#include "cluster.h"

namespace cb {

const char* method_name(ClusterMethod m) {
    switch (m) {
        case ClusterMethod::kmeans: return "kmeans";
        case ClusterMethod::vco: return "vco";
        case ClusterMethod::morton: return "morton";
    }
    return "?";
}

bool parse_method(const std::string& name, ClusterMethod& out) {
    for (ClusterMethod m : {ClusterMethod::kmeans, ClusterMethod::vco, ClusterMethod::morton})
        if (name == method_name(m)) {
            out = m;
            return true;
        }
    return false;
}

ClusterOptionsError check_options(const ClusterOptions& o) {
    if (o.fine_size == 0) return ClusterOptionsError::fine_size_zero;
    if (o.fine_size > max_fine_size) return ClusterOptionsError::fine_size_above_max;
    if (o.coarse_size == 0) return ClusterOptionsError::coarse_size_zero;
    if (o.coarse_size < o.fine_size) return ClusterOptionsError::coarse_size_below_fine_size;
    if (o.kmeans_branching < 2) return ClusterOptionsError::kmeans_branching_below_two;
    if (o.vco_cache_size < 3) return ClusterOptionsError::vco_cache_size_below_three;
    return ClusterOptionsError::none;
}

std::string describe(ClusterOptionsError error, const std::function<std::string(const char* field)>& name) {
    auto field = [&](const char* f) { return name ? name(f) : std::string(f); };
    switch (error) {
        case ClusterOptionsError::none: return {};
        case ClusterOptionsError::fine_size_zero: return field("fine_size") + " must be at least 1";
        case ClusterOptionsError::fine_size_above_max:
            return field("fine_size") + " must be at most " + std::to_string(max_fine_size) +
                " (a fine cluster's corners must fit the asset's 8-bit local indices)";
        case ClusterOptionsError::coarse_size_zero: return field("coarse_size") + " must be at least 1";
        case ClusterOptionsError::coarse_size_below_fine_size:
            return field("coarse_size") + " must be at least " + field("fine_size");
        case ClusterOptionsError::kmeans_branching_below_two:
            return field("kmeans_branching") + " must be at least 2 (children per k-means node)";
        case ClusterOptionsError::vco_cache_size_below_three:
            return field("vco_cache_size") + " must be at least 3 (a triangle's corners)";
    }
    return "unknown clustering options error";
}

}  // namespace cb
