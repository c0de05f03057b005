// The fixed lights the measuring tools place about a scene (the report's and the heat map's), so that every
// run asks the same questions of it.
#pragma once

#include <cstdint>
#include <vector>

namespace cb {

// Fixed light positions around the world box [lo, hi]: above and to one side, then others around it.
std::vector<double> report_lights(const double* lo, const double* hi, uint32_t count);

// Fixed sun directions (toward the sun, +y up as glTF has it): high, then low, then others around.
std::vector<double> report_suns(uint32_t count);

}  // namespace cb
