// Pages asked for ahead, in parallel. The first touch of each fresh page is a page fault: on a virtual
// machine one costs microseconds, so an array of hundreds of megabytes sized (or a file mapping read) on one
// thread takes tenths of a second on one core while the others wait. Here the pages are asked for in parts
// on several threads first; the zeroing of a vector's resize, or the reads of a mapping, then run over
// memory that is already there.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif

#include "parallel.h"

namespace cb {

#if defined(__linux__) && defined(MADV_POPULATE_WRITE) && defined(MADV_POPULATE_READ)
#define CB_CAN_POPULATE_PAGES 1
constexpr bool can_populate_pages = true;
constexpr int populate_for_writing = MADV_POPULATE_WRITE, populate_for_reading = MADV_POPULATE_READ;
#else
constexpr bool can_populate_pages = false;
constexpr int populate_for_writing = 0, populate_for_reading = 0;
#endif
constexpr size_t populate_part_bytes = size_t(4) << 20;

// Asks for the pages of [begin, begin + bytes) ahead of their first use, in parts of populate_part_bytes on
// `threads` threads (0: all): `advice` is populate_for_writing for private memory about to be written,
// populate_for_reading for a file mapping about to be read. A part the system refuses (a kernel before 5.14)
// is left to be faulted in by its first use; without can_populate_pages, nothing is done.
inline void populate_pages([[maybe_unused]] void* begin, [[maybe_unused]] size_t bytes, [[maybe_unused]] int advice,
                           [[maybe_unused]] unsigned threads) {
#if defined(CB_CAN_POPULATE_PAGES)
    uint8_t* const at = static_cast<uint8_t*>(begin);
    parallel_for((bytes + populate_part_bytes - 1) / populate_part_bytes, threads, [&](size_t p) {
        const size_t from = p * populate_part_bytes;
        madvise(at + from, std::min(populate_part_bytes, bytes - from), advice);
    });
#endif
}

// v.resize(n), value-initialising the new elements, on `threads` threads for the page faults (0: all).
// Where the system cannot populate pages ahead, the same as resize.
template <class T, class A>
void parallel_resize(std::vector<T, A>& v, size_t n, [[maybe_unused]] unsigned threads) {
#if defined(CB_CAN_POPULATE_PAGES)
    if (n > v.capacity() && (n - v.size()) * sizeof(T) >= 2 * populate_part_bytes) {
        v.reserve(n);
        const uintptr_t page = uintptr_t(sysconf(_SC_PAGESIZE));
        // Whole pages within the new elements' bytes: the pages around them belong to the vector too.
        const uintptr_t first = (reinterpret_cast<uintptr_t>(v.data() + v.size()) + page - 1) / page * page;
        const uintptr_t last = reinterpret_cast<uintptr_t>(v.data() + n) / page * page;
        if (last > first) populate_pages(reinterpret_cast<void*>(first), last - first, populate_for_writing, threads);
    }
#endif
    v.resize(n);
}

}  // namespace cb
