// The one thread pool shape the offline stages use: items [0, n) handed out one at a time from a shared
// counter, so uneven items balance; the calling thread works too. Determinism is the caller's: each item
// writes only its own output.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <thread>
#include <vector>

namespace cb {

// Runs body(i) for every i in [0, n) on `threads` threads (0: all hardware threads; never more than n).
template <class Body>
void parallel_for(size_t n, unsigned threads, Body&& body) {
    unsigned count = threads ? threads : std::max(1u, std::thread::hardware_concurrency());
    count = unsigned(std::min<size_t>(count, std::max<size_t>(n, 1)));
    std::atomic<size_t> next{0};
    auto work = [&] {
        for (size_t i; (i = next.fetch_add(1)) < n;) body(i);
    };
    std::vector<std::thread> pool;
    for (unsigned t = 1; t < count; ++t) pool.emplace_back(work);
    work();
    for (std::thread& t : pool) t.join();
}

}  // namespace cb
