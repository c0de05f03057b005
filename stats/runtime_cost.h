// What a bake costs at run time, measured through the runtime's own query API (query/scene_query.h) on an
// asset encoded in memory: per-light build time, queries per second and traversal counts; and the points
// those queries use, the first hits of a camera's pixel rays.
#pragma once

#include <cb_asset.h>
#include <cb_shadow.h>
#include <detail/cb_tile.h>

#include <cstdint>
#include <vector>

#include "asset_writer.h"

namespace cb {

// A pinhole camera; pixel (x, y), y down, looks along forward + half_extent * (sx * aspect * right + sy * up).
struct Camera {
    double eye[3], forward[3], right[3], up[3];
    double half_extent = 0.5;
    uint32_t width = 128, height = 128;
};

// Looking at the centre of the world box [lo, hi] from a diagonal above it, the box's corners just in view.
Camera default_camera(const double* lo, const double* hi, uint32_t width, uint32_t height);

// Where the ray o + t v (t >= 0) enters box b, INFINITY when it misses: in double, each half extent widened
// by 1e-9 of itself and 1e-12, so that grazing rays do not slip between neighbouring boxes.
double ray_box_entry(const Obb& b, const double* o, const double* v);

// The world point each pixel's ray first hits (xyz per pixel, NaN where it hits nothing): a double-precision
// ray cast over the triangles of the fine clusters whose box the ray meets, coarse boxes first. Needs fine
// and coarse OBBs.
std::vector<double> first_hits(const BakedScene& baked, const Camera& camera, unsigned threads = 0);

// The hit points only (xyz), in pixel order.
std::vector<double> hit_points(const std::vector<double>& hits);

struct RuntimeCost {
    double build_seconds = 0;  // all instances' trees for one light: median over runs, mean over lights and suns
    double query_seconds = 0;  // every point once, one thread: median over runs, mean over lights and suns
    uint64_t queries = 0;      // points x (lights + suns)
    uint64_t shadowed = 0;
    QueryStats stats;  // summed over points and lights
    // A shadowed query stops at its one blocking cluster; every other cluster test found nothing.
    double useless_per_query() const {
        return queries ? double(stats.clusters_tested - shadowed) / double(queries) : 0;
    }
    double queries_per_second() const {
        return query_seconds > 0 && queries ? double(queries) / double(lights) / query_seconds : 0;
    }
    uint32_t lights = 0;  // point lights and suns
};

// For each light (xyz triples, world) and each sun (xyz toward it), builds every instance's structure and
// queries every point (xyz, world) on one thread, `runs` times, through query_scene with the given traversal
// (a sun has its own).
RuntimeCost measure_runtime(const AssetView& view, const std::vector<double>& lights, const std::vector<double>& suns,
                            const std::vector<double>& points, int runs, bool one_sided = false,
                            Traversal traversal = Traversal::scan);

// Per point, the cluster tests whose triangles did not block it (the heat map's figure), on `threads`
// threads (0: all); the counts do not depend on them. With `sun`, `light` is the direction toward a sun.
std::vector<uint32_t> useless_tests(const AssetView& view, const double* light, const std::vector<double>& points,
                                    bool one_sided = false, unsigned threads = 0, bool sun = false);

}  // namespace cb
