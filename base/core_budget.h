// The cores that jobs running side by side share, and that parallel_for (parallel.h) draws its helper threads
// from when one is installed on the calling thread.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>

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

}  // namespace cb
