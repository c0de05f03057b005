// Where the tests find the shared scenes (../shared/data beside the checkout): the folder compiled in
// (CB_SHARED_DATA_DEFAULT) unless CB_SHARED_DATA_DIR names another. The suite's run without shared data
// names a folder that does not exist, as a user's clone has none. Included in every test source by the
// build (CB_SHARED_DATA expands to a call of this).
#pragma once

#include <cstdlib>

inline const char* cb_shared_data_dir() {
    const char* dir = std::getenv("CB_SHARED_DATA_DIR");
    return dir && *dir ? dir : CB_SHARED_DATA_DEFAULT;
}
