// Mesh frames: every loader stores a mesh's positions relative to an origin of the mesh's own, and every
// instance of the mesh carries that origin in the translation of its double transform
// (world = instance transform * translate(origin), scene.h). Float positions then keep float precision
// relative to the mesh's size, not to its distance from the world origin.
#pragma once

#include <array>
#include <vector>

#include "scene.h"

namespace cb {

using Origin = std::array<double, 3>;

// For coordinates read as doubles (text formats, double PLY properties): the origin is the centre of their
// box, computed in double (to 1/512 of the mesh's size), and positions become float(x - origin).
Origin store_centred(const std::vector<double>& xyz, std::vector<float>& positions);

// For coordinates that are floats already (glTF accessors, Draco, float PLY, binary STL): per axis, a float
// origin that every coordinate minus it is exact in float, so the world positions are the file's floats
// exactly; 0 on an axis where the mesh is not far from the world origin for its size. Shifts `positions`
// in place, on `threads` threads (0: all).
Origin shift_exactly(std::vector<float>& positions, unsigned threads = 1);

// t * translate(origin), exactly t when the origin is 0.
Transform with_origin(const Transform& t, const Origin& origin);

}  // namespace cb
