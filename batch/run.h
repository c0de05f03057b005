// Bakes many files side by side: `jobs` files at once, largest first, sharing the machine's cores through
// a CoreBudget so that a file's parallel stages use the cores other files leave idle. Every result is what
// bake_file gives for its request alone, whatever the order or the thread count.
#pragma once

#include <functional>
#include <vector>

#include "bake_file.h"

namespace cb {

struct BatchRun {
    unsigned jobs = 0;   // files at once; 0: one per core
    unsigned cores = 0;  // cores to share; 0: all hardware threads
};

// `started(i)` and `finished(i, result)` are called as request i starts and ends, one call at a time (from
// the worker threads, under a lock). `order` lists the requests in the order to start them.
std::vector<BakeResult> run_batch(const std::vector<BakeRequest>& requests, const std::vector<size_t>& order,
                                  const BatchRun& run, const std::function<void(size_t)>& started,
                                  const std::function<void(size_t, const BakeResult&)>& finished);

}  // namespace cb
