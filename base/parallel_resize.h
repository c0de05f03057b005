// Sizing a large zeroed vector with its fresh pages faulted in by several threads. A vector's resize zeroes
// its new elements on the calling thread, and the first write to each fresh page is a page fault: on a
// virtual machine one costs microseconds, so an array of hundreds of megabytes would take tenths of a second
// on one core while the others wait. The pages are asked for in parallel parts first; the zeroing then runs
// over memory that is already there.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif

#include "parallel.h"

namespace cb {

// v.resize(n), value-initialising the new elements, on `threads` threads for the page faults (0: all).
// Where the system cannot populate pages ahead (not Linux, or a kernel before 5.14), the same as resize.
template <class T, class A>
void parallel_resize(std::vector<T, A>& v, size_t n, unsigned threads) {
#if defined(__linux__) && defined(MADV_POPULATE_WRITE)
    constexpr size_t part_bytes = size_t(4) << 20;
    if (n > v.capacity() && (n - v.size()) * sizeof(T) >= 2 * part_bytes) {
        v.reserve(n);
        const uintptr_t page = uintptr_t(sysconf(_SC_PAGESIZE));
        // Whole pages within the new elements' bytes: the pages around them belong to the vector too.
        const uintptr_t first = (reinterpret_cast<uintptr_t>(v.data() + v.size()) + page - 1) / page * page;
        const uintptr_t last = reinterpret_cast<uintptr_t>(v.data() + n) / page * page;
        if (last > first) {
            const size_t parts = (last - first + part_bytes - 1) / part_bytes;
            parallel_for(parts, threads, [&](size_t p) {
                const uintptr_t from = first + p * part_bytes, to = std::min<uintptr_t>(last, from + part_bytes);
                // A failure (EINVAL on an older kernel) leaves the pages to be faulted in by the zeroing.
                madvise(reinterpret_cast<void*>(from), to - from, MADV_POPULATE_WRITE);
            });
        }
    }
#endif
    v.resize(n);
}

}  // namespace cb
