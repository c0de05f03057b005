#include "draco_header.h"

#include <cstring>
#include <vector>

namespace cb {
namespace {

// A cursor over the stream that never reads past its end.
struct Reader {
    const uint8_t* data;
    size_t size;
    size_t at = 0;

    bool byte(uint8_t& v) {
        if (at >= size) return false;
        v = data[at++];
        return true;
    }
    // Draco's varUI32/varUI64: 7 bits per byte, least significant first.
    bool varint(uint64_t& v) {
        v = 0;
        for (int shift = 0; shift < 64; shift += 7) {
            uint8_t b;
            if (!byte(b)) return false;
            v |= uint64_t(b & 0x7f) << shift;
            if (!(b & 0x80)) return true;
        }
        return false;
    }
    bool skip(size_t n) {
        if (n > size - at) return false;
        at += n;
        return true;
    }
    bool skip_sized() {  // a UI8 length, then that many bytes
        uint8_t n;
        return byte(n) && skip(n);
    }
};

// One metadata element's entries; its number of sub-elements in `subs`.
bool skip_metadata_entries(Reader& r, uint64_t& subs) {
    uint64_t entries;
    if (!r.varint(entries)) return false;
    for (uint64_t i = 0; i < entries; ++i)
        if (!r.skip_sized() || !r.skip_sized()) return false;
    return r.varint(subs);
}

// A metadata element and every element nested in it, walked on a stack of the counts of sub-elements still
// to skip at each level: the stream decides the depth.
bool skip_metadata_element(Reader& r) {
    std::vector<uint64_t> pending(1);
    if (!skip_metadata_entries(r, pending[0])) return false;
    while (!pending.empty()) {
        if (pending.back() == 0) {
            pending.pop_back();
            continue;
        }
        --pending.back();
        uint64_t subs;
        if (!r.skip_sized() || !skip_metadata_entries(r, subs)) return false;
        pending.push_back(subs);
    }
    return true;
}

// The geometry metadata: per-attribute elements, then the file's.
bool skip_metadata(Reader& r) {
    uint64_t attributes;
    if (!r.varint(attributes)) return false;
    for (uint64_t i = 0; i < attributes; ++i) {
        uint64_t id;
        if (!r.varint(id) || !skip_metadata_element(r)) return false;
    }
    return skip_metadata_element(r);
}

}  // namespace

std::string read_draco_counts(const uint8_t* data, size_t size, DracoCounts& out) {
    Reader r{data, size};
    if (size < 11 || std::memcmp(data, "DRACO", 5) != 0) return "not a Draco stream";
    const uint8_t major = data[5], minor = data[6], geometry = data[7], method = data[8];
    const uint16_t flags = uint16_t(data[9] | data[10] << 8);
    if (major != 2 || minor < 2)
        return "bitstream version " + std::to_string(major) + "." + std::to_string(minor) + " (2.2 or later is read)";
    if (geometry != 1) return "not a triangle mesh (geometry type " + std::to_string(geometry) + ")";
    r.at = 11;
    if ((flags & 0x8000) && !skip_metadata(r)) return "truncated metadata";
    if (method == 0) {  // sequential: faces, then points
        if (!r.varint(out.faces) || !r.varint(out.points)) return "truncated connectivity header";
        return {};
    }
    if (method == 1) {  // edgebreaker: traversal type, encoded vertices, then faces
        uint8_t traversal;
        if (!r.byte(traversal) || !r.varint(out.points) || !r.varint(out.faces)) return "truncated connectivity header";
        return {};
    }
    return "unknown encoding method " + std::to_string(method);
}

}  // namespace cb
