// What the shadow benchmarks share on Embree's side: its memory, counted by a device's monitor, a camera's
// visible points, the first hits of a grid of rays, and the shadow rays of a range of points.
#pragma once

#include <cb_segment.h>
#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <sys/types.h>
#include <vector>

namespace cb::bench {

// Bytes Embree's devices hold now and at most (embree_monitor, set with rtcSetDeviceMemoryMonitorFunction).
inline std::atomic<long long> embree_bytes{0}, embree_peak{0};
inline bool embree_monitor(void*, ssize_t bytes, bool) {
    long long now = embree_bytes += bytes;
    long long peak = embree_peak.load();
    while (now > peak && !embree_peak.compare_exchange_weak(peak, now)) {}
    return true;
}

// The first hits (xyz doubles) of a view x view grid of rays from `eye` along fw + spread (sx right + sy up),
// sx and sy from -1 to 1 across the grid, row by row; rays that hit nothing give no point.
inline std::vector<double> first_hits(RTCScene scene, const double* eye, const double* fw, const double* right,
                                      const double* up, int view, double spread) {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    std::vector<double> pts;
    for (int y = 0; y < view; ++y)
        for (int x = 0; x < view; ++x) {
            double sx = (x + 0.5) / view * 2 - 1, sy = (y + 0.5) / view * 2 - 1;
            RTCRayHit rh{};
            rh.ray.org_x = float(eye[0]);
            rh.ray.org_y = float(eye[1]);
            rh.ray.org_z = float(eye[2]);
            rh.ray.dir_x = float(fw[0] + spread * (sx * right[0] + sy * up[0]));
            rh.ray.dir_y = float(fw[1] + spread * (sx * right[1] + sy * up[1]));
            rh.ray.dir_z = float(fw[2] + spread * (sx * right[2] + sy * up[2]));
            rh.ray.tnear = 0;
            rh.ray.tfar = INFINITY;
            rh.ray.mask = 0xffffffff;
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rtcIntersect1(scene, &ctx, &rh);
            if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
            pts.insert(
                pts.end(),
                {rh.ray.org_x + double(rh.ray.tfar) * rh.ray.dir_x, rh.ray.org_y + double(rh.ray.tfar) * rh.ray.dir_y,
                 rh.ray.org_z + double(rh.ray.tfar) * rh.ray.dir_z});
        }
    return pts;
}

// Points [first, last) of `pts` (xyz doubles) against `light`, by rtcOccluded1 (packet 1) or rtcOccluded16
// (packet 16: 16 neighbouring points a packet): out[i] = 1 when the ray from point i to the light is blocked
// past the runtime's self-shadowing start (cb::shadow_from of the point, the light and `bias`). With `sun`,
// `light` is the direction toward a sun: every ray runs along it, from cb::sun_from on, without end.
inline void occluded_range(RTCScene scene, const double* pts, const double* light, size_t first, size_t last,
                           int packet, double bias, uint8_t* out, bool sun = false) {
    // Point i's ray in float: from the point toward the light (its far end at 1) or along the sun (no end).
    auto ray = [&](size_t i, float* dir, float& tnear, float& tfar) {
        const double* p = pts + i * 3;
        for (int k = 0; k < 3; ++k) dir[k] = float(sun ? light[k] : light[k] - p[k]);
        tnear = float(sun ? cb::sun_from(light, bias) : cb::shadow_from(p, light, bias));
        tfar = sun ? INFINITY : 1.0f;
    };
    RTCIntersectContext c;
    rtcInitIntersectContext(&c);
    if (packet == 1) {
        for (size_t i = first; i < last; ++i) {
            RTCRay r{};
            float dir[3];
            r.org_x = float(pts[i * 3]);
            r.org_y = float(pts[i * 3 + 1]);
            r.org_z = float(pts[i * 3 + 2]);
            ray(i, dir, r.tnear, r.tfar);
            r.dir_x = dir[0];
            r.dir_y = dir[1];
            r.dir_z = dir[2];
            r.mask = 0xffffffff;
            rtcOccluded1(scene, &c, &r);
            out[i] = r.tfar < 0;
        }
        return;
    }
    for (size_t at = first; at < last; at += 16) {
        alignas(64) RTCRay16 r{};
        alignas(64) int valid[16];
        for (size_t k = 0; k < 16; ++k) {
            const size_t i = std::min(at + k, last - 1);
            float dir[3];
            valid[k] = at + k < last ? -1 : 0;
            r.org_x[k] = float(pts[i * 3]);
            r.org_y[k] = float(pts[i * 3 + 1]);
            r.org_z[k] = float(pts[i * 3 + 2]);
            ray(i, dir, r.tnear[k], r.tfar[k]);
            r.dir_x[k] = dir[0];
            r.dir_y[k] = dir[1];
            r.dir_z[k] = dir[2];
            r.mask[k] = 0xffffffff;
        }
        rtcOccluded16(valid, scene, &c, &r);
        for (size_t k = 0; k < 16 && at + k < last; ++k) out[at + k] = r.tfar[k] < 0;
    }
}

}  // namespace cb::bench
