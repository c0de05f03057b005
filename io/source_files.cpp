#include "source_files.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <new>

#include "parallel.h"
#include "populate_pages.h"

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
    for (uint8_t b : canonical.digest) {
        out.hash += digits[b >> 4];
        out.hash += digits[b & 15];
    }
    return out;
}

FileBytes::~FileBytes() { release(); }

void FileBytes::release() {
    if (mapped_) munmap(const_cast<uint8_t*>(mapped_), mapped_size_);
    mapped_ = nullptr;
    mapped_size_ = 0;
    copy_.clear();
}

bool FileBytes::read(const std::string& path, std::string& error, unsigned threads) {
    release();
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        error = path + ": cannot open (" + std::strerror(errno) + ")";
        return false;
    }
    // Below a megabyte a read costs less than setting up a mapping.
    constexpr off_t map_from = off_t(1) << 20;
    struct stat st;
    const bool regular = fstat(fd, &st) == 0 && S_ISREG(st.st_mode);
    if (regular && st.st_size >= map_from) {
        const size_t size = size_t(st.st_size);
        // Mapped in ahead, as MAP_POPULATE would, but in parts on the load's threads.
        const bool parallel = can_populate_pages && threads_or_all(threads) > 1 && size >= 2 * populate_part_bytes;
        void* at = mmap(nullptr, size, PROT_READ, MAP_PRIVATE | (parallel ? 0 : MAP_POPULATE), fd, 0);
        if (at != MAP_FAILED) {
            if (parallel) populate_pages(at, size, populate_for_reading, threads);
            mapped_ = static_cast<const uint8_t*>(at);
            mapped_size_ = size;
            ::close(fd);
            return true;
        }
    }
    if (regular && st.st_size > 0) copy_.reserve(size_t(st.st_size));
    bool failed = false;
    uint8_t block[1 << 16];
    for (;;) {
        const ssize_t n = ::read(fd, block, sizeof block);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) {
            failed = n < 0;
            break;
        }
        copy_.insert(copy_.end(), block, block + n);
    }
    ::close(fd);
    if (failed) error = path + ": read error";
    return !failed;
}

bool hash_source_files(const std::string& scene_path, const std::vector<std::string>& names, SourceFiles& out,
                       std::string& error) {
    SourceHasher hasher;
    std::filesystem::path folder = std::filesystem::path(scene_path).parent_path();
    FileBytes bytes;
    for (size_t i = 0; i < names.size(); ++i) {
        std::string path = i == 0 ? scene_path : (folder / names[i]).string();
        if (!bytes.read(path, error)) return false;
        hasher.add(names[i], bytes.data(), bytes.size());
    }
    out = hasher.finish();
    return true;
}

}  // namespace cb
