#include "camera.h"

#include <detail/cb_math.h>

#include <algorithm>
#include <cmath>

#include "vec3.h"

namespace cb {

namespace {

using math::cross3;
using math::dot3;

constexpr double pi = 3.14159265358979323846;

}  // namespace

Camera default_camera(const double* lo, const double* hi, uint32_t width, uint32_t height) {
    Camera c;
    c.width = width;
    c.height = height;
    double size = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-30});
    double centre[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
    const double from[3] = {1.2, 0.8, 1.5};
    double up[3] = {0, 1, 0};
    for (int k = 0; k < 3; ++k) {
        c.eye[k] = centre[k] + from[k] * size;
        c.forward[k] = -from[k];
    }
    normalise(c.forward);
    cross3(c.forward, up, c.right);
    normalise(c.right);
    cross3(c.right, c.forward, c.up);
    // Frame the box's corners tightly, so the scene fills the view whatever its proportions.
    double aspect = aspect_of(c), extent = 1e-6;
    for (int i = 0; i < 8; ++i) {
        double e[3];
        for (int k = 0; k < 3; ++k) e[k] = ((i >> k & 1) ? hi[k] : lo[k]) - c.eye[k];
        double depth = dot3(e, c.forward);
        if (depth > 0)
            extent = std::max({extent, std::fabs(dot3(e, c.right)) / depth / aspect, std::fabs(dot3(e, c.up)) / depth});
    }
    c.half_extent = 1.04 * extent;
    return c;
}

Camera camera_looking_at(const double* eye, const double* target, const double* up, double fov_degrees, uint32_t width,
                         uint32_t height) {
    Camera c;
    c.width = width;
    c.height = height;
    for (int k = 0; k < 3; ++k) {
        c.eye[k] = eye[k];
        c.forward[k] = target[k] - eye[k];
    }
    normalise(c.forward);
    double upright[3] = {up[0], up[1], up[2]};
    normalise(upright);
    cross3(c.forward, upright, c.right);
    if (dot3(c.right, c.right) < 1e-12) {  // looking along `up`: keep the axis least along the view upright
        double axis[3] = {0, 0, 0};
        int least = 0;
        for (int k = 1; k < 3; ++k)
            if (std::fabs(c.forward[k]) < std::fabs(c.forward[least])) least = k;
        axis[least] = 1;
        cross3(c.forward, axis, c.right);
    }
    normalise(c.right);
    cross3(c.right, c.forward, c.up);
    c.half_extent = std::tan(fov_degrees * pi / 360);
    return c;
}

double framing_fov(const Camera& c, const double* lo, const double* hi) {
    const double aspect = aspect_of(c);
    double extent = 1e-6;
    for (int i = 0; i < 8; ++i) {
        double e[3];
        for (int k = 0; k < 3; ++k) e[k] = ((i >> k & 1) ? hi[k] : lo[k]) - c.eye[k];
        double depth = dot3(e, c.forward);
        if (!(depth > 0)) return 0;
        extent = std::max({extent, std::fabs(dot3(e, c.right)) / depth / aspect, std::fabs(dot3(e, c.up)) / depth});
    }
    return 2 * std::atan(1.04 * extent) * 180 / pi;  // the same margin as default_camera's
}

}  // namespace cb
