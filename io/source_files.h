// What a scene was made from: the files a load read (the scene file, then a glTF's external buffers in the
// order tinygltf read them) and one hash of their bytes, so that a bake can tell whether its output is up
// to date without loading the scene again.
//
// The hash is XXH3-128 (xxHash 0.8, whose XXH3 output is stable) over, for each file in order, its size as
// a little-endian u64 followed by its bytes. Images are never read, so a texture edit changes nothing.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace cb {

struct SourceFiles {
    std::vector<std::string> names;  // the scene file's name, then external files relative to its folder
    uint64_t bytes = 0;              // all files together
    std::string hash;                // 32 lowercase hex digits
};

// Accumulates files into a SourceFiles, in the order they are added.
class SourceHasher {
public:
    SourceHasher();
    ~SourceHasher();
    SourceHasher(const SourceHasher&) = delete;
    SourceHasher& operator=(const SourceHasher&) = delete;

    void add(const std::string& name, const uint8_t* data, size_t size);
    SourceFiles finish() const;  // the files so far and their hash

private:
    struct State;
    std::unique_ptr<State> state_;
    SourceFiles files_;
};

// A file's bytes. A regular file of a megabyte or more is mapped read-only, so that loading it neither
// zeroes a buffer of its size nor copies it there; a smaller one, or a pipe, is read in blocks. (A mapped
// file cut short by another process while it is held would stop this one: inputs are held only while they
// are parsed.)
class FileBytes {
public:
    FileBytes() = default;
    ~FileBytes();
    FileBytes(const FileBytes&) = delete;
    FileBytes& operator=(const FileBytes&) = delete;

    // Replaces the bytes held with the file's. False, with "PATH: cannot open (REASON)" or "PATH: read error",
    // when it cannot be read. A mapped file's pages are mapped in by `threads` threads (0: all), in parts.
    bool read(const std::string& path, std::string& error, unsigned threads = 1);
    const uint8_t* data() const { return mapped_ ? mapped_ : copy_.data(); }
    size_t size() const { return mapped_ ? mapped_size_ : copy_.size(); }

private:
    void release();
    const uint8_t* mapped_ = nullptr;
    size_t mapped_size_ = 0;
    std::vector<uint8_t> copy_;
};

// Hashes `names` again (the first relative to the working directory, the others to the first one's folder),
// as a load of them would. False, with a one-line error naming the file, when one cannot be read.
bool hash_source_files(const std::string& scene_path, const std::vector<std::string>& names, SourceFiles& out,
                       std::string& error);

}  // namespace cb
