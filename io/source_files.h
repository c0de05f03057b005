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

// The file's bytes, in one read where its size is known (a regular file), in blocks otherwise (a pipe).
// False, with "PATH: cannot open (REASON)" or "PATH: read error", when it cannot be read.
bool read_file_bytes(const std::string& path, std::vector<uint8_t>& bytes, std::string& error);

// Hashes `names` again (the first relative to the working directory, the others to the first one's folder),
// as a load of them would. False, with a one-line error naming the file, when one cannot be read.
bool hash_source_files(const std::string& scene_path, const std::vector<std::string>& names, SourceFiles& out,
                       std::string& error);

}  // namespace cb
