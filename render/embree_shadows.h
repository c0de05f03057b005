// The same shadow questions asked of Embree's rays (rtcOccluded1), for comparing pictures: every instance's
// triangles placed in world space and rounded to float, as an engine would hand them to a ray tracer.
#pragma once

#include <cb_asset.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "scene_query.h"

namespace cb {

class EmbreeShadows {
public:
    // Builds the Embree scene of the level's triangles. `one_sided`: a triangle blocks only when the light
    // is behind it (double-sided ones always), as the runtime's one-sided mode. Throws std::runtime_error
    // when Embree fails.
    EmbreeShadows(const LevelInput& level, bool one_sided, unsigned threads);
    ~EmbreeShadows();
    EmbreeShadows(const EmbreeShadows&) = delete;
    EmbreeShadows& operator=(const EmbreeShadows&) = delete;

    // Per point (xyz, world), 1 when the ray from it towards `light` hits a triangle at a parameter in
    // [shadow_from(point, light, bias), 1], the runtime's self-shadowing rule (cb_segment.h) in Embree's float
    // arithmetic. With `sun`, `light` is the direction toward a sun: the ray runs along it from
    // sun_from(light, bias) on, without end.
    std::vector<uint8_t> occluded(const double* light, double bias, const double* points, size_t count,
                                  bool sun = false) const;

    double build_seconds() const { return build_seconds_; }

    struct Scene;  // Embree's objects and the triangles they read (embree_shadows.cpp)

private:
    std::unique_ptr<Scene> scene_;
    unsigned threads_;
    double build_seconds_ = 0;
};

}  // namespace cb
