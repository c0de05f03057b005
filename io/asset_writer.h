// Writes the clusterbake asset (runtime/cb_asset.h, docs/FORMAT.md) from flat per-mesh arrays.
#pragma once

#include <cb_asset.h>

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "asset_content.h"
#include "scene.h"

namespace cb {

// Bounds sections are written for the volumes every mesh has (each mesh one record per cluster); `source`,
// when not empty, as the source section (what the asset was made from, docs/FORMAT.md). Throws
// std::invalid_argument when a fine cluster has more than 255 triangles or its corners more than
// max_cluster_vertices distinct vertices.
std::vector<uint8_t> encode_asset(const std::vector<AssetMesh>& meshes, const std::vector<Instance>& instances,
                                  const std::string& source = {});

// Writes to a temporary file beside `path` and renames it over `path`, so a failure leaves any existing
// file untouched: an unnamed file (O_TMPFILE) where the filesystem has them, so that a process killed
// while writing leaves nothing; temporaries of `path` left by dead processes are removed first. Refuses a
// `path` that exists and is not a regular file. Throws std::runtime_error naming the path.
void write_file_atomic(const std::string& path, const std::vector<uint8_t>& bytes);

// Removes the temporaries of `path` that processes no longer running left (killed between naming their file
// and renaming it over `path`), as every write_file_atomic of `path` does first.
void remove_dead_temporaries(const std::string& path);

// The same, with the contents written by `fill(fd)` (from offset 0 of a new, empty file), which returns false
// with errno set when it fails.
void write_file_atomic(const std::string& path, const std::function<bool(int fd)>& fill);

// write_file_atomic in steps: the temporary is opened on construction (throwing as write_file_atomic does),
// written through fd() for as long as it takes, and renamed over the path by commit(). Destroyed without a
// commit (an exception on the way), it leaves nothing behind and the path untouched.
class AtomicFile {
public:
    explicit AtomicFile(const std::string& path);
    ~AtomicFile();
    AtomicFile(const AtomicFile&) = delete;
    AtomicFile& operator=(const AtomicFile&) = delete;
    int fd() const { return fd_; }
    // Throws std::runtime_error naming the path, for a write through fd() that failed with `err` (an errno).
    [[noreturn]] void fail(int err);
    void commit();

private:
    std::string path_, tmp_;
    int fd_ = -1;
    bool unnamed_ = false, committed_ = false;
};

// A mesh's geometry as the asset stores it: vertices renumbered in order of first use (a vertex too far
// back for a 16-bit reference stored again), each fine cluster's corners as 8-bit indices into its list of
// new vertices followed by reused ones. It depends on the triangles alone, not on the bounding volumes.
struct EncodedMesh {
    std::vector<float> positions;
    std::vector<uint8_t> local;
    std::vector<uint16_t> refs;
    std::vector<FineCluster> fine;
};

// The encoded geometry of every mesh; throws as encode_asset does.
std::vector<EncodedMesh> encode_geometry(const std::vector<AssetMesh>& meshes);

// encode_asset's bytes written to `path` as write_file_atomic writes, without assembling them in memory, in
// two steps so that the geometry can go to the file while the volumes are still being fitted. The
// constructor lays the asset out, its volume arrays already sized as they will be filled (one record per
// cluster; fit_scene_bounds sizes them first), opens the temporary and writes everything before the
// bounds sections, summing the checksum as it goes; the encoded geometry is then freed. finish(), once the
// volumes are filled, writes the bounds sections and the rest, the checksum, and renames the file over
// `path`; it frees each mesh's positions and triangles and returns the file's size. The meshes must stay
// as they are (but for their volumes' values) in between, and their positions and triangles may be freed
// once encoded.
class AssetWriter {
public:
    AssetWriter(const std::string& path, const std::vector<AssetMesh>& meshes, std::vector<EncodedMesh> geometry,
                const std::vector<Instance>& instances, const std::string& source);
    ~AssetWriter();
    // `threads` (0: all hardware threads) > 1: the rest of the file goes out on a second thread while the
    // checksum is summed.
    uint64_t finish(std::vector<AssetMesh>& meshes, unsigned threads);

private:
    struct State;
    std::unique_ptr<State> state_;
};

// AssetWriter's two steps in one.
uint64_t write_asset(const std::string& path, std::vector<AssetMesh>& meshes, std::vector<EncodedMesh> geometry,
                     const std::vector<Instance>& instances, const std::string& source, unsigned threads);

}  // namespace cb
