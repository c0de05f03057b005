// Deterministic random numbers for the clustering and the statistics: the same stream on every platform and
// compiler (std distributions are not), seeded per work item so results do not depend on threads.
#pragma once

#include <cstdint>

namespace cb {

// splitmix64's finaliser: well-spread seeds for children of a seed, and the step of SplitMix below.
inline uint64_t splitmix(uint64_t x) {
    x += 0x9e3779b97f4a7c15ULL;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
}

struct SplitMix {
    uint64_t state;
    uint64_t next() { return state = splitmix(state); }
    double uniform() { return double(next() >> 11) * 0x1.0p-53; }  // [0, 1)
};

}  // namespace cb
