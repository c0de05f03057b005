// Meshes on which shadow tests are hardest, with the lights that make them so, shared by the traversal
// tests (tests/test_shadow.cpp, tests/test_metric_tree.cpp): flat grids with lights in their plane, layers
// at scales where float products vanish, and needles fanned about a light among them.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace cb::test {

// "at 1e+06", "at 1e-12": the case's scale or offset in its name.
inline std::string at(double v) {
    char text[32];
    std::snprintf(text, sizeof text, " at %g", v);
    return text;
}

struct HardCase {
    std::string name;
    std::vector<float> positions;
    std::vector<uint32_t> indices;
    std::vector<std::array<double, 3>> lights;
};

// A flat, zero-thickness 8 x 8 grid (coplanar clusters, flat boxes) at z = 0 around (offset, offset). Lights:
// above, exactly in the plane (on the grid and beside it), inside a flat box, and 2e9 above (beyond
// float_safe, where the runtime's float filters give way to double tests).
inline HardCase flat_grid(double offset) {
    HardCase c{offset == 0 ? "flat grid" : "flat grid" + at(offset), {}, {}, {}};
    for (int j = 0; j <= 8; ++j)
        for (int i = 0; i <= 8; ++i)
            c.positions.insert(c.positions.end(), {float(offset + i), float(offset + j), 0.0f});
    for (uint32_t j = 0; j < 8; ++j)
        for (uint32_t i = 0; i < 8; ++i) {
            uint32_t a = j * 9 + i;
            c.indices.insert(c.indices.end(), {a, a + 1, a + 9, a + 1, a + 10, a + 9});
        }
    c.lights = {{offset + 4.3, offset + 3.7, 6},
                {offset + 4, offset + 4, 0},
                {offset - 3, offset + 4.5, 0},
                {offset + 2.5, offset + 2.5, 0},
                {offset + 4.2, offset + 3.9, 2e9}};
    return c;
}

// Two bumpy layers scaled by `scale` (1e-12: products of four sizes vanish in float; 1e-23: squares do), the
// light above both, beside and between them.
inline HardCase two_layers(double scale) {
    HardCase c{"two layers" + at(scale), {}, {}, {}};
    for (int layer = 0; layer < 2; ++layer) {
        const uint32_t base = uint32_t(c.positions.size() / 3), n = layer == 0 ? 10 : 5;
        for (uint32_t j = 0; j <= n; ++j)
            for (uint32_t i = 0; i <= n; ++i) {
                double x = layer == 0 ? i : 2.5 + i, y = layer == 0 ? j : 2.5 + j,
                       z = 4.0 * layer + 0.3 * std::sin(1.7 * i + 2.3 * j);
                c.positions.insert(c.positions.end(), {float(x * scale), float(y * scale), float(z * scale)});
            }
        for (uint32_t j = 0; j < n; ++j)
            for (uint32_t i = 0; i < n; ++i) {
                uint32_t a = base + j * (n + 1) + i;
                c.indices.insert(c.indices.end(), {a, a + 1, a + n + 1, a + 1, a + n + 2, a + n + 1});
            }
    }
    c.lights = {{5.1 * scale, 4.9 * scale, 9 * scale},
                {-6 * scale, 5 * scale, 4 * scale},
                {5.2 * scale, 4.7 * scale, 2 * scale}};
    return c;
}

// Long, thin triangles fanned around the origin, and a light among them (inside their boxes).
inline HardCase needles() {
    HardCase c{"needles", {}, {}, {{0.1, 0.05, 0.02}, {30, 5, 2}}};
    for (int i = 0; i < 40; ++i) {
        double a = i * 0.157;
        uint32_t b = uint32_t(c.positions.size() / 3);
        c.positions.insert(
            c.positions.end(),
            {0.0f, 0.0f, float(0.01 * i), float(20 * std::cos(a)), float(20 * std::sin(a)), float(0.01 * i),
             float(20 * std::cos(a + 1e-3)), float(20 * std::sin(a + 1e-3)), float(0.01 * i + 0.05)});
        c.indices.insert(c.indices.end(), {b, b + 1, b + 2});
    }
    return c;
}

}  // namespace cb::test
