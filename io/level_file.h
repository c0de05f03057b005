// A level file: several baked assets placed in one world, for the tools that answer queries over a whole
// level (`clusterbake query`, `render`). JSON text:
//
//   {"instances": [{"asset": "tower.cbk", "matrix": [16 numbers, column-major as in glTF]},
//                  {"asset": "ground.cbk", "translation": [x, y, z], "rotation": [x, y, z, w], "scale": [x, y, z]},
//                  {"asset": "tree.cbk"}]}
//
// Each entry places every baked instance of its asset under its transform (world = transform x the baked
// instance's transform); none given: identity. Asset paths are relative to the level file's folder (or
// absolute). docs/RUNTIME.md, "Level files", is the reference.
#pragma once

#include <string>
#include <vector>

#include "scene.h"

namespace cb {

struct LevelEntry {
    std::string asset;    // the asset's path, resolved against the level file's folder
    Transform transform;  // affine, finite
};

// True when the file's first character that is not white space is '{': JSON text, not an asset.
bool is_level_file(const std::string& path);

// Reads the level file. False, with a one-line message naming the file and the entry in `error`
// ("FILE: instances[2]: rotation needs 4 numbers"), when it cannot be read, is not JSON of that form, has no
// entry, or an entry has an unknown key, a missing asset, a transform that is not finite and affine, or both
// a matrix and a translation, rotation or scale.
bool read_level_file(const std::string& path, std::vector<LevelEntry>& out, std::string& error);

}  // namespace cb
