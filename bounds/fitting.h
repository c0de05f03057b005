// What the fitters share (obb.cpp, sphere.cpp, capsule.cpp, cone.cpp, slab.cpp, and fit_bounds in
// bounds.cpp); internal to bounds/.
//
// Every volume is fitted in double around a local origin (the centre of the cluster's box), then stored in
// float: the shape parameters (centre, axes, end points) are rounded to nearest, and only then are the
// extents and radii measured against those very floats, in double, with a margin for the rounding of that
// measurement, and rounded up. So containment never depends on how well the fit went: it holds by
// construction for the stored numbers.
#pragma once

#include <detail/cb_math.h>

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "bounds.h"

namespace cb::fitting {

using Vec = std::array<double, 3>;

inline Vec sub(const double* a, const double* b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
using math::dot3;
inline Vec cross(const Vec& a, const Vec& b) {
    Vec c;
    math::cross3(a.data(), b.data(), c.data());
    return c;
}
inline double norm(const Vec& a) { return std::sqrt(dot3(a.data(), a.data())); }

inline float round_up(double x) {
    float f = float(x);
    if (double(f) < x) f = std::nextafter(f, std::numeric_limits<float>::infinity());
    return f;
}
inline float round_down(double x) {
    float f = float(x);
    if (double(f) > x) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
    return f;
}

// Relative size of the rounding error of a double dot product or distance over float-derived inputs,
// with room to spare (a handful of ulps of 2^-53), and far below a float ulp (2^-24).
constexpr double measure_margin = 1e-14;

// Two float steps of a unit vector's component: how far a decoded axis may move between compilers.
constexpr double axis_step = 1.2e-7;

struct Frame {
    double axis[3][3];  // orthonormal rows, right-handed
};

// ---- boxes (obb.cpp)

// The box frame `method` fits to the points `pts` (local); `positions`, `indices`, `tris` and `count` are
// the cluster's triangles, for the area-weighted frame and the triangle normals (may be null), `origin`
// the local origin. Its axes are ordered and signed as the box's rotation nearest the identity.
Frame best_frame(const double* pts, size_t n, ObbMethod method, const float* positions, const uint32_t* indices,
                 const uint32_t* tris, size_t count, const double* origin);

// Stores a frame as a packed box that contains every world point: the rotation quantised first, then the
// centre rounded and the extents measured against the decoded axes (floats in `positions` order). The
// extents also allow each decoded axis component to move by two float steps (another compiler's decode).
PackedObb store_obb(const Frame& f, const double* local, size_t n, const double* origin, const double* world);

// ---- spheres and circles (sphere.cpp)

struct Ball {
    double c[3];
    double r2;  // negative: empty
};

// The smallest ball (dims 3) around the points, or circle (dims 2) around points that lie in the plane z = 0.
Ball min_ball(const double* pts, size_t n, int dims);

// Stores a sphere around `centre` that contains every world point.
Sphere store_sphere(const double* centre, const double* world, size_t n);

// ---- capsules (capsule.cpp)

// Axis from the box; radius from the minimal circle of the points projected on the plane across it;
// the segment as short as containment allows.
Capsule fit_capsule(const Frame& f, int major, const double* local, size_t n, const double* origin,
                    const double* world);

// ---- normal cones (cone.cpp)

// A packed cone for the triangles; `centre` is the decoded centre of the cluster's box. `normal` gets the
// stored axis direction whenever the triangles have one (zero otherwise), valid cone or not.
PackedCone fit_cone(const float* positions, const uint32_t* indices, const uint32_t* tris, size_t count,
                    const double* centre, double extent, float normal[3]);

// ---- slabs (slab.cpp)

// The slab across `axis_f` that holds every world point.
Slab fit_slab(const float axis_f[3], const double* world, size_t n);

}  // namespace cb::fitting
