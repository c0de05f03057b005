// Bounding volumes of a set of triangles: oriented box, minimal sphere, capsule, normal cones with apex,
// slabs. Fitted in double in a frame local to the cluster, stored in float rounded outward: after rounding,
// every vertex of the cluster is inside every stored volume, evaluated in double against the floats, at any
// distance from the origin.
//
// Containment contracts (what "inside" means for the stored floats):
//   Obb:     |dot(p - center, axis[i])| <= half[i] for i = 0, 1, 2 (axes are unit to float precision)
//   Sphere:  |p - center| <= radius
//   Capsule: distance(p, segment a..b) <= radius
//   Slab:    low <= dot(p, axis) <= high
// Cones are the other way round: every point strictly inside the front cone sees every non-degenerate
// triangle of the cluster from its front side; see Cone in runtime/cb_asset.h.
#pragma once

#include <cb_asset.h>  // the volume structs: Obb, Sphere, Capsule, Cone, Slab

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>

namespace cb {

// Which volumes to fit.
enum BoundsMask : uint32_t { bounds_obb = 1, bounds_sphere = 2, bounds_capsule = 4, bounds_cone = 8, bounds_slab = 16 };
constexpr uint32_t bounds_all = 31;
// What the shadow runtime (clustered partitioned shadow volumes) reads: boxes, and cones for one-sided skips.
constexpr uint32_t bounds_auto = bounds_obb | bounds_cone;

// Parses "auto", "all" or a comma list of obb, sphere, capsule, cone, slab. False on an unknown word.
bool parse_bounds_mask(const std::string& text, uint32_t& mask);

// Boxes and cones come packed, as the asset stores them, and decoded, as the runtime reads them.
struct ClusterBounds {
    PackedObb packed_obb;
    Obb obb;  // unpack_obb(packed_obb)
    Sphere sphere;
    Capsule capsule;   // the sphere as a zero-length capsule unless has_capsule
    bool has_capsule;  // fitted only when the box's longest side is at least capsule_ratio times each other side
    PackedCone packed_cone;
    Cone cone;  // unpack_cone(packed_cone, packed_obb)
    Slab slab;
};

enum class ObbMethod {
    pca,          // covariance of the vertices
    pca_area,     // area-weighted covariance of the triangles (resists uneven tessellation)
    refined,      // rectangles across PCA axes and triangle normals, then a descent (default)
    cgal_optimal  // CGAL::oriented_bounding_box (slow reference; boxes from 4 points up)
};

// The fitter's name on the command line and in reports: "refined", "pca", "pca-area", "cgal".
const char* obb_method_name(ObbMethod m);
// False on an unknown name.
bool parse_obb_method(const std::string& name, ObbMethod& out);

struct BoundsOptions {
    uint32_t mask = bounds_obb | bounds_sphere | bounds_capsule | bounds_cone | bounds_slab;
    ObbMethod obb = ObbMethod::refined;
    double capsule_ratio = 2.0;
};

// The rules BoundsOptions must keep, each an error of its own; checked in this order.
enum class BoundsOptionsError {
    none,
    mask_unknown_kind,        // mask holds a bit of no volume kind
    capsule_ratio_below_one,  // capsule_ratio must be a finite number of at least 1 (a side against the others)
};

// The first rule `options` breaks, or none; fit_bounds's callers check it before any work.
BoundsOptionsError check_options(const BoundsOptions& options);

// The broken rule in one line, empty for none; fields named by `name` when set, by their own names otherwise.
std::string describe(BoundsOptionsError error, const std::function<std::string(const char* field)>& name = {});

// The triangles are `count` indices into `triangle_ids`, each a triangle of `indices` (3 per triangle)
// over `positions` (xyz floats). Pure: no state, safe to call from many threads. `vertex_count`, when known
// (not 0), is the positions' count: each thread's per-vertex scratch then takes its size once, instead of
// growing (a copy and fresh pages each time) as higher vertex numbers come.
ClusterBounds fit_bounds(const float* positions, const uint32_t* indices, const uint32_t* triangle_ids, size_t count,
                         const BoundsOptions& options, size_t vertex_count = 0);

// ---- the pieces, for tests and benchmarks. Points are xyz doubles, already relative to a local origin.

Obb fit_obb(const double* points, size_t n, const double* origin, ObbMethod method, const float* positions = nullptr,
            const uint32_t* indices = nullptr, const uint32_t* triangle_ids = nullptr, size_t triangle_count = 0);
Sphere fit_sphere(const double* points, size_t n, const double* origin);
Sphere ritter_sphere(const double* points, size_t n, const double* origin);  // Ritter's approximation, a baseline

// Volume of a stored box, for tightness comparisons.
double obb_volume(const Obb& b);

}  // namespace cb
