#include "source_files.h"

#include <xxhash.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <new>

namespace cb {

struct SourceHasher::State {
    XXH3_state_t* xxh = XXH3_createState();
    ~State() { XXH3_freeState(xxh); }
};

SourceHasher::SourceHasher() : state_(std::make_unique<State>()) {
    if (!state_->xxh) throw std::bad_alloc();
    XXH3_128bits_reset(state_->xxh);
}
SourceHasher::~SourceHasher() = default;

void SourceHasher::add(const std::string& name, const uint8_t* data, size_t size) {
    uint8_t length[8];
    for (int i = 0; i < 8; ++i) length[i] = uint8_t(uint64_t(size) >> (8 * i));
    XXH3_128bits_update(state_->xxh, length, sizeof length);
    XXH3_128bits_update(state_->xxh, data, size);
    files_.names.push_back(name);
    files_.bytes += size;
}

SourceFiles SourceHasher::finish() const {
    XXH128_canonical_t canonical;
    XXH128_canonicalFromHash(&canonical, XXH3_128bits_digest(state_->xxh));
    SourceFiles out = files_;
    out.hash.clear();
    static const char digits[] = "0123456789abcdef";
    for (uint8_t b : canonical.digest) out.hash += digits[b >> 4], out.hash += digits[b & 15];
    return out;
}

bool read_file_bytes(const std::string& path, std::vector<uint8_t>& bytes, std::string& error) {
    bytes.clear();
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) {
        error = path + ": cannot open (" + std::strerror(errno) + ")";
        return false;
    }
    std::error_code ec;
    uintmax_t size = std::filesystem::file_size(path, ec);
    if (!ec && size > 0) {
        bytes.resize(size_t(size));
        bytes.resize(std::fread(bytes.data(), 1, bytes.size(), f));
    }
    uint8_t block[1 << 16];
    for (size_t n; (n = std::fread(block, 1, sizeof block, f)) > 0;) bytes.insert(bytes.end(), block, block + n);
    bool failed = std::ferror(f);
    std::fclose(f);
    if (failed) error = path + ": read error";
    return !failed;
}

bool hash_source_files(const std::string& scene_path, const std::vector<std::string>& names, SourceFiles& out,
                       std::string& error) {
    SourceHasher hasher;
    std::filesystem::path folder = std::filesystem::path(scene_path).parent_path();
    std::vector<uint8_t> bytes;
    for (size_t i = 0; i < names.size(); ++i) {
        std::string path = i == 0 ? scene_path : (folder / names[i]).string();
        if (!read_file_bytes(path, bytes, error)) return false;
        hasher.add(names[i], bytes.data(), bytes.size());
    }
    out = hasher.finish();
    return true;
}

}  // namespace cb
