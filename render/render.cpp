#include "render.h"

#include <cb_level.h>
#include <detail/cb_math.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <memory>
#include <stdexcept>

#include "asset_file.h"
#include "asset_writer.h"
#include "baked_scene.h"
#include "embree_shadows.h"
#include "scene_query.h"
#include "timing.h"
#include "vec3.h"
#include "visibility.h"
#include "world_box.h"

namespace cb {

namespace {

using math::cross3;
using math::dot3;

constexpr double ambient = 0.15;  // light every surface gets, so that shadows are dark but not black
constexpr double pi = 3.14159265358979323846;

// Pale surface colours (linear), one per asset mesh in turn, so that meshes stand apart; the ground plane's.
constexpr float palette[6][3] = {{0.80f, 0.78f, 0.74f}, {0.55f, 0.68f, 0.82f}, {0.82f, 0.62f, 0.50f},
                                 {0.60f, 0.78f, 0.58f}, {0.80f, 0.74f, 0.52f}, {0.70f, 0.62f, 0.80f}};
constexpr float ground_colour[3] = {0.72f, 0.72f, 0.70f};

uint8_t to_srgb8(double linear) { return uint8_t(std::lround(255 * std::pow(std::clamp(linear, 0.0, 1.0), 1 / 2.2))); }
double to_linear(uint8_t srgb) { return std::pow(srgb / 255.0, 2.2); }

// The background: a pale grey-blue, lighter at the top.
void background(uint32_t y, uint32_t height, uint8_t* px) {
    const double s = height > 1 ? double(y) / (height - 1) : 0;
    const uint8_t top[3] = {236, 240, 245}, bottom[3] = {200, 206, 214};
    for (int k = 0; k < 3; ++k) px[k] = uint8_t(std::lround(top[k] + s * (bottom[k] - top[k])));
}

// The world axis nearest `up`.
int up_axis(const double* up) {
    int u = 0;
    for (int k = 1; k < 3; ++k)
        if (std::fabs(up[k]) > std::fabs(up[u])) u = k;
    return u;
}

// The ground plane of RenderOptions::ground, appended to `level` as an asset of its own (`asset` holds it):
// a square across the world axis nearest `up`, a thousandth of the box's largest side below the box [lo, hi],
// 40 box sides across about the box's centre, two triangles facing up. Its mesh is the unit square, scaled
// and placed by its instance's transform in double, so that its four corners lie in one plane exactly.
void add_ground(LevelInput& level, const double* up, const double* lo, const double* hi, LoadedAsset& asset) {
    const int u = up_axis(up), a = (u + 1) % 3, b = (u + 2) % 3;
    const bool flip = up[u] < 0;
    const double size = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-30});
    Mesh square;
    square.name = "ground";
    const float corners[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};  // counter-clockwise about +u
    for (const auto& c : corners) {
        float p[3] = {0, 0, 0};
        p[a] = c[0];
        p[b] = c[1];
        square.positions.insert(square.positions.end(), p, p + 3);
    }
    square.indices = flip ? std::vector<uint32_t>{0, 2, 1, 0, 3, 2} : std::vector<uint32_t>{0, 1, 2, 0, 2, 3};
    square.primitives.push_back({0, 2, false});
    Scene scene;
    scene.meshes.push_back(std::move(square));
    Transform place = identity_transform();
    place[a * 5] = place[b * 5] = 20 * size;
    place[12 + a] = 0.5 * (lo[a] + hi[a]), place[12 + b] = 0.5 * (lo[b] + hi[b]);
    place[12 + u] = flip ? hi[u] + 1e-3 * size : lo[u] - 1e-3 * size;
    scene.instances.push_back({0, place, "ground"});
    BoundsOptions bounds;
    bounds.mask = bounds_auto;
    const BakedScene baked = bake_in_memory(scene, ClusterOptions{}, bounds, nullptr, {}, 1);
    if (open_asset_copy(encode_asset(baked.meshes, baked.instances), asset) != AssetError::ok)
        throw std::runtime_error("the ground plane does not open as an asset");
    place_baked(level, asset.view);
}

// The level's default self-shadowing bias (cb::Level::shadow_bias), for the level without the ground plane.
double level_bias(const LevelInput& level) {
    Level runtime;
    for (const AssetView* view : level.assets) runtime.add_asset(*view, false);
    for (const LevelInstance& placed : level.instances)
        runtime.add_instance(placed.asset, placed.mesh, placed.transform);
    runtime.commit();
    return runtime.shadow_bias();
}

