// The pinhole camera the tools look through (stats' heat maps and report points, render's pictures), the
// cameras they place, and the rays through its pixels.
#pragma once

#include <algorithm>
#include <cstdint>

namespace cb {

// A pinhole camera; pixel (x, y), y down, looks along forward + half_extent * (sx * aspect * right + sy * up).
struct Camera {
    double eye[3], forward[3], right[3], up[3];
    double half_extent = 0.5;
    uint32_t width = 128, height = 128;
};

// The picture's width over its height.
inline double aspect_of(const Camera& c) { return double(c.width) / double(std::max(1u, c.height)); }

// The direction of pixel (x, y)'s ray through its centre, as Camera defines it (not unit); `aspect` is
// aspect_of(c).
inline void pixel_ray(const Camera& c, double aspect, uint32_t x, uint32_t y, double* dir) {
    double sx = ((x + 0.5) / c.width * 2 - 1) * aspect, sy = 1 - (y + 0.5) / c.height * 2;
    for (int k = 0; k < 3; ++k) dir[k] = c.forward[k] + c.half_extent * (sx * c.right[k] + sy * c.up[k]);
}

// Looking at the centre of the world box [lo, hi] from a diagonal above it, the box's corners just in view.
Camera default_camera(const double* lo, const double* hi, uint32_t width, uint32_t height);

// A camera at `eye` looking at `target`, `up` kept upright in the picture (when it is along the view,
// another axis is taken), a vertical field of view of `fov_degrees`.
Camera camera_looking_at(const double* eye, const double* target, const double* up, double fov_degrees, uint32_t width,
                         uint32_t height);

// The vertical field of view (degrees) from `eye` along `forward` that just holds the box [lo, hi], as
// default_camera frames it; 0 when some corner is not in front of the eye.
double framing_fov(const Camera& camera, const double* lo, const double* hi);

}  // namespace cb
