// Test helper: every scene of ../shared/data that loads.
#pragma once

#include <filesystem>
#include <string>

#include "load.h"

namespace cb::test {

// Calls f(path, scene) for every mesh file under ../shared/data that loads (the invalid-input ones are the
// loader tests' business). Returns how many; 0 when the folder is absent.
template <class F>
size_t for_each_shared_scene(F&& f) {
    namespace fs = std::filesystem;
    fs::path root(CB_SHARED_DATA);
    if (!fs::exists(root)) return 0;
    size_t files = 0;
    for (const auto& e : fs::recursive_directory_iterator(root)) {
        if (!e.is_regular_file() || format_from_path(e.path().string()) == FileFormat::unknown) continue;
        Scene scene;
        try {
            scene = load_scene(e.path().string());
        } catch (const LoadError&) {
            continue;
        }
        ++files;
        f(e.path().string(), scene);
    }
    return files;
}

}  // namespace cb::test
