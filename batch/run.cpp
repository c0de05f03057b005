#include "run.h"

#include <algorithm>
#include <atomic>
#include <mutex>
#include <thread>

#include "parallel.h"

namespace cb {

std::vector<BakeResult> run_batch(const std::vector<BakeRequest>& requests, const std::vector<size_t>& order,
                                  const BatchRun& run, const std::function<void(size_t)>& started,
                                  const std::function<void(size_t, const BakeResult&)>& finished) {
    unsigned cores = threads_or_all(run.cores);
    unsigned workers = unsigned(std::min<size_t>(run.jobs ? run.jobs : cores, std::max<size_t>(order.size(), 1)));
    CoreBudget budget(cores);
    std::vector<BakeResult> results(requests.size());
    std::atomic<size_t> next{0};
    std::mutex report;
    auto work = [&] {
        // A worker holds its core from its first file to its last, so that no other file's parallel stage
        // takes it in between and finds three threads on two cores.
        thread_core_budget() = &budget;
        bool holding = false;
        for (size_t k; (k = next.fetch_add(1)) < order.size();) {
            size_t i = order[k];
            if (!holding) {
                budget.take();
                holding = true;
            }
            {
                std::lock_guard<std::mutex> lock(report);
                if (started) started(i);
            }
            results[i] = bake_file(requests[i]);
            std::lock_guard<std::mutex> lock(report);
            if (finished) finished(i, results[i]);
        }
        if (holding) budget.give();
        thread_core_budget() = nullptr;
    };
    std::vector<std::thread> pool;
    for (unsigned w = 1; w < workers; ++w) pool.emplace_back(work);
    work();
    for (std::thread& t : pool) t.join();
    return results;
}

}  // namespace cb
