// Slabs: two parallel planes across an axis.
#include <algorithm>

#include "fitting.h"

namespace cb::fitting {

Slab fit_slab(const float axis_f[3], const double* world, size_t n) {
    Slab s;
    for (int k = 0; k < 3; ++k) s.axis[k] = axis_f[k];
    double a[3] = {axis_f[0], axis_f[1], axis_f[2]}, lo = INFINITY, hi = -INFINITY, scale = 0;
    for (size_t v = 0; v < n; ++v) {
        double d = dot3(world + v * 3, a);
        lo = std::min(lo, d);
        hi = std::max(hi, d);
        scale = std::max(
            scale,
            std::fabs(world[v * 3] * a[0]) + std::fabs(world[v * 3 + 1] * a[1]) + std::fabs(world[v * 3 + 2] * a[2]));
    }
    s.low = round_down(lo - measure_margin * scale);
    s.high = round_up(hi + measure_margin * scale);
    return s;
}

}  // namespace cb::fitting
