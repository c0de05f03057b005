// The one thread pool shape the offline stages use: items [0, n) handed out one at a time from a shared
// counter, so uneven items balance; the calling thread works too. Determinism is the caller's: each item
// writes only its own output.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <exception>
#include <mutex>
#include <system_error>
#include <thread>
#include <vector>

#include "core_budget.h"

namespace cb {

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

// [0, n) cut into at most 64 parts of at least `smallest` elements (the last one shorter), the items of a
// parallel_for over a long array.
struct Parts {
    Parts(size_t n, size_t smallest) : n(n), size(std::max<size_t>({smallest, (n + 63) / 64, 1})) {}
    size_t count() const { return (n + size - 1) / size; }
    size_t first(size_t p) const { return p * size; }
    size_t last(size_t p) const { return std::min(n, (p + 1) * size); }
    size_t n, size;
};

// The axis box of items [0, parts.n), `coord(i, k)` giving item i's coordinate on axis k as a T: each part's
// box on `threads` threads (0: all), then folded. Minima and maxima are exact, so the box does not depend on
// the parts. lo > hi on every axis when there are no items.
template <class T, class Coord>
void parallel_box(const Parts& parts, unsigned threads, Coord&& coord, T lo[3], T hi[3]) {
    std::vector<std::array<T, 6>> part_box(parts.count());
    parallel_for(parts.count(), threads, [&](size_t p) {
        std::array<T, 6> b = {INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY};
        for (size_t i = parts.first(p); i < parts.last(p); ++i)
            for (int k = 0; k < 3; ++k) {
                const T c = coord(i, k);
                b[k] = std::min(b[k], c);
                b[3 + k] = std::max(b[3 + k], c);
            }
        part_box[p] = b;
    });
    for (int k = 0; k < 3; ++k) {
        lo[k] = INFINITY;
        hi[k] = -INFINITY;
    }
    for (const auto& b : part_box)
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], b[k]);
            hi[k] = std::max(hi[k], b[3 + k]);
        }
}

}  // namespace cb
