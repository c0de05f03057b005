// The shadow volume of a box seen from a point light (the thesis's figure 2.7), the building block of the
// TOP-trees (cb_top_tree.h). Header-only C++17, no dependencies, no exceptions, no allocation. MIT licensed
// (runtime/LICENSE).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "../cb_asset.h"
#include "cb_simd.h"

namespace cb {
inline namespace CB_LANES {

// The shadow volume of a box seen from a point light, the building block of the clustered structure
// (the thesis's figure 2.7): four planes through the light that enclose every ray from the light through
// the box, closed by the box's distance from the light. Any point a triangle in the box can shadow lies
// inside: the blocking point X is in the box and p lies on the ray from the light through X, beyond X.
struct ShadowVolume {
    float normal[4][3];  // unit to float precision; inside: dot(normal[k], p - light) >= 0 for every k
    double near;         // no point closer than this to the light can be shadowed by the box
    bool valid;          // false: the light is inside or level with the box; test its cluster for every point
    // The frame the planes come from (for samplers and drawing): the volume is about the points
    // light + z (direction + x across[0] + y across[1]), z > 0, rect[0] <= x <= rect[1], rect[2] <= y <= rect[3]
    // (the stored float planes hold at least that, and are what inside_shadow_volume tests).
    double direction[3], across[2][3], rect[4];
};

// Builds the volume; the light is in the box's frame. The planes come from the central projection of the
// box's 8 corners onto the plane across the direction to the box, bounded by a rectangle whose sides follow
// the box axis that looks longest from the light. The 4-plane approximation is never trusted blindly: each
// plane, as stored in float, is checked against all 8 corners in double and widened until they clear it.
inline ShadowVolume make_shadow_volume(const Obb& box, const double* light) {
    ShadowVolume v{};
    double c[3] = {box.center[0], box.center[1], box.center[2]}, d[3], len = 0;
    for (int k = 0; k < 3; ++k) {
        d[k] = c[k] - light[k];
        len += d[k] * d[k];
    }
    len = std::sqrt(len);
    if (!(len > 0)) return v;
    for (double& x : d) x /= len;
    double half[3], corner[8][3];
    padded_halves(box, half);  // the corners of a box that holds the stored one (cb_asset.h)
    for (int i = 0; i < 8; ++i)
        for (int k = 0; k < 3; ++k)
            corner[i][k] = (c[k] - light[k]) +
                ((i & 1 ? 1 : -1) * half[0] * box.axis[0][k] + (i & 2 ? 1 : -1) * half[1] * box.axis[1][k] +
                 (i & 4 ? 1 : -1) * half[2] * box.axis[2][k]);
    // Every corner must be clearly in front of the light; otherwise no pyramid through the light holds the
    // box (the light is inside it or level with it): never build a wrong plane. Corner sizes are taken in
    // the max norm (no square roots): twice it bounds the Euclidean length.
    double depth[8], inv_depth[8], reach = 0, corner_size[8];
    for (int i = 0; i < 8; ++i) {
        depth[i] = corner[i][0] * d[0] + corner[i][1] * d[1] + corner[i][2] * d[2];
        corner_size[i] = 2 * std::max({std::fabs(corner[i][0]), std::fabs(corner[i][1]), std::fabs(corner[i][2])});
        reach = std::max(reach, corner_size[i]);
    }
    for (int i = 0; i < 8; ++i) {
        if (!(depth[i] > 1e-6 * reach)) return v;
        inv_depth[i] = 1 / depth[i];
    }
    // u: the box axis with the longest extent across the view direction, made perpendicular to it.
    double u[3] = {0, 0, 0}, best = -1;
    for (int i = 0; i < 3; ++i) {
        double a[3] = {box.axis[i][0], box.axis[i][1], box.axis[i][2]};
        double along = a[0] * d[0] + a[1] * d[1] + a[2] * d[2], w[3], wl = 0;
        for (int k = 0; k < 3; ++k) {
            w[k] = a[k] - along * d[k];
            wl += w[k] * w[k];
        }
        if (wl * half[i] * half[i] > best * std::fabs(best) && wl > 1e-12) {  // compares squared lengths
            wl = std::sqrt(wl);
            best = wl * half[i];
            for (int k = 0; k < 3; ++k) u[k] = w[k] / wl;
        }
    }
    if (best < 0) {  // every axis along the view direction: any perpendicular will do
        double h[3] = {std::fabs(d[0]) < 0.6 ? 1.0 : 0.0, std::fabs(d[0]) < 0.6 ? 0.0 : 1.0, 0.0};
        double along = h[0] * d[0] + h[1] * d[1] + h[2] * d[2], wl = 0;
        for (int k = 0; k < 3; ++k) {
            u[k] = h[k] - along * d[k];
            wl += u[k] * u[k];
        }
        for (double& x : u) x /= std::sqrt(wl);
    }
    double w[3] = {d[1] * u[2] - d[2] * u[1], d[2] * u[0] - d[0] * u[2], d[0] * u[1] - d[1] * u[0]};
    // bound[0] <= x, x <= bound[1], bound[2] <= y, y <= bound[3] in the projection plane. Rounding here
    // only moves the planes a little: the check below widens any plane a corner does not clear.
    double bound[4] = {INFINITY, -INFINITY, INFINITY, -INFINITY};
    for (int i = 0; i < 8; ++i) {
        double x = (corner[i][0] * u[0] + corner[i][1] * u[1] + corner[i][2] * u[2]) * inv_depth[i];
        double y = (corner[i][0] * w[0] + corner[i][1] * w[1] + corner[i][2] * w[2]) * inv_depth[i];
        bound[0] = std::min(bound[0], x);
        bound[1] = std::max(bound[1], x);
        bound[2] = std::min(bound[2], y);
        bound[3] = std::max(bound[3], y);
    }
    double scale = 1 + std::max({std::fabs(bound[0]), std::fabs(bound[1]), std::fabs(bound[2]), std::fabs(bound[3])});
    const double* side[4] = {u, u, w, w};
    for (int k = 0; k < 4; ++k) {
        double sign = k % 2 == 0 ? 1 : -1;  // lower bounds keep the side's direction, upper bounds flip it
        double slack = 1e-9 * scale;
        for (int attempt = 0;; ++attempt) {
            if (attempt == 40) return ShadowVolume{};  // cannot be made to hold: no volume, test always
            double limit = bound[k] - sign * slack, n[3], nl = 0;
            v.rect[k] = limit;
            for (int j = 0; j < 3; ++j) {
                n[j] = sign * (side[k][j] - limit * d[j]);
                nl += n[j] * n[j];
            }
            nl = 1 / std::sqrt(nl);
            for (int j = 0; j < 3; ++j) v.normal[k][j] = float(n[j] * nl);
            // Every corner strictly inside the stored plane, by more than this double evaluation can err.
            bool holds = true;
            for (int i = 0; i < 8; ++i) {
                double s =
                    v.normal[k][0] * corner[i][0] + v.normal[k][1] * corner[i][1] + v.normal[k][2] * corner[i][2];
                holds &= s > 1e-12 * corner_size[i];
            }
            if (holds) break;
            slack = slack * 4 + 1e-7 * scale;
        }
    }
    // Closing distance: from the light to the nearest point of the padded box, shortened for rounding.
    double q[3] = {0, 0, 0}, dist2 = 0;
    for (int i = 0; i < 3; ++i) {
        double t =
            -(d[0] * box.axis[i][0] + d[1] * box.axis[i][1] + d[2] * box.axis[i][2]) * len;  // (light - c) . axis
        t = std::max(-half[i], std::min(half[i], t));
        for (int k = 0; k < 3; ++k) q[k] += t * box.axis[i][k];
    }
    for (int k = 0; k < 3; ++k) dist2 += (c[k] + q[k] - light[k]) * (c[k] + q[k] - light[k]);
    v.near = std::sqrt(dist2) * (1 - 1e-7);
    for (int k = 0; k < 3; ++k) {
        v.direction[k] = d[k];
        v.across[0][k] = u[k];
        v.across[1][k] = w[k];
    }
    v.valid = true;
    return v;
}

// Conservative membership: true for every point a triangle in the box can shadow.
inline bool inside_shadow_volume(const ShadowVolume& v, const double* light, const double* p) {
    if (!v.valid) return true;
    double e[3] = {p[0] - light[0], p[1] - light[1], p[2] - light[2]};
    double dist = std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
    if (dist < v.near) return false;
    for (const float* n : v.normal)
        if (n[0] * e[0] + n[1] * e[1] + n[2] * e[2] < -1e-9 * dist) return false;
    return true;
}
}  // namespace CB_LANES
}  // namespace cb