// `p` turned about `centre` by the rotation that takes +y to `up` (the shortest one; a half turn about x
// when `up` is -y): the default eye and light are placed for +y up and turned with --up.
void turn_to_up(const double* up, const double* centre, double* p) {
    double u[3] = {up[0], up[1], up[2]}, length = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    for (double& c : u) c /= length;
    double v[3] = {p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]};
    const double axis[3] = {u[2], 0, -u[0]};  // +y x up
    const double sine = std::sqrt(axis[0] * axis[0] + axis[2] * axis[2]), cosine = u[1];
    double turned[3];
    if (sine < 1e-12) {
        const double flip = cosine < 0 ? -1 : 1;  // none, or a half turn about x
        turned[0] = v[0];
        turned[1] = flip * v[1];
        turned[2] = flip * v[2];
    } else {  // Rodrigues' formula about the unit axis k
        const double k[3] = {axis[0] / sine, 0, axis[2] / sine};
        const double kv = k[0] * v[0] + k[2] * v[2];
        const double cross[3] = {k[1] * v[2] - k[2] * v[1], k[2] * v[0] - k[0] * v[2], k[0] * v[1] - k[1] * v[0]};
        for (int i = 0; i < 3; ++i) turned[i] = v[i] * cosine + cross[i] * sine + k[i] * kv * (1 - cosine);
    }
    for (int i = 0; i < 3; ++i) p[i] = centre[i] + turned[i];
}

// The camera the options ask for.
Camera choose_camera(const RenderOptions& o, const double* lo, const double* hi, double& fov) {
    const double centre[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
    double eye[3], target[3];
    if (o.has_eye) {
        std::copy(o.eye, o.eye + 3, eye);
    } else {
        const Camera framing = default_camera(lo, hi, o.width, o.height);
        std::copy(framing.eye, framing.eye + 3, eye);
        turn_to_up(o.up, centre, eye);
    }
    for (int k = 0; k < 3; ++k) target[k] = o.has_target ? o.target[k] : centre[k];
    Camera c = camera_looking_at(eye, target, o.up, 60, o.width, o.height);
    fov = o.fov_degrees > 0 ? o.fov_degrees : framing_fov(c, lo, hi);
    if (!(fov > 0) || fov > 120) fov = 60;  // the eye is in the box, or beside it: a usual lens
    return camera_looking_at(eye, target, o.up, fov, o.width, o.height);
}

// Marks pixel (x, y) as a 3 x 3 dot of `colour`, so that a single pixel shows.
void dot(std::vector<uint8_t>& rgb, uint32_t width, uint32_t height, uint32_t x, uint32_t y, const uint8_t* colour) {
    for (int64_t dy = -1; dy <= 1; ++dy)
        for (int64_t dx = -1; dx <= 1; ++dx) {
            int64_t px = int64_t(x) + dx, py = int64_t(y) + dy;
            if (px < 0 || py < 0 || px >= int64_t(width) || py >= int64_t(height)) continue;
            std::copy(colour, colour + 3, &rgb[(size_t(py) * width + size_t(px)) * 3]);
        }
}

// Tells each differing pair (point index in `differing`, for `light`) apart: an exact tie when the reference
// walk meets a touching contact; a near tie when the exact answer changes with the whole segment moved by
// float rounding of its coordinates (1e-6 of the largest, along the point's normal or an axis, either way:
// the segment moves by that much at every parameter, wherever it meets its occluder). Counts them and marks
// their pixels (1 a tie or near tie, 2 the runtime alone shadows, 3 Embree alone).
void classify(const LevelInput& level, const SceneQueryOptions& query, const double* light,
              const VisibleSurface& surface, const std::vector<uint8_t>& shadowed, const std::vector<size_t>& differing,
              CompareCounts& counts, std::vector<uint8_t>& mark) {
    SceneQueryOptions exact = query;
    exact.reference = true;
    exact.per_point = true;
    exact.threads = 1;  // each call asks one point: no threads to start
    for (size_t i : differing) {
        const double* p = &surface.points[i * 3];
        const double* n = &surface.normals[i * 3];
        const bool tie = query_level(level, light, p, 1, exact).point_stats[0].touching > 0;
        double size = 0;
        for (int k = 0; k < 3; ++k) size = std::max({size, std::fabs(p[k]), query.sun ? 0.0 : std::fabs(light[k])});
        const double step = 1e-6 * size;
        bool near = false;
        for (int m = 0; m < 8 && !tie && !near; ++m) {  // along the normal and the three axes, either way
            double moved_point[3], moved_light[3];
            for (int k = 0; k < 3; ++k) {
                const double d = (m % 2 ? -step : step) * (m < 2 ? n[k] : double(k == m / 2 - 1));
                moved_point[k] = p[k] + d;
                moved_light[k] = query.sun ? light[k] : light[k] + d;  // a sun: its way
            }
            near = query_level(level, moved_light, moved_point, 1, exact).shadowed[0] != shadowed[i];
        }
        (shadowed[i] ? counts.runtime_only : counts.embree_only) += 1;
        counts.ties += tie;
        counts.near_ties += near;
        const uint8_t kind = tie || near ? 1 : shadowed[i] ? 2 : 3;
        mark[i] = std::max(mark[i], kind);
    }
}

}  // namespace

