// The one thread pool shape the offline stages use: items [0, n) handed out one at a time from a shared
// counter, so uneven items balance; the calling thread works too. Determinism is the caller's: each item
// writes only its own output.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <mutex>
#include <system_error>
#include <thread>
#include <vector>

namespace cb {

// Cores shared by jobs that run side by side (`clusterbake batch`): each job holds one core while it runs
// (take, which may overdraw for a moment), and a parallel_for on a thread with the budget installed starts
// a helper thread only for a core that is idle (try_take), even in the middle of its items, so that one
// large file left alone at the end of a batch gets the cores the small ones gave back.
//
// A batch bakes each file in a process of its own: the budget then lives in memory the processes share
// (its atomics are lock-free, so they work there), and each process draws on it through a view that
// counts in `held` what it has taken and not given back, so that the cores of a process that dies with
// helper threads running are given back (reclaim).
class CoreBudget {
public:
    explicit CoreBudget(unsigned cores) : own_(int(cores)) {}
    // A view of `shared` whose takes are counted in `held` (memory shared with whoever reclaims them).
    CoreBudget(CoreBudget& shared, std::atomic<int>& held) : idle_(shared.idle_), held_(&held) {}
    CoreBudget(const CoreBudget&) = delete;
    CoreBudget& operator=(const CoreBudget&) = delete;

    void take() {
        count(1);
        idle_->fetch_sub(1);
    }
    bool try_take() {
        // Counted before it is taken and uncounted after it is given: a process killed in between gives
        // back one core too many at worst, never loses one.
        for (int n = idle_->load(); n > 0;) {
            count(1);
            if (idle_->compare_exchange_weak(n, n - 1)) return true;
            count(-1);
        }
        return false;
    }
    void give(size_t cores = 1) {
        idle_->fetch_add(int(cores));
        count(-int(cores));
    }
    // Gives back what a view counted in `held` still holds (its process has ended).
    void reclaim(std::atomic<int>& held) { give(size_t(std::max(0, held.exchange(0)))); }

private:
    void count(int n) {
        if (held_) held_->fetch_add(n);
    }
    static_assert(std::atomic<int>::is_always_lock_free, "a budget shared between processes needs lock-free atomics");
    std::atomic<int> own_{0};
    std::atomic<int>* idle_ = &own_;
    std::atomic<int>* held_ = nullptr;
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
// or, under a CoreBudget, on as many of them as there are idle cores as it goes. An exception thrown by
// body (std::bad_alloc under a memory limit) stops the items not yet started and is rethrown here once
// every thread has joined; a helper thread that cannot be started leaves its items to the others.
template <class Body>
void parallel_for(size_t n, unsigned threads, Body&& body) {
    unsigned count = threads_or_all(threads);
    count = unsigned(std::min<size_t>(count, std::max<size_t>(n, 1)));
    std::atomic<size_t> next{0};
    std::exception_ptr failed;
    std::mutex failing;
    auto work = [&] {
        try {
            for (size_t i; (i = next.fetch_add(1)) < n;) body(i);
        } catch (...) {
            next = n;
            std::lock_guard<std::mutex> lock(failing);
            if (!failed) failed = std::current_exception();
        }
    };
    std::vector<std::thread> pool;
    pool.reserve(count - 1);
    // False when no thread could be started (the process is out of threads or memory).
    auto start = [&] {
        try {
            pool.emplace_back(work);
            return true;
        } catch (const std::system_error&) {
            return false;
        }
    };
    CoreBudget* budget = thread_core_budget();
    if (!budget) {
        for (unsigned t = 1; t < count; ++t)
            if (!start()) break;
        work();
    } else {
        auto recruit = [&] {
            while (pool.size() + 1 < count && budget->try_take())
                if (!start()) {
                    budget->give();
                    break;
                }
        };
        try {
            recruit();
            for (size_t i; (i = next.fetch_add(1)) < n; recruit()) body(i);
        } catch (...) {
            next = n;
            std::lock_guard<std::mutex> lock(failing);
            if (!failed) failed = std::current_exception();
        }
    }
    for (std::thread& t : pool) t.join();
    if (budget) budget->give(pool.size());
    if (failed) std::rethrow_exception(failed);
}

}  // namespace cb
