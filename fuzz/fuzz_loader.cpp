// libFuzzer target for one loader, chosen at compile time by CB_FUZZ_FORMAT (a cb::FileFormat value).
// A LoadError is the expected answer to bad bytes; anything else (crash, other exception, sanitizer
// report, leak, runaway memory) is a bug.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "load.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    constexpr cb::FileFormat format = cb::FileFormat::CB_FUZZ_FORMAT;
    try {
        cb::Scene scene = format == cb::FileFormat::gltf ? cb::load_gltf_memory(data, size, "fuzz", "")
                                                         : cb::load_mesh_memory(data, size, format, "fuzz");
        cb::validate_scene(scene, "fuzz");
    } catch (const cb::LoadError& e) {
        // The promise to users: one printable line naming the file.
        for (const char* c = e.what(); *c; ++c)
            if (*c == '\n' || static_cast<unsigned char>(*c) < 0x20) std::abort();
        if (std::strncmp(e.what(), "fuzz: ", 6) != 0) std::abort();
    }
    return 0;
}