size_t frame_box(const std::vector<std::array<double, 6>>& boxes, const double* up, const double* lo, const double* hi,
                 double* frame_lo, double* frame_hi) {
    std::copy(lo, lo + 3, frame_lo), std::copy(hi, hi + 3, frame_hi);
    const int u = up_axis(up), a = (u + 1) % 3, b = (u + 2) % 3;
    const double sign = up[u] < 0 ? -1 : 1;
    const size_t n = boxes.size();
    std::vector<char> flat(n), ground(n, 0);
    double solid_lo[3] = {INFINITY, INFINITY, INFINITY}, solid_hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; ++i) {
        const double* box = boxes[i].data();
        const double width_a = box[3 + a] - box[a], width_b = box[3 + b] - box[b];
        flat[i] = box[3 + u] - box[u] <= 0.01 * std::min(width_a, width_b) && width_a > 0 && width_b > 0;
        if (!flat[i]) grow_box(solid_lo, solid_hi, box, box + 3);
    }
    if (!(solid_lo[0] <= solid_hi[0])) return 0;  // nothing but flat instances: no object to frame
    size_t grounds = 0;
    double ground_lo[3] = {INFINITY, INFINITY, INFINITY}, ground_hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; ++i) {
        const double* box = boxes[i].data();
        const double top = sign > 0 ? box[3 + u] : box[u];
        ground[i] = flat[i] && box[3 + a] - box[a] >= 1.5 * (solid_hi[a] - solid_lo[a]) &&
            box[3 + b] - box[b] >= 1.5 * (solid_hi[b] - solid_lo[b]) &&
            sign * 0.5 * (solid_lo[u] + solid_hi[u]) > sign * top;
        if (ground[i]) ++grounds, grow_box(ground_lo, ground_hi, box, box + 3);
    }
    if (!grounds) return 0;
    double objects_lo[3] = {INFINITY, INFINITY, INFINITY}, objects_hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; ++i)
        if (!ground[i]) grow_box(objects_lo, objects_hi, boxes[i].data(), boxes[i].data() + 3);
    const double height = objects_hi[u] - objects_lo[u];
    for (int k : {a, b}) {
        frame_lo[k] = std::max(ground_lo[k], objects_lo[k] - height);
        frame_hi[k] = std::min(ground_hi[k], objects_hi[k] + height);
    }
    frame_lo[u] = sign > 0 ? std::min(objects_lo[u], ground_hi[u]) : objects_lo[u];
    frame_hi[u] = sign > 0 ? objects_hi[u] : std::max(objects_hi[u], ground_lo[u]);
    return grounds;
}

void default_light(const Camera& c, const double* up, const double* lo, const double* hi, double* light) {
    double u[3] = {up[0], up[1], up[2]};
    normalise(u);
    const double centre[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
    const double size = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-30});
    // The way to the eye across `up`; looking along `up`, the way to the picture's bottom.
    double across[3], to_eye[3] = {c.eye[0] - centre[0], c.eye[1] - centre[1], c.eye[2] - centre[2]};
    double along = dot3(to_eye, u);
    for (int k = 0; k < 3; ++k) across[k] = to_eye[k] - along * u[k];
    if (!(dot3(across, across) > 1e-12 * dot3(to_eye, to_eye))) {
        along = -dot3(c.up, u);
        for (int k = 0; k < 3; ++k) across[k] = -c.up[k] - along * u[k];
    }
    normalise(across);
    double left[3];  // across x up: the picture's left, seen from the eye
    cross3(across, u, left);
    const double turn = 45 * pi / 180, rise = 50 * pi / 180;
    for (int k = 0; k < 3; ++k) {
        const double way = std::cos(turn) * across[k] + std::sin(turn) * left[k];
        light[k] = centre[k] + 2 * size * (std::cos(rise) * way + std::sin(rise) * u[k]);
    }
}

