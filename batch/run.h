// Bakes many files side by side, each in a process of its own: `jobs` files at once, largest first, sharing
// the machine's cores through a CoreBudget so that a file's parallel stages use the cores other files leave
// idle. A file whose process dies (a crash, an abort, the kernel's out-of-memory killer) fails alone, with
// one line, and the others bake. Every other result is what bake_file gives for its request alone, whatever
// the order, the number at once or the thread count.
#pragma once

#include <functional>
#include <vector>

#include "bake_file.h"

namespace cb {

struct BatchRun {
    unsigned jobs = 0;   // files at once; 0: one per core
    unsigned cores = 0;  // cores to share; 0: all hardware threads
};

// `started(i)` and `finished(i, result)` are called as request i starts and ends, one call at a time, on
// the calling thread. `order` lists the requests in the order to start them.
//
// Each request is baked by bake_file in a child forked from this process, under its memory budget as a
// hard limit (limit_process_memory), and its result sent back through a pipe. The calling process must run
// no other thread (a fork copies one thread, and any lock another one held): throws std::logic_error
// otherwise, and std::runtime_error when the cores cannot be shared. A child that dies is reported
// failed, "FILE: bake killed by signal 11 (SIGSEGV)", and the temporary it may have left beside its
// output is removed: its output is untouched, as for any failure. Children die with this process.
std::vector<BakeResult> run_batch(const std::vector<BakeRequest>& requests, const std::vector<size_t>& order,
                                  const BatchRun& run, const std::function<void(size_t)>& started,
                                  const std::function<void(size_t, const BakeResult&)>& finished);

}  // namespace cb
