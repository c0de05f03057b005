#include "render.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <stdexcept>

#include "embree_shadows.h"
#include "report.h"
#include "scene_query.h"
#include "timing.h"
#include "visibility.h"

namespace cb {

namespace {

constexpr double ambient = 0.15;  // light every surface gets, so that shadows are dark but not black

// Pale surface colours (linear), one per asset mesh in turn, so that meshes stand apart.
constexpr float palette[6][3] = {{0.80f, 0.78f, 0.74f}, {0.55f, 0.68f, 0.82f}, {0.82f, 0.62f, 0.50f},
                                 {0.60f, 0.78f, 0.58f}, {0.80f, 0.74f, 0.52f}, {0.70f, 0.62f, 0.80f}};

uint8_t to_srgb8(double linear) { return uint8_t(std::lround(255 * std::pow(std::clamp(linear, 0.0, 1.0), 1 / 2.2))); }

// The background: a pale grey-blue, lighter at the top.
void background(uint32_t y, uint32_t height, uint8_t* px) {
    const double s = height > 1 ? double(y) / (height - 1) : 0;
    const uint8_t top[3] = {236, 240, 245}, bottom[3] = {200, 206, 214};
    for (int k = 0; k < 3; ++k) px[k] = uint8_t(std::lround(top[k] + s * (bottom[k] - top[k])));
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
        turned[0] = v[0], turned[1] = flip * v[1], turned[2] = flip * v[2];
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
    exact.reference = true, exact.per_point = true;
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
                moved_point[k] = p[k] + d, moved_light[k] = query.sun ? light[k] : light[k] + d;  // a sun: its way
            }
            near = query_level(level, moved_light, moved_point, 1, exact).shadowed[0] != shadowed[i];
        }
        (shadowed[i] ? counts.runtime_only : counts.embree_only) += 1;
        counts.ties += tie, counts.near_ties += near;
        const uint8_t kind = tie || near ? 1 : shadowed[i] ? 2 : 3;
        mark[i] = std::max(mark[i], kind);
    }
}

}  // namespace

RenderResult render_level(const LevelInput& level, const RenderOptions& o, const RenderProgress& progress) {
    RenderResult r;
    r.width = o.width, r.height = o.height;
    double lo[3], hi[3];
    if (!level_world_box(level, lo, hi)) throw std::runtime_error("no vertex to look at");
    r.camera = choose_camera(o, lo, hi, r.fov_degrees);

    // The lights: one point, or the area light's samples facing the scene's centre.
    if (o.has_area_light) {
        const double centre[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
        r.lights = area_light_samples(o.area_light, centre);
    } else if (o.has_light) {
        r.lights.assign(o.light, o.light + 3);
    } else {
        r.lights = report_lights(lo, hi, 1);
        const double centre[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
        turn_to_up(o.up, centre, r.lights.data());
    }
    const size_t light_count = r.lights.size() / 3;

    if (progress) progress("drawing the clusters the camera sees", -1);
    auto start = std::chrono::steady_clock::now();
    const VisibleSurface surface = primary_visibility(level, r.camera, o.threads);
    r.visibility_seconds = seconds_since(start);
    r.clusters_drawn = surface.clusters_drawn, r.triangles_drawn = surface.triangles_drawn;
    r.points = surface.points;
    const size_t n = surface.pixel.size();

    std::unique_ptr<EmbreeShadows> embree;
    if (o.compare) {
        if (progress) progress("building Embree's scene", -1);
        embree = std::make_unique<EmbreeShadows>(level, o.one_sided, o.threads);
        r.compare.build_seconds = embree->build_seconds();
    }

    // Each light's answers: its Lambert term added where the point is lit; with compare, Embree's answers
    // beside them, each differing pair told apart (classify).
    std::vector<double> diffuse(n, 0.0);
    std::vector<uint8_t> mark(n, 0);  // with compare: as classify marks
    SceneQueryOptions query;
    query.one_sided = o.one_sided, query.threads = o.threads, query.bias = o.bias, query.sun = o.sun;
    if (progress) progress("light 1 of " + std::to_string(light_count), 0);
    r.bounds_seconds = query_level_lights(
        level, r.lights.data(), light_count, surface.points.data(), n, query, [&](size_t l, const SceneQueryResult& q) {
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
                if (!differing.empty()) classify(level, asked, light, surface, q.shadowed, differing, r.compare, mark);
            }
            if (progress)
                progress("light " + std::to_string(std::min(l + 2, light_count)) + " of " + std::to_string(light_count),
                         double(l + 1) / double(light_count));
        });

    // Shading: the mesh's colour times the ambient term plus the mean Lambert term over the lights.
    r.rgb.resize(size_t(r.width) * r.height * 3);
    for (uint32_t y = 0; y < r.height; ++y)
        for (uint32_t x = 0; x < r.width; ++x) background(y, r.height, &r.rgb[(size_t(y) * r.width + x) * 3]);
    for (size_t i = 0; i < n; ++i) {
        const float* albedo = palette[surface.meshes[i] % 6];
        const double light = ambient + (1 - ambient) * diffuse[i] / double(std::max<size_t>(light_count, 1));
        uint8_t* px = &r.rgb[size_t(surface.pixel[i]) * 3];
        for (int k = 0; k < 3; ++k) px[k] = to_srgb8(albedo[k] * light);
    }

    if (o.compare) {
        // The picture in dim grey, each differing pixel a dot: yellow a tie or near tie, red where only the
        // runtime shadows otherwise, blue where only Embree does.
        r.compare_rgb.resize(r.rgb.size());
        for (size_t p = 0; p < r.rgb.size(); p += 3) {
            const double grey = (0.3 * r.rgb[p] + 0.59 * r.rgb[p + 1] + 0.11 * r.rgb[p + 2]) / 255;
            r.compare_rgb[p] = r.compare_rgb[p + 1] = r.compare_rgb[p + 2] = uint8_t(std::lround(60 + 110 * grey));
        }
        const uint8_t colours[4][3] = {{0, 0, 0}, {255, 200, 0}, {230, 20, 20}, {20, 90, 255}};
        for (int kind = 1; kind <= 3; ++kind)  // stronger marks drawn over weaker ones
            for (size_t i = 0; i < n; ++i)
                if (mark[i] == kind)
                    dot(r.compare_rgb, r.width, r.height, surface.pixel[i] % r.width, surface.pixel[i] / r.width,
                        colours[kind]);
        for (uint8_t m : mark) r.compare.pixels += m != 0, r.compare.pixels_other += m > 1;
    }
    return r;
}

RenderResult render_asset(const AssetView& view, const RenderOptions& options, const RenderProgress& progress) {
    return render_level(baked_level(view), options, progress);
}

}  // namespace cb
