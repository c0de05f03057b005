// Wall-clock timing of the offline tools and their benchmarks: seconds since a start, and the median of
// repeated timings (noise on a shared machine is one-sided, so the middle run says more than the mean).
#pragma once

#include <algorithm>
#include <chrono>
#include <vector>

namespace cb {

inline double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The upper median (the middle element of an odd count); 0 for none.
inline double median(std::vector<double> v) {
    if (v.empty()) return 0;
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
}

}  // namespace cb
