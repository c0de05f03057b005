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

// Cores shared by jobs that run side by side (`clusterbake batch`): each job holds one core while it runs
// (take, which may overdraw for a moment), and a parallel_for on a thread with the budget installed starts
// a helper thread only for a core that is idle (try_take), even in the middle of its items, so that one
// large file left alone at the end of a batch gets the cores the small ones gave back.
class CoreBudget {
public:
    explicit CoreBudget(unsigned cores) : idle_(int(cores)) {}
    void take() { idle_.fetch_sub(1); }
    bool try_take() {
        for (int n = idle_.load(); n > 0;)
            if (idle_.compare_exchange_weak(n, n - 1)) return true;
        return false;
    }
    void give(size_t cores = 1) { idle_.fetch_add(int(cores)); }

private:
    std::atomic<int> idle_;
};

// The budget that parallel_for calls on this thread draw their helpers from; none (null) by default.
inline CoreBudget*& thread_core_budget() {
    thread_local CoreBudget* budget = nullptr;
    return budget;
}

// A thread count as the options give it: `threads`, or every hardware thread for 0.
inline unsigned threads_or_all(unsigned threads) {
    return threads ? threads : std::max(1u, std::thread::hardware_concurrency());
}

// Runs body(i) for every i in [0, n) on `threads` threads (0: all hardware threads; never more than n),
// or, under a CoreBudget, on as many of them as there are idle cores as it goes.
template <class Body>
void parallel_for(size_t n, unsigned threads, Body&& body) {
    unsigned count = threads_or_all(threads);
    count = unsigned(std::min<size_t>(count, std::max<size_t>(n, 1)));
    std::atomic<size_t> next{0};
    auto work = [&] {
        for (size_t i; (i = next.fetch_add(1)) < n;) body(i);
    };
    std::vector<std::thread> pool;
    CoreBudget* budget = thread_core_budget();
    if (!budget) {
        for (unsigned t = 1; t < count; ++t) pool.emplace_back(work);
        work();
    } else {
        auto recruit = [&] {
            while (pool.size() + 1 < count && budget->try_take()) pool.emplace_back(work);
        };
        recruit();
        for (size_t i; (i = next.fetch_add(1)) < n; recruit()) body(i);
    }
    for (std::thread& t : pool) t.join();
    if (budget) budget->give(pool.size());
}

}  // namespace cb
