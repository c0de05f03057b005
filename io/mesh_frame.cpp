#include "mesh_frame.h"

#include <algorithm>
#include <cmath>

#include "parallel.h"

namespace cb {
namespace {

// Per axis box of xyz triples; lo > hi when there are none.
template <class T>
void axis_box(const std::vector<T>& xyz, double lo[3], double hi[3]) {
    for (int k = 0; k < 3; ++k) {
        lo[k] = INFINITY;
        hi[k] = -INFINITY;
    }
    for (size_t i = 0; i < xyz.size(); ++i) {
        double v = double(xyz[i]);
        lo[i % 3] = std::min(lo[i % 3], v);
        hi[i % 3] = std::max(hi[i % 3], v);
    }
}

// A float c with x - c exact in float for every float x in [lo, hi], or 0. Sterbenz's lemma: for floats x
// and c with c/2 <= x <= 2c, x - c is a float. c is the float nearest the box centre, so lo <= c <= hi;
// when c/2 <= lo and hi <= 2c, every x of the axis satisfies c/2 <= lo <= x <= hi <= 2c (mirrored for
// negative boxes), and its subtraction is exact. Otherwise the box nearly reaches 0 and recentring gains
// less than a factor of 3 in magnitude: 0. Also 0 when |c| is within the mesh's largest side, where floats
// already hold positions to float precision relative to the mesh's size.
float exact_offset(float lo, float hi, double largest_side) {
    const float c = float(0.5 * (double(lo) + double(hi)));
    const bool positive = lo > 0 && 0.5 * double(c) <= lo && hi <= 2.0 * double(c);
    const bool negative = hi < 0 && 0.5 * double(c) >= hi && lo >= 2.0 * double(c);
    if (!(positive || negative) || std::fabs(double(c)) <= largest_side) return 0;
    return c;
}

}  // namespace

Origin store_centred(const std::vector<double>& xyz, std::vector<float>& positions) {
    Origin origin = {0, 0, 0};
    if (xyz.empty()) return origin;
    double lo[3], hi[3];
    axis_box(xyz, lo, hi);
    // The centre rounded to a multiple of a power of two near 1/256 of the mesh's largest side: coordinates
    // on a coarser binary grid (0, whole numbers, floats written out as text) then stay exact.
    const double side = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
    const double step = side > 0 ? std::ldexp(1.0, std::ilogb(side) - 8) : 1.0;
    for (int k = 0; k < 3; ++k) origin[k] = std::nearbyint(0.5 * (lo[k] + hi[k]) / step) * step;
    positions.resize(xyz.size());
    for (size_t i = 0; i < xyz.size(); ++i) positions[i] = float(xyz[i] - origin[i % 3]);
    return origin;
}

Origin shift_exactly(std::vector<float>& positions, unsigned threads) {
    Origin origin = {0, 0, 0};
    if (positions.empty()) return origin;
    // Both passes over parts of whole vertices: a large scan's positions are hundreds of megabytes.
    const Parts parts(positions.size() / 3, size_t(1) << 18);
    float lo[3], hi[3];
    parallel_box(
        parts, threads, [&](size_t v, int k) { return positions[v * 3 + k]; }, lo, hi);
    const double side = std::max({double(hi[0]) - lo[0], double(hi[1]) - lo[1], double(hi[2]) - lo[2]});
    float c[3];
    for (int k = 0; k < 3; ++k) {
        c[k] = exact_offset(lo[k], hi[k], side);
        origin[k] = c[k];
    }
    if (c[0] == 0 && c[1] == 0 && c[2] == 0) return origin;
    parallel_for(parts.count(), threads, [&](size_t p) {
        for (size_t v = parts.first(p); v < parts.last(p); ++v)
            for (int k = 0; k < 3; ++k) positions[v * 3 + k] -= c[k];  // exact, as proven above
    });
    return origin;
}

Transform with_origin(const Transform& t, const Origin& o) {
    if (o[0] == 0 && o[1] == 0 && o[2] == 0) return t;
    Transform r = t;
    for (int row = 0; row < 3; ++row) r[12 + row] = t[row] * o[0] + t[4 + row] * o[1] + t[8 + row] * o[2] + t[12 + row];
    return r;
}

}  // namespace cb
