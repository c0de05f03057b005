// Where the tests find the shared scenes (../shared/data beside the checkout): the folder compiled in
// (CB_SHARED_DATA_DEFAULT) unless CB_SHARED_DATA_DIR names another. The suite's run without shared data
// names a folder that does not exist, as a user's clone has none. Included in every test source by the
// build (CB_SHARED_DATA expands to a call of this).
#pragma once

#include <cstdlib>
#include <string>

inline const char* cb_shared_data_dir() {
    const char* dir = std::getenv("CB_SHARED_DATA_DIR");
    return dir && *dir ? dir : CB_SHARED_DATA_DEFAULT;
}

#ifdef CB_CLI_DEFAULT
// The clusterbake binary the command-line tests run (CB_CLI expands to a call of this): the build's own,
// unless CB_CLI_UNDER_TEST names another, as the sanitizer build's (scripts/fuzz-smoke.sh).
inline std::string cb_cli_path() {
    const char* tool = std::getenv("CB_CLI_UNDER_TEST");
    return tool && *tool ? tool : CB_CLI_DEFAULT;
}
#endif
