#include "lights.h"

#include <algorithm>

namespace cb {

std::vector<double> report_lights(const double* lo, const double* hi, uint32_t count) {
    // Directions from the centre, in units of the box's largest side: all outside the box.
    static const double offsets[6][3] = {{-0.8, 1.5, 0.3},   {1.4, 0.6, -0.9}, {0.2, 1.8, 1.3},
                                         {-1.3, -0.2, -1.1}, {0.9, -1.2, 1.0}, {-0.3, 0.9, -1.6}};
    double size = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-30});
    std::vector<double> out;
    for (uint32_t i = 0; i < count; ++i)
        for (int k = 0; k < 3; ++k)
            out.push_back(0.5 * (lo[k] + hi[k]) + offsets[i % 6][k] * size * (1 + 0.25 * (i / 6)));
    return out;
}

std::vector<double> report_suns(uint32_t count) {
    static const double directions[6][3] = {{-0.4, 1.0, 0.3},  {1.0, 0.2, -0.5}, {0.3, 0.7, 1.0},
                                            {-1.0, 0.5, -0.2}, {0.1, 1.0, -0.9}, {0.8, 0.1, 0.9}};
    std::vector<double> out;
    for (uint32_t i = 0; i < count; ++i) out.insert(out.end(), directions[i % 6], directions[i % 6] + 3);
    return out;
}

}  // namespace cb
