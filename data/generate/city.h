// A generated city for tests and benchmarks of whole levels: one ground plane of two triangles (a large
// flat receiver) and instances of 20 building meshes (towers with a pyramid roof, 62 to 290 triangles) on a
// square grid, each with a random yaw and every seventh mirrored. Deterministic for a seed.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>
#include <string>

#include "scene.h"

namespace cb::generate {

// A tower w x d x h whose walls are cut into s x s quads, with a pyramid roof, standing on z = 0 around the
// mesh's origin.
inline Mesh tower(const std::string& name, double w, double d, double h, uint32_t s) {
    Mesh m;
    m.name = name;
    auto vertex = [&](double x, double y, double z) {
        m.positions.insert(m.positions.end(), {float(x), float(y), float(z)});
        return uint32_t(m.vertex_count() - 1);
    };
    const double corner[5][2] = {{-w / 2, -d / 2}, {w / 2, -d / 2}, {w / 2, d / 2}, {-w / 2, d / 2}, {-w / 2, -d / 2}};
    for (int side = 0; side < 4; ++side) {
        const uint32_t first = uint32_t(m.vertex_count());
        for (uint32_t j = 0; j <= s; ++j)
            for (uint32_t i = 0; i <= s; ++i) {
                const double t = double(i) / s;
                vertex(corner[side][0] + t * (corner[side + 1][0] - corner[side][0]),
                       corner[side][1] + t * (corner[side + 1][1] - corner[side][1]), h * j / s);
            }
        for (uint32_t j = 0; j < s; ++j)
            for (uint32_t i = 0; i < s; ++i) {
                const uint32_t a = first + j * (s + 1) + i;  // counter-clockwise seen from outside
                m.indices.insert(m.indices.end(), {a, a + 1, a + s + 2, a, a + s + 2, a + s + 1});
            }
    }
    const uint32_t apex = vertex(0, 0, h + 0.25 * std::min(w, d));
    uint32_t top[4];
    for (int c = 0; c < 4; ++c) top[c] = vertex(corner[c][0], corner[c][1], h);
    for (int c = 0; c < 4; ++c) m.indices.insert(m.indices.end(), {top[c], top[(c + 1) % 4], apex});
    m.primitives.push_back({0, uint32_t(m.triangle_count()), false});
    return m;
}

// The city: mesh 0 the ground (side x side metres around the origin, at z = 0), meshes 1-20 the buildings,
// instance 0 the ground, then `buildings` building instances on a grid 30 m apart.
inline Scene city(uint32_t buildings, uint64_t seed = 1) {
    Scene scene;
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    const uint32_t per_row = uint32_t(std::ceil(std::sqrt(double(std::max(buildings, 1u)))));
    const double spacing = 30, side = spacing * per_row + 40;
    Mesh ground;
    ground.name = "ground";
    ground.positions = {float(-side / 2), float(-side / 2), 0, float(side / 2),  float(-side / 2), 0,
                        float(side / 2),  float(side / 2),  0, float(-side / 2), float(side / 2),  0};
    ground.indices = {0, 1, 2, 0, 2, 3};
    ground.primitives.push_back({0, 2, false});
    scene.meshes.push_back(ground);
    for (uint32_t b = 0; b < 20; ++b)
        scene.meshes.push_back(
            tower("building " + std::to_string(b), 8 + 12 * u(rng), 8 + 12 * u(rng), 5 + 25 * u(rng), 3 + b % 4));
    scene.instances.push_back({0, identity_transform(), "ground"});
    for (uint32_t i = 0; i < buildings; ++i) {
        const double yaw = 2 * M_PI * u(rng), c = std::cos(yaw), s = std::sin(yaw);
        const double mirror = i % 7 == 3 ? -1.0 : 1.0;  // x mirrored: the winding turns over
        const double x = (double(i % per_row) - 0.5 * (per_row - 1)) * spacing,
                     y = (double(i / per_row) - 0.5 * (per_row - 1)) * spacing;
        Transform m = {mirror * c, mirror * s, 0, 0, -s, c, 0, 0, 0, 0, 1, 0, x, y, 0, 1};
        scene.instances.push_back({1 + uint32_t(rng() % 20), m, "building"});
    }
    return scene;
}

}  // namespace cb::generate
