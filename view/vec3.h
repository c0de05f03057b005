// Small double 3-vector helpers the viewing code shares beside cb_math.h's dot3 and cross3.
#pragma once

#include <detail/cb_math.h>

#include <cmath>

namespace cb {

// `v` scaled to unit length in place; a zero vector is left as it is.
inline void normalise(double* v) {
    const double l = std::sqrt(math::dot3(v, v));
    if (l > 0)
        for (int k = 0; k < 3; ++k) v[k] /= l;
}

}  // namespace cb
