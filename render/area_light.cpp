#include "area_light.h"

#include <algorithm>
#include <cmath>

#include "vec3.h"

namespace cb {

namespace {

constexpr double pi = 3.14159265358979323846;

// SplitMix64: a small generator with a fixed sequence on every platform (the standard distributions are
// not specified bit for bit).
struct SplitMix64 {
    uint64_t state;
    uint64_t next() {
        uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
        return z ^ (z >> 31);
    }
    double unit() { return double(next() >> 11) * 0x1.0p-53; }  // [0, 1)
};

// Shirley and Chiu's concentric map of the square [-1, 1]^2 onto the unit disc.
void square_to_disc(double a, double b, double& x, double& y) {
    if (a == 0 && b == 0) return void(x = y = 0);
    double r, phi;
    if (std::fabs(a) > std::fabs(b)) {
        r = a;
        phi = pi / 4 * (b / a);
    } else {
        r = b;
        phi = pi / 2 - pi / 4 * (a / b);
    }
    x = r * std::cos(phi);
    y = r * std::sin(phi);
}

}  // namespace

std::vector<double> area_light_samples(const AreaLight& light, const double* facing) {
    // The light's plane: spanned by u and v, perpendicular to the direction to `facing`.
    double n[3] = {facing[0] - light.centre[0], facing[1] - light.centre[1], facing[2] - light.centre[2]};
    if (!(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] > 0)) {
        n[0] = 0;
        n[1] = 1;
        n[2] = 0;
    }
    normalise(n);
    int least = 0;  // the axis least along n makes the first side
    for (int k = 1; k < 3; ++k)
        if (std::fabs(n[k]) < std::fabs(n[least])) least = k;
    double axis[3] = {0, 0, 0}, u[3], v[3];
    axis[least] = 1;
    u[0] = axis[1] * n[2] - axis[2] * n[1];
    u[1] = axis[2] * n[0] - axis[0] * n[2];
    u[2] = axis[0] * n[1] - axis[1] * n[0];
    normalise(u);
    v[0] = n[1] * u[2] - n[2] * u[1];
    v[1] = n[2] * u[0] - n[0] * u[2];
    v[2] = n[0] * u[1] - n[1] * u[0];

    const uint32_t count = light.samples;
    const uint32_t rows = std::max<uint32_t>(1, uint32_t(std::lround(std::sqrt(double(count)))));
    SplitMix64 random{1};
    std::vector<double> out;
    out.reserve(size_t(count) * 3);
    for (uint32_t row = 0; row < rows; ++row) {
        const uint32_t first = uint32_t(uint64_t(count) * row / rows),
                       last = uint32_t(uint64_t(count) * (row + 1) / rows);
        for (uint32_t cell = 0; cell < last - first; ++cell) {
            // A point of the cell, in [-1, 1]^2.
            double a = (cell + random.unit()) / (last - first) * 2 - 1, b = (row + random.unit()) / rows * 2 - 1;
            double x = a, y = b, half = 0.5 * light.size;
            if (light.shape == AreaShape::disc) square_to_disc(a, b, x, y);
            for (int k = 0; k < 3; ++k) out.push_back(light.centre[k] + half * (x * u[k] + y * v[k]));
        }
    }
    return out;
}

}  // namespace cb
