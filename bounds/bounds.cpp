// The bounds options (their rules, the mask's text) and fit_bounds, which fits a cluster's volumes with the
// fitters of obb.cpp, sphere.cpp, capsule.cpp, cone.cpp and slab.cpp (fitting.h).
#include "bounds.h"

#include <algorithm>
#include <vector>

#include "fitting.h"

namespace cb {

using namespace fitting;

BoundsOptionsError check_options(const BoundsOptions& o) {
    if (o.mask & ~bounds_all) return BoundsOptionsError::mask_unknown_kind;
    if (!(o.capsule_ratio >= 1 && std::isfinite(o.capsule_ratio))) return BoundsOptionsError::capsule_ratio_below_one;
    return BoundsOptionsError::none;
}

std::string describe(BoundsOptionsError error, const std::function<std::string(const char* field)>& name) {
    auto field = [&](const char* f) { return name ? name(f) : std::string(f); };
    switch (error) {
        case BoundsOptionsError::none: return {};
        case BoundsOptionsError::mask_unknown_kind:
            return field("mask") + " holds a bit of no volume kind (obb, sphere, capsule, cone, slab)";
        case BoundsOptionsError::capsule_ratio_below_one:
            return field("capsule_ratio") + " must be a finite number of at least 1";
    }
    return "unknown bounds options error";
}

bool parse_bounds_mask(const std::string& text, uint32_t& mask) {
    if (text == "auto") {
        mask = bounds_auto;
        return true;
    }
    if (text == "all") {
        mask = bounds_all;
        return true;
    }
    mask = 0;
    size_t at = 0;
    while (at <= text.size()) {
        size_t end = std::min(text.find(',', at), text.size());
        std::string word = text.substr(at, end - at);
        if (word == "obb")
            mask |= bounds_obb;
        else if (word == "sphere")
            mask |= bounds_sphere;
        else if (word == "capsule")
            mask |= bounds_capsule;
        else if (word == "cone")
            mask |= bounds_cone;
        else if (word == "slab")
            mask |= bounds_slab;
        else
            return false;
        at = end + 1;
    }
    return mask != 0;
}

ClusterBounds fit_bounds(const float* positions, const uint32_t* indices, const uint32_t* triangle_ids, size_t count,
                         const BoundsOptions& options, size_t vertex_count) {
    ClusterBounds out{};
    // The cluster's distinct vertices in order of first use, in double, world and local (around the centre
    // of their box). A vertex is new when its stamp is not this call's: no sort, no clearing between calls.
    thread_local std::vector<uint32_t> stamp;
    thread_local uint32_t call = 0;
    if (++call == 0) {
        std::fill(stamp.begin(), stamp.end(), 0u);
        call = 1;
    }
    if (vertex_count > stamp.size()) stamp.resize(vertex_count, 0u);
    thread_local std::vector<uint32_t> ids;  // scratch, as the arrays below: no allocation per cluster
    thread_local std::vector<double> world, local;
    // Branch-free: whether a corner's vertex is new follows no pattern a predictor could learn.
    ids.resize(count * 3);
    size_t n = 0;
    for (size_t i = 0; i < count; ++i)
        for (int k = 0; k < 3; ++k) {
            uint32_t v = indices[size_t(triangle_ids[i]) * 3 + k];
            if (v >= stamp.size()) stamp.resize(size_t(v) + 1 + stamp.size() / 2, 0u);
            const bool fresh = stamp[v] != call;
            stamp[v] = call;
            ids[n] = v;
            n += fresh;
        }
    world.resize(n * 3);
    local.resize(n * 3);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < n; ++v)
        for (int k = 0; k < 3; ++k) {
            world[v * 3 + k] = positions[size_t(ids[v]) * 3 + k];
            lo[k] = std::min(lo[k], world[v * 3 + k]);
            hi[k] = std::max(hi[k], world[v * 3 + k]);
        }
    double origin[3], extent = 0;
    for (int k = 0; k < 3; ++k) {
        origin[k] = 0.5 * (lo[k] + hi[k]);
        extent = std::max(extent, hi[k] - lo[k]);
    }
    for (size_t i = 0; i < n * 3; ++i) local[i] = world[i] - origin[i % 3];
    if (n == 0) return out;

    Frame frame = best_frame(local.data(), n, options.obb, positions, indices, triangle_ids, count, origin);
    out.packed_obb = store_obb(frame, local.data(), n, origin, world.data());
    out.obb = unpack_obb(out.packed_obb);
    if (options.mask & bounds_sphere) {
        Ball b = min_ball(local.data(), n, 3);
        double c[3] = {b.c[0] + origin[0], b.c[1] + origin[1], b.c[2] + origin[2]};
        out.sphere = store_sphere(c, world.data(), n);
    }
    if (options.mask & bounds_capsule) {
        double e[3];
        for (int i = 0; i < 3; ++i) e[i] = out.obb.half[i];
        int major = int(std::max_element(e, e + 3) - e);
        bool elongated = true;
        for (int i = 0; i < 3; ++i)
            if (i != major && e[major] < options.capsule_ratio * e[i]) elongated = false;
        if (elongated) {
            out.capsule = fit_capsule(frame, major, local.data(), n, origin, world.data());
            out.has_capsule = true;
        } else {  // the sphere, as a capsule of zero length: still a valid, containing capsule
            if (!(options.mask & bounds_sphere)) {
                Ball b = min_ball(local.data(), n, 3);
                double c[3] = {b.c[0] + origin[0], b.c[1] + origin[1], b.c[2] + origin[2]};
                out.sphere = store_sphere(c, world.data(), n);
            }
            for (int k = 0; k < 3; ++k) out.capsule.a[k] = out.capsule.b[k] = out.sphere.center[k];
            out.capsule.radius = out.sphere.radius;
        }
    }
    if (options.mask & (bounds_cone | bounds_slab)) {
        double centre[3] = {out.obb.center[0], out.obb.center[1], out.obb.center[2]};
        float normal[3];
        out.packed_cone = fit_cone(positions, indices, triangle_ids, count, centre, std::max(extent, 1e-30), normal);
        out.cone = unpack_cone(out.packed_cone, out.packed_obb);
        if (options.mask & bounds_slab) {
            // Across the mean normal; without one (no area, or normals cancelling), the box's thinnest axis.
            float axis[3];
            bool have = normal[0] != 0 || normal[1] != 0 || normal[2] != 0;
            int thin = int(std::min_element(out.obb.half, out.obb.half + 3) - out.obb.half);
            for (int k = 0; k < 3; ++k) axis[k] = have ? normal[k] : out.obb.axis[thin][k];
            out.slab = fit_slab(axis, world.data(), n);
        }
    }
    return out;
}

}  // namespace cb
