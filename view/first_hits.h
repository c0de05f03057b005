// The first hits of a camera's pixel rays by ray casting: a double-precision ray cast over a bake held in
// memory, its boxes culling, for the points the measuring tools query (the report, the heat map).
// visibility.h finds the same points by drawing the clusters instead.
#pragma once

#include <cb_asset.h>

#include <vector>

#include "asset_content.h"
#include "camera.h"

namespace cb {

// Where the ray o + t v (t >= 0) enters box b, INFINITY when it misses: in double, each half extent widened
// by 1e-9 of itself and 1e-12, so that grazing rays do not slip between neighbouring boxes.
double ray_box_entry(const Obb& b, const double* o, const double* v);

// The world point each pixel's ray first hits (xyz per pixel, NaN where it hits nothing): a double-precision
// ray cast over the triangles of the fine clusters whose box the ray meets, coarse boxes first. Needs fine
// and coarse OBBs.
std::vector<double> first_hits(const BakedScene& baked, const Camera& camera, unsigned threads = 0);

// The hit points only (xyz), in pixel order.
std::vector<double> hit_points(const std::vector<double>& hits);

}  // namespace cb