RenderResult render_level(const LevelInput& level, const RenderOptions& o, const RenderProgress& progress) {
    RenderResult r;
    r.width = o.width;
    r.height = o.height;
    r.aa = std::max(1u, o.aa);
    std::vector<std::array<double, 6>> boxes;  // each instance's world box, for the level's and the framing
    double lo[3], hi[3];
    if (!instance_world_boxes(level, boxes, lo, hi)) throw std::runtime_error("no vertex to look at");
    r.ground_instances = frame_box(boxes, o.up, lo, hi, r.frame_lo, r.frame_hi);
    r.camera = choose_camera(o, r.frame_lo, r.frame_hi, r.fov_degrees);

    // The lights: one point, or the area light's samples facing the scene's centre.
    if (o.has_area_light) {
        const double centre[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
        r.lights = area_light_samples(o.area_light, centre);
    } else if (o.has_light) {
        r.lights.assign(o.light, o.light + 3);
    } else {
        r.lights.resize(3);
        default_light(r.camera, o.up, r.frame_lo, r.frame_hi, r.lights.data());
    }
    const size_t light_count = r.lights.size() / 3;

    // What is drawn and shadowed: the level, and the ground plane as one more asset of it. The bias stays
    // the level's own, so that the objects' points get the answers they get without the ground.
    LevelInput drawn = level;
    LoadedAsset ground;
    uint32_t ground_mesh = UINT32_MAX;  // the ground's mesh, numbered across the assets as surface.meshes
    double bias = o.bias;
    if (o.ground) {
        r.ground = true;
        if (!(bias > 0)) bias = level_bias(level);
        ground_mesh = 0;
        for (const AssetView* view : level.assets) ground_mesh += view->mesh_count;
        add_ground(drawn, o.up, lo, hi, ground);
    }

    // aa x aa samples a pixel: the picture's camera, aa times as many rows and columns.
    Camera sampled = r.camera;
    sampled.width *= r.aa;
    sampled.height *= r.aa;
    if (progress) progress("drawing the clusters the camera sees", -1);
    auto start = std::chrono::steady_clock::now();
    const VisibleSurface surface = primary_visibility(drawn, sampled, o.threads);
    r.visibility_seconds = seconds_since(start);
    r.clusters_drawn = surface.clusters_drawn;
    r.triangles_drawn = surface.triangles_drawn;
    r.points = surface.points;
    const size_t n = surface.pixel.size();
    // The picture's pixel of each covered sample.
    std::vector<uint32_t> pixel_of(n);
    for (size_t i = 0; i < n; ++i) {
        const uint32_t x = surface.pixel[i] % sampled.width, y = surface.pixel[i] / sampled.width;
        pixel_of[i] = (y / r.aa) * r.width + x / r.aa;
    }

    std::unique_ptr<EmbreeShadows> embree;
    if (o.compare) {
        if (progress) progress("building Embree's scene", -1);
        embree = std::make_unique<EmbreeShadows>(drawn, o.one_sided, o.threads);
        r.compare.build_seconds = embree->build_seconds();
    }

    // Each light's answers: its Lambert term added where the point is lit; with compare, Embree's answers
    // beside them, each differing pair told apart (classify).
    std::vector<double> diffuse(n, 0.0);
    std::vector<uint8_t> mark(n, 0);  // with compare: as classify marks
    SceneQueryOptions query;
    query.one_sided = o.one_sided;
    query.threads = o.threads;
    query.bias = bias;
    query.sun = o.sun;
    if (progress) progress("light 1 of " + std::to_string(light_count), 0);
    r.bounds_seconds = query_level_lights(
        drawn, r.lights.data(), light_count, surface.points.data(), n, query, [&](size_t l, const SceneQueryResult& q) {
            const double* light = &r.lights[l * 3];
            r.build_seconds.push_back(q.build_seconds), r.query_seconds.push_back(q.query_seconds);
            r.bias = q.bias;
            r.queries += n;
            for (size_t i = 0; i < n; ++i) {
                if (q.shadowed[i]) {
                    ++r.shadowed;
                    continue;
                }
                const double* p = &surface.points[i * 3];
                const double* normal = &surface.normals[i * 3];
                double to_light[3] = {light[0] - p[0], light[1] - p[1], light[2] - p[2]};
                if (o.sun) std::copy(light, light + 3, to_light);
                double length =
                    std::sqrt(to_light[0] * to_light[0] + to_light[1] * to_light[1] + to_light[2] * to_light[2]);
                double cosine = (normal[0] * to_light[0] + normal[1] * to_light[1] + normal[2] * to_light[2]) / length;
                if (cosine > 0) diffuse[i] += cosine;
            }
            if (embree) {
                auto embree_start = std::chrono::steady_clock::now();
                const std::vector<uint8_t> theirs = embree->occluded(light, q.bias, surface.points.data(), n, o.sun);
                r.compare.query_seconds += seconds_since(embree_start);
                r.compare.pairs += n;
                std::vector<size_t> differing;
                for (size_t i = 0; i < n; ++i)
                    if (theirs[i] != q.shadowed[i]) differing.push_back(i);
                SceneQueryOptions asked = query;
                asked.bias = q.bias;  // the level's default resolved: each point asked alone keeps it
                if (!differing.empty()) classify(drawn, asked, light, surface, q.shadowed, differing, r.compare, mark);
            }
            if (progress)
                progress("light " + std::to_string(std::min(l + 2, light_count)) + " of " + std::to_string(light_count),
                         double(l + 1) / double(light_count));
        });

    // Shading: the mesh's colour times the ambient term plus the mean Lambert term over the lights, for each
    // sample; each pixel the mean of its samples in linear light, those that see nothing the background's.
    const size_t pixels = size_t(r.width) * r.height;
    r.rgb.resize(pixels * 3);
    for (uint32_t y = 0; y < r.height; ++y)
        for (uint32_t x = 0; x < r.width; ++x) background(y, r.height, &r.rgb[(size_t(y) * r.width + x) * 3]);
    std::vector<double> sum(pixels * 3, 0.0);
    std::vector<uint32_t> covered(pixels, 0);
    for (size_t i = 0; i < n; ++i) {
        const float* albedo = surface.meshes[i] == ground_mesh ? ground_colour : palette[surface.meshes[i] % 6];
        const double light = ambient + (1 - ambient) * diffuse[i] / double(std::max<size_t>(light_count, 1));
        for (int k = 0; k < 3; ++k) sum[size_t(pixel_of[i]) * 3 + k] += albedo[k] * light;
        ++covered[pixel_of[i]];
    }
    const uint32_t per_pixel = r.aa * r.aa;
    for (size_t p = 0; p < pixels; ++p) {
        if (!covered[p]) continue;
        ++r.pixels_covered;
        uint8_t* px = &r.rgb[p * 3];
        for (int k = 0; k < 3; ++k)
            px[k] = to_srgb8((sum[p * 3 + k] + (per_pixel - covered[p]) * to_linear(px[k])) / per_pixel);
    }

    if (o.compare) {
        // The picture in dim grey, each pixel with a differing sample a dot: yellow a tie or near tie, red
        // where only the runtime shadows otherwise, blue where only Embree does.
        r.compare_rgb.resize(r.rgb.size());
        for (size_t p = 0; p < r.rgb.size(); p += 3) {
            const double grey = (0.3 * r.rgb[p] + 0.59 * r.rgb[p + 1] + 0.11 * r.rgb[p + 2]) / 255;
            r.compare_rgb[p] = r.compare_rgb[p + 1] = r.compare_rgb[p + 2] = uint8_t(std::lround(60 + 110 * grey));
        }
        std::vector<uint8_t> pixel_mark(pixels, 0);
        for (size_t i = 0; i < n; ++i) pixel_mark[pixel_of[i]] = std::max(pixel_mark[pixel_of[i]], mark[i]);
        const uint8_t colours[4][3] = {{0, 0, 0}, {255, 200, 0}, {230, 20, 20}, {20, 90, 255}};
        for (int kind = 1; kind <= 3; ++kind)  // stronger marks drawn over weaker ones
            for (size_t p = 0; p < pixels; ++p)
                if (pixel_mark[p] == kind)
                    dot(r.compare_rgb, r.width, r.height, p % r.width, p / r.width, colours[kind]);
        for (uint8_t m : pixel_mark) {
            r.compare.pixels += m != 0;
            r.compare.pixels_other += m > 1;
        }
    }
    return r;
}

RenderResult render_asset(const AssetView& view, const RenderOptions& options, const RenderProgress& progress) {
    return render_level(baked_level(view), options, progress);
}

}  // namespace cb
