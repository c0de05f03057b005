// What a batch bakes: the command line's inputs (scene files, folders, manifests) expanded into one job per
// scene file, each with the output path that mirrors its place in the input tree. No file is read but the
// manifests and the folder listings; nothing is written.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <stdexcept>
#include <string>
#include <vector>

namespace cb {

struct BatchJob {
    std::string name;               // the scene's path below its root, '/'-separated: "a/b/scene.glb"
    std::string input;              // the path read: root joined with name
    std::string root;               // the folder or manifest's root its files must lie below; empty for a file
    std::string output;             // OUTDIR/a/b/scene.cbk
    std::vector<std::string> args;  // bake options for this file alone, from its manifest line
    std::string origin;             // where it was named, for errors: the input, or "list.txt: line 3"
    uint64_t input_size = 0;        // the scene file's bytes (not its external buffers): larger ones go first
};

// One line naming the input, the manifest line or the two inputs that collide.
struct PlanError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// True for the extensions the loaders read (.gltf .glb .obj .ply .off .stl, any case).
bool is_scene_path(const std::string& path);

// A manifest line's fields: separated by blanks; a field with blanks in double or single quotes. Empty for a
// blank line or a comment (first non-blank character '#'). Throws PlanError("unclosed quote") on a bad line.
std::vector<std::string> manifest_fields(const std::string& line);

// Expands the inputs, in order: a scene file is its own root (name: its file name); a folder is the root of
// every scene file below it (recursively, symbolic links to folders not followed); any other file, or "-"
// for `manifest_stdin`, is a manifest: one scene path per line, relative to the manifest's folder (the
// working directory for "-"), which is the root, then that file's bake options. Jobs come back sorted by
// name; the same input twice with the same options is one job. Throws PlanError when an input does not
// exist, a folder holds no scene, a manifest line is bad or names a file outside the manifest's folder, or
// two different inputs would write the same output.
std::vector<BatchJob> plan_batch(const std::vector<std::string>& inputs, const std::string& outdir,
                                 std::istream* manifest_stdin = nullptr);

}  // namespace cb
