// A baked asset as binary glTF (GLB) for any glTF viewer: every cluster its own primitive, coloured so that
// no two neighbouring clusters look alike, one glTF mesh per asset mesh under one node per instance, and
// optionally the clusters' bounding volumes and normal cones as coloured lines. A debugging view of the
// clustering; nothing reads it back. docs/EXPORT.md describes the output.
#pragma once

#include <cb_asset.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace cb {

enum class ExportLevel { fine, coarse };

// Wireframes drawn over the clusters, as bits of ExportOptions::overlays.
enum ExportOverlay : uint32_t {
    overlay_obb = 1,      // the box's 12 edges
    overlay_sphere = 2,   // three great circles
    overlay_capsule = 4,  // the end circles, four lines joining them and the end caps' outlines
    overlay_cone = 8,     // the normal cone's axis, from its front apex (valid cones only)
};

struct ExportOptions {
    ExportLevel level = ExportLevel::fine;
    uint32_t overlays = 0;  // ExportOverlay bits
    std::string generator;  // the glTF's asset.generator, e.g. the tool and its version
};

// What an export holds.
struct ExportSummary {
    size_t meshes = 0, instances = 0, nodes = 0;
    size_t clusters = 0;           // of the level: one triangle primitive each
    size_t triangles = 0;          // in the triangle primitives: the asset's, each mesh once
    size_t line_primitives = 0;    // overlays: one per mesh, kind and colour
    size_t colours = 0;            // colour classes used
    size_t materials = 0;          // one per colour for triangles, one more per colour for lines
    size_t cones = 0;              // valid cones drawn
    size_t sheared_instances = 0;  // placed by two nodes (below)
    size_t bytes = 0;              // of the GLB
};

// The names of --boxes' list ("obb,sphere,capsule") as overlay bits; false for an unknown or empty name.
bool parse_volume_overlays(const std::string& text, uint32_t& out);

// Why `view` cannot give what `options` asks (an overlay whose section the asset does not have), in one
// line, or empty.
std::string export_options_error(const AssetView& view, const ExportOptions& options);

// Neighbouring clusters of the level: two clusters of the same mesh are neighbours when a vertex of one has
// the position of a vertex of the other (a shared corner, whether the asset stores it once or twice).
// Clusters of different meshes never are: a mesh is placed by many instances. Indexed as the level's
// records (fine clusters then first_fine + i of each mesh; coarse likewise); each list sorted.
std::vector<std::vector<uint32_t>> cluster_neighbours(const AssetView& view, ExportLevel level);

// Each cluster's colour class: a greedy colouring of cluster_neighbours, clusters taken in smallest-last
// order (at most one more colour than the graph's degeneracy), each given the least used palette colour no
// neighbour has, or the first colour past the palette when all of it is taken. Neighbours never share one.
std::vector<uint32_t> cluster_colours(const AssetView& view, ExportLevel level);

// How many colours the fixed palette has; colour classes past it get further hues.
constexpr uint32_t export_palette_size = 12;

// Colour class `k` as linear RGB (glTF's baseColorFactor), each channel 0 to 1. The palette: six bright
// hues 60 degrees apart, then six darker ones between them, so that the colours greedy colouring uses most
// are the farthest apart; classes past it step round the hue circle by the golden angle.
void export_colour(uint32_t k, double rgb[3]);

// The asset as a GLB file. The view must have come from open_asset; throws std::invalid_argument when
// export_options_error is not empty. Each instance is one root node whose translation, rotation and scale
// equal its transform; a sheared transform, which no translation-rotation-scale can hold, is split as
// T U S V^T (singular values S) into the root's T U S and a child node's rotation V^T, the child holding
// the mesh.
std::vector<uint8_t> export_clusters_glb(const AssetView& view, const ExportOptions& options,
                                         ExportSummary* summary = nullptr);

}  // namespace cb
