// An area light as the point lights that sample it: a square or a disc facing a point of the scene,
// stratified so that the samples cover it evenly, jittered with a fixed seed so that pictures repeat.
#pragma once

#include <cstdint>
#include <vector>

namespace cb {

enum class AreaShape { square, disc };

struct AreaLight {
    double centre[3] = {0, 0, 0};
    double size = 1;        // the square's side, or the disc's diameter
    uint32_t samples = 16;  // point lights
    AreaShape shape = AreaShape::square;
};

// `light.samples` positions (xyz triples) on the light, which faces `facing` (its plane is perpendicular to
// the direction from its centre to `facing`; any plane through the centre when they coincide). The unit
// square is cut into that many cells of equal area, rows of nearly equal counts, and each cell gives one
// point at a pseudo-random place inside it; a disc takes the square's points through a mapping that keeps
// areas (Shirley and Chiu's concentric map), so its cells stay equal too.
std::vector<double> area_light_samples(const AreaLight& light, const double* facing);

}  // namespace cb
