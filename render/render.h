// A small CPU renderer for looking at an asset, or a level of several, and its shadows: primary visibility
// from the assets' own clusters (visibility.h), Lambert shading, and shadows from the runtime's exact queries, a point light's
// hard ones or an area light's soft ones (the fraction of its samples that reach each point). Optionally
// the same shadows asked of Embree's rays, and a picture of where the two differ.
#pragma once

#include <cb_asset.h>

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "area_light.h"
#include "camera.h"
#include "scene_query.h"

namespace cb {

struct RenderOptions {
    uint32_t width = 640, height = 480;
    // Samples per pixel side: each pixel is the mean of aa x aa samples on a regular grid (1: its centre).
    uint32_t aa = 2;
    // The camera. Default: the eye of default_camera (a diagonal above the framed box, frame_box), looking at
    // the box's centre, upright along +y, with the field of view that holds the whole box. With another
    // `up`, the default eye is turned about the box's centre by the rotation taking +y to it, so that a z-up
    // scene is seen as a y-up one.
    bool has_eye = false, has_target = false, has_up = false;
    double eye[3] = {0, 0, 0}, target[3] = {0, 0, 0}, up[3] = {0, 1, 0};
    double fov_degrees = 0;  // vertical; 0: the one that frames the box (60 when the eye is inside it)
    // A point light, an area light, or a sun (`light` is then the direction toward it, cb_segment.h "A sun");
    // none: default_light, above the camera and to its left, so that the side the camera sees is lit.
    bool has_light = false, has_area_light = false, sun = false;
    double light[3] = {0, 0, 0};
    AreaLight area_light;    // faces the world box's centre
    bool one_sided = false;  // one-sided occluders, as query --one-sided
    double bias = 0;         // self-shadowing bias, a world distance; 0: the level's (cb::Level::shadow_bias)
    bool compare = false;    // also ask Embree, and draw where the answers differ
    bool ground = false;     // add a ground plane under the scene (docs/RENDER.md, "The ground plane")
    unsigned threads = 0;    // 0: all; the picture does not depend on it
};

// The box the default camera frames, from the world boxes of the level's instances and of them all, [lo, hi]
// (instance_world_boxes): the box of the instances that are not a ground, when some are. A ground is an
// instance flat along the world axis nearest `up` (its extent there at most 1% of both others), at least 1.5
// times as wide on both other axes as the box of every instance that is not flat, and whose top is below that
// box's centre. The framed box
// then reaches past the other instances' box on those two axes by its height (so that shadows as long as
// the objects are tall stay in view), within the ground's box, and down to the ground's top. Returns the
// number of instances taken as a ground (0: the framed box is the world box).
size_t frame_box(const std::vector<std::array<double, 6>>& boxes, const double* up, const double* lo, const double* hi,
                 double* frame_lo, double* frame_hi);

// The default point light for `camera`, given the framed box [lo, hi]: from the box's centre, the way to
// the eye turned 45 degrees to the picture's left about `up` and raised to 50 degrees above the plane
// across `up`, at twice the box's largest side. It lights the side the camera sees, and the shadows it
// casts fall to the right of the objects and behind them, in view.
void default_light(const Camera& camera, const double* up, const double* lo, const double* hi, double* light);

struct CompareCounts {
    uint64_t pairs = 0;         // point and light pairs asked of both
    uint64_t runtime_only = 0;  // pairs in shadow by the runtime's answer, lit by Embree's
    uint64_t embree_only = 0;   // lit by the runtime's, in shadow by Embree's
    // Of the differing pairs: exact ties, whose exact answer involved a touching contact (cb_segment.h);
    // and near ties, whose exact answer changes when the segment moves by float rounding of the coordinates
    // (1e-6 of the largest, along the point's normal or an axis), which Embree's float triangles cannot
    // resolve.
    uint64_t ties = 0, near_ties = 0;
    uint64_t pixels = 0;        // pixels with some differing pair
    uint64_t pixels_other = 0;  // of those, pixels with a differing pair that is neither a tie nor a near tie
    double build_seconds = 0, query_seconds = 0;  // Embree's scene, and its rays for every light
};

struct RenderResult {
    uint32_t width = 0, height = 0;
    std::vector<uint8_t> rgb;          // the picture, rows top to bottom
    std::vector<uint8_t> compare_rgb;  // with compare: the picture dimmed, differing pixels marked
    Camera camera;
    double fov_degrees = 0;
    std::vector<double> lights;      // the point lights asked (xyz triples): one, or the area light's samples; or the
                                     // sun's direction
    uint32_t aa = 1;                 // samples per pixel side
    std::vector<double> points;      // every covered sample's visible point (xyz), in the order of the samples' rows
                                     // (the picture aa times as wide and high, top to bottom)
    uint64_t pixels_covered = 0;     // pixels where some sample sees the scene
    double frame_lo[3] = {0, 0, 0};  // the framed box (frame_box)
    double frame_hi[3] = {0, 0, 0};
    size_t ground_instances = 0;  // instances frame_box took as a ground
    bool ground = false;          // a ground plane was added (RenderOptions::ground)
    uint64_t clusters_drawn = 0, triangles_drawn = 0;
    uint64_t queries = 0, shadowed = 0;  // point and light pairs, and those in shadow
    double bias = 0;                     // the self-shadowing bias the answers used
    double visibility_seconds = 0;
    double bounds_seconds = 0;  // the level's hierarchy and the scan's per-asset bounds, once for every light
    std::vector<double> build_seconds, query_seconds;  // per light
    CompareCounts compare;
};

// What the renderer reports as it goes: the stage, and the share of the lights done (negative: unknown).
using RenderProgress = std::function<void(const std::string& stage, double fraction)>;

// Throws std::runtime_error when the level has no vertex to look at, or Embree fails.
RenderResult render_level(const LevelInput& level, const RenderOptions& options, const RenderProgress& progress = {});

// render_level over the asset's baked instances.
RenderResult render_asset(const AssetView& view, const RenderOptions& options, const RenderProgress& progress = {});

}  // namespace cb
