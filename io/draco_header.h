// What a Draco mesh stream declares before any of it is decoded: its face and point counts, read from the
// header and the start of the connectivity (Draco bitstream 2.2, the version KHR_draco_mesh_compression
// files carry). The Draco decoder allocates for these counts before it finds out whether the stream holds
// them, so the loader bounds them first (docs/SECURITY.md).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace cb {

struct DracoCounts {
    uint64_t faces = 0;
    uint64_t points = 0;  // encoded vertices for edgebreaker; decoded points can be up to 3 a face
};

// Reads the counts of the mesh stream `data[0..size)`. Returns an empty string, or what keeps them from
// being read ("not a Draco stream", "bitstream version 1.3 (2.2 or later is read)", "truncated header").
std::string read_draco_counts(const uint8_t* data, size_t size, DracoCounts& out);

}  // namespace cb
