// Writes the clusterbake asset (runtime/cb_asset.h, docs/FORMAT.md) from flat per-mesh arrays.
#pragma once

#include <cb_asset.h>

#include <functional>
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

// encode_asset's bytes written to `path` by write_file_atomic without assembling them in memory, from the
// meshes and their encode_geometry; each mesh's positions and triangles are freed once laid out (its
// volumes are written from where they are). The file goes out on a second thread while the checksum is
// summed when `threads` (0: all hardware threads) allows. Returns the file's size.
uint64_t write_asset(const std::string& path, std::vector<AssetMesh>& meshes, std::vector<EncodedMesh> geometry,
                     const std::vector<Instance>& instances, const std::string& source, unsigned threads);

}  // namespace cb
