// Vectors whose new elements are left unset instead of zeroed: for large arrays that a parallel pass then
// fills whole. A fresh large block comes from the kernel already zero; zeroing it again on the allocating
// thread faults in every page there, serially, before the parallel pass touches it.
#pragma once

#include <memory>
#include <utility>
#include <vector>

namespace cb {

template <class T>
struct UnsetAllocator : std::allocator<T> {
    template <class U>
    struct rebind {
        using other = UnsetAllocator<U>;
    };
    UnsetAllocator() = default;
    template <class U>
    UnsetAllocator(const UnsetAllocator<U>&) noexcept {}
    // Default-initialise (nothing, for the plain types this is for) where the vector would value-initialise.
    template <class U, class... Args>
    void construct(U* p, Args&&... args) {
        if constexpr (sizeof...(Args) == 0)
            ::new (static_cast<void*>(p)) U;
        else
            ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
    }
};

template <class T>
using UnsetVector = std::vector<T, UnsetAllocator<T>>;

}  // namespace cb
