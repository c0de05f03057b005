// Frees a vector's storage at once. `v = {}` does not: it picks the initializer-list assignment, which empties
// the vector and keeps its capacity, as `clear()` does.
#pragma once

namespace cb {

template <class Vector>
void free_storage(Vector& v) {
    Vector().swap(v);
}

}  // namespace cb
