// clusterbake render: a picture of an asset lit by a point or an area light, its shadows from the runtime's
// exact queries (render/); with --compare, also where Embree's rays answer otherwise.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <numeric>
#include <stdexcept>

#include "args.h"
#include "asset_writer.h"
#include "commands.h"
#include "png_writer.h"
#include "progress.h"
#include "render.h"
#include "scene_query.h"

namespace cb::cli {
namespace {

struct RenderArgs {
    std::string asset, out, light, sun, area_light, area_shape = "square", eye, target, up, size = "640x480";
    std::string write_points;
    double fov = 0, bias = 0;
    unsigned aa = 0;  // 0: not given
    bool one_sided = false, compare = false, ground = false, force = false, json = false, quiet = false;
    unsigned threads = 0;
};

// "X,Y,Z", three finite numbers, for option `name`; otherwise a one-line error and false.
bool parse_triple(const std::string& name, const std::string& text, double* out) {
    char extra;
    if (std::sscanf(text.c_str(), "%lf,%lf,%lf%c", &out[0], &out[1], &out[2], &extra) == 3 && std::isfinite(out[0]) &&
        std::isfinite(out[1]) && std::isfinite(out[2]))
        return true;
    return usage_ok(name + " takes X,Y,Z (got '" + text + "')");
}

// "W" (a square) or "WxH", each 16 to 4096 pixels.
bool parse_size(const std::string& text, uint32_t& width, uint32_t& height) {
    unsigned w = 0, h = 0;
    char extra;
    int got = std::sscanf(text.c_str(), "%ux%u%c", &w, &h, &extra);
    if (got == 1 && text.find('x') == std::string::npos) {
        h = w;
        got = 2;
    }
    if (got == 2 && std::isdigit(static_cast<unsigned char>(text[0])) && w >= 16 && h >= 16 && w <= 4096 && h <= 4096) {
        width = w;
        height = h;
        return true;
    }
    return usage_ok("--size takes W or WxH, each 16 to 4096 pixels (got '" + text + "')");
}

// "X,Y,Z,SIZE,N": the centre, a side (or diameter) above zero and 1 to 4096 samples.
bool parse_area_light(const std::string& text, cb::AreaLight& out) {
    double size;
    unsigned samples;
    char extra;
    const double* c = out.centre;
    if (std::sscanf(text.c_str(), "%lf,%lf,%lf,%lf,%u%c", &out.centre[0], &out.centre[1], &out.centre[2], &size,
                    &samples, &extra) == 5 &&
        std::isfinite(c[0]) && std::isfinite(c[1]) && std::isfinite(c[2]) && std::isfinite(size) && size > 0 &&
        samples >= 1 && samples <= 4096) {
        out.size = size;
        out.samples = samples;
        return true;
    }
    return usage_ok("--area-light takes X,Y,Z,SIZE,N: a centre, a size above 0 and 1 to 4096 samples (got '" + text +
                    "')");
}

bool ends_with_png(std::string name) {
    std::transform(name.begin(), name.end(), name.begin(), [](unsigned char ch) { return char(std::tolower(ch)); });
    return name.size() >= 4 && name.compare(name.size() - 4, 4, ".png") == 0;
}

bool starts_with_png_signature(const std::string& path) {
    static const char signature[8] = {'\x89', 'P', 'N', 'G', '\r', '\n', '\x1a', '\n'};
    char head[8] = {};
    std::ifstream in(path, std::ios::binary);
    return in.read(head, 8) && std::memcmp(head, signature, 8) == 0;
}

bool same_file(const std::string& a, const std::string& b) {
    std::error_code ec;
    return std::filesystem::equivalent(a, b, ec);
}

// The picture of where the runtime and Embree differ: beside the output, IMAGE.compare.png.
std::string compare_path(const std::string& out) { return out.substr(0, out.size() - 4) + ".compare.png"; }

// What is wrong with a PNG output path, found before any work, or empty. An existing file that is not a
// PNG is most likely something else named by mistake: kept unless --force.
std::string png_output_error(const RenderArgs& a, const std::string& path) {
    std::string error = output_file_error(path);
    if (!error.empty()) return error;
    if (!ends_with_png(path)) return path + ": render writes PNG; name it .png";
    if (same_file(path, a.asset)) return path + ": is the input asset";
    if (!a.force && std::filesystem::exists(path) && !starts_with_png_signature(path))
        return path + ": exists and is not a PNG; render would replace it (another name, or --force)";
    return {};
}

// The options as the renderer takes them, and every output usable; false after one line on stderr.
bool parse_render(const CLI::App* c, const RenderArgs& a, cb::RenderOptions& o) {
    if (!a.area_light.empty()) {
        if (!a.light.empty()) return usage_ok("--light and --area-light name two lights; give one");
        if (!parse_area_light(a.area_light, o.area_light)) return false;
        o.area_light.shape = a.area_shape == "disc" ? cb::AreaShape::disc : cb::AreaShape::square;
        o.has_area_light = true;
    } else if (refuse_given(c, {"--area-shape"}, "it shapes the light of --area-light")) {
        return false;
    }
    if (!a.sun.empty()) {
        if (!a.light.empty() || !a.area_light.empty()) return usage_ok("--sun and a light name two lights; give one");
        if (!parse_sun(a.sun, o.light)) return false;
        o.has_light = o.sun = true;
    }
    if (!a.light.empty()) {
        if (!parse_triple("--light", a.light, o.light)) return false;
        o.has_light = true;
    }
    if (!a.eye.empty() && !parse_triple("--eye", a.eye, o.eye)) return false;
    if (!a.target.empty() && !parse_triple("--target", a.target, o.target)) return false;
    if (!a.up.empty() && !parse_triple("--up", a.up, o.up)) return false;
    o.has_eye = !a.eye.empty();
    o.has_target = !a.target.empty();
    o.has_up = !a.up.empty();
    if (o.has_eye && o.has_target && o.eye[0] == o.target[0] && o.eye[1] == o.target[1] && o.eye[2] == o.target[2])
        return usage_ok("--eye and --target are the same point: no direction to look in");
    if (!(o.up[0] != 0 || o.up[1] != 0 || o.up[2] != 0)) return usage_ok("--up must not be zero");
    if (!first_given(c, {"--fov"}).empty() && !(a.fov > 0 && a.fov < 170))
        return usage_ok("--fov takes degrees above 0 and below 170 (got " + std::to_string(a.fov) + ")");
    o.fov_degrees = a.fov;
    if (!parse_size(a.size, o.width, o.height)) return false;
    // Samples: at most 4096 x 4096 of them, as the largest picture of one sample a pixel. By default 2 x 2
    // a pixel, or 1 where that would be more.
    const uint64_t pixels = uint64_t(o.width) * o.height, most = uint64_t(4096) * 4096;
    if (!first_given(c, {"--aa"}).empty()) {
        if (a.aa < 1 || a.aa > 4)
            return usage_ok("--aa takes 1 to 4 samples a pixel side (got " + std::to_string(a.aa) + ")");
        if (pixels * a.aa * a.aa > most)
            return usage_ok("--aa " + std::to_string(a.aa) + " at --size " + a.size +
                            " is over 4096 x 4096 samples; a smaller --aa or --size");
        o.aa = a.aa;
    } else {
        o.aa = pixels * 4 <= most ? 2 : 1;
    }
    o.ground = a.ground;
    o.one_sided = a.one_sided;
    o.compare = a.compare;
    o.threads = a.threads;
    if (!(a.bias >= 0 && a.bias < INFINITY))  // NaN too
        return usage_ok("--bias takes a distance of at least 0 (0: the scene's default)");
    o.bias = a.bias;

    if (!usage_ok(png_output_error(a, a.out))) return false;
    if (a.compare && !usage_ok(png_output_error(a, compare_path(a.out)))) return false;
    if (!a.write_points.empty()) {
        std::string error = output_file_error(a.write_points);
        if (error.empty() &&
            (same_file(a.write_points, a.asset) || same_file(a.write_points, a.out) ||
             (!a.force && cb::is_asset_file(a.write_points))))
            error = a.write_points + ": is an asset or the picture; --write-points would replace it";
        if (!usage_ok(error)) return false;
    }
    return true;
}

std::string points_text(const std::vector<double>& points) {
    std::string text;
    char line[96];
    for (size_t i = 0; i + 2 < points.size(); i += 3) {
        int n = std::snprintf(line, sizeof line, "%.17g %.17g %.17g\n", points[i], points[i + 1], points[i + 2]);
        text.append(line, size_t(n));
    }
    return text;
}

struct LightTimes {
    double mean = 0, shortest = 0, longest = 0;  // build plus queries, per light
};

LightTimes light_times(const cb::RenderResult& r) {
    LightTimes t;
    const size_t n = r.build_seconds.size();
    if (!n) return t;
    std::vector<double> each(n);
    for (size_t l = 0; l < n; ++l) each[l] = r.build_seconds[l] + r.query_seconds[l];
    t.mean = std::accumulate(each.begin(), each.end(), 0.0) / double(n);
    t.shortest = *std::min_element(each.begin(), each.end());
    t.longest = *std::max_element(each.begin(), each.end());
    return t;
}

double sum(const std::vector<double>& v) { return std::accumulate(v.begin(), v.end(), 0.0); }

void print_json(const RenderArgs& a, const cb::RenderOptions& o, const cb::RenderResult& r) {
    const cb::Camera& cam = r.camera;
    const LightTimes t = light_times(r);
    nlohmann::json j = {{"tool", cb::tool_version()},
                        {"asset", a.asset},
                        {"output", a.out},
                        {"width", r.width},
                        {"height", r.height},
                        {"camera",
                         {{"eye", {cam.eye[0], cam.eye[1], cam.eye[2]}},
                          {"forward", {cam.forward[0], cam.forward[1], cam.forward[2]}},
                          {"up", {cam.up[0], cam.up[1], cam.up[2]}},
                          {"fov", r.fov_degrees}}},
                        {"one_sided", o.one_sided},
                        {"bias", r.bias},
                        {"lights", r.lights.size() / 3},
                        {"light_positions", r.lights},
                        {"aa", r.aa},
                        {"pixels_covered", r.pixels_covered},
                        {"points", r.points.size() / 3},
                        {"framed_box",
                         {{"lo", {r.frame_lo[0], r.frame_lo[1], r.frame_lo[2]}},
                          {"hi", {r.frame_hi[0], r.frame_hi[1], r.frame_hi[2]}}}},
                        {"ground_instances", r.ground_instances},
                        {"ground", r.ground},
                        {"clusters_drawn", r.clusters_drawn},
                        {"triangles_drawn", r.triangles_drawn},
                        {"queries", r.queries},
                        {"shadowed", r.shadowed},
                        {"shadowed_fraction", r.queries ? double(r.shadowed) / double(r.queries) : 0.0},
                        {"lanes", cb::query_lanes()},
                        {"visibility_seconds", r.visibility_seconds},
                        {"bounds_seconds", r.bounds_seconds},
                        {"seconds_per_light", {{"mean", t.mean}, {"shortest", t.shortest}, {"longest", t.longest}}},
                        {"build_seconds", r.build_seconds},
                        {"query_seconds", r.query_seconds}};
    if (o.has_area_light)
        j["area_light"] = {{"centre", {o.area_light.centre[0], o.area_light.centre[1], o.area_light.centre[2]}},
                           {"size", o.area_light.size},
                           {"samples", o.area_light.samples},
                           {"shape", a.area_shape}};
    else
        j[o.sun ? "sun" : "light"] = {r.lights[0], r.lights[1], r.lights[2]};
    if (!a.write_points.empty()) j["points_output"] = a.write_points;
    if (o.compare)
        j["compare"] = {{"output", compare_path(a.out)},
                        {"pairs", r.compare.pairs},
                        {"differing", r.compare.runtime_only + r.compare.embree_only},
                        {"runtime_only", r.compare.runtime_only},
                        {"embree_only", r.compare.embree_only},
                        {"ties", r.compare.ties},
                        {"near_ties", r.compare.near_ties},
                        {"pixels", r.compare.pixels},
                        {"pixels_other", r.compare.pixels_other},
                        {"embree_build_seconds", r.compare.build_seconds},
                        {"embree_query_seconds", r.compare.query_seconds}};
    std::cout << j.dump(2) << "\n";
}

void print_summary(const RenderArgs& a, const cb::RenderOptions& o, const cb::RenderResult& r) {
    const size_t lights = r.lights.size() / 3, points = r.points.size() / 3;
    const LightTimes t = light_times(r);
    std::printf(
        "%s -> %s (%ux%u, %.1f degrees, %ux%u samples a pixel): %llu pixels see the scene, %zu points%s; %llu "
        "clusters, %llu triangles drawn in %.3f s\n",
        a.asset.c_str(), a.out.c_str(), r.width, r.height, r.fov_degrees, r.aa, r.aa,
        (unsigned long long)r.pixels_covered, points, r.ground ? " (ground plane added)" : "",
        (unsigned long long)r.clusters_drawn, (unsigned long long)r.triangles_drawn, r.visibility_seconds);
    if (r.ground_instances)
        std::printf("  framed the objects: %zu ground instance%s left out of the framed box\n", r.ground_instances,
                    r.ground_instances == 1 ? "" : "s");
    std::printf("  %zu %s%s: %.2f%% of %llu point-light pairs in shadow (%s occluders)\n", lights,
                o.sun             ? "sun"
                    : lights == 1 ? "light"
                                  : "lights",
                o.has_area_light ? (a.area_shape == "disc" ? " on a disc" : " on a square") : "",
                r.queries ? 100.0 * double(r.shadowed) / double(r.queries) : 0.0, (unsigned long long)r.queries,
                o.one_sided ? "one-sided" : "two-sided");
    const double query_total = sum(r.query_seconds);
    std::printf(
        "  per light %.2f ms (%.2f to %.2f): build %.2f ms, queries %.2f ms (%.2f M queries/s on %s lanes); scan "
        "bounds %.2f ms once\n",
        1e3 * t.mean, 1e3 * t.shortest, 1e3 * t.longest,
        1e3 * sum(r.build_seconds) / double(std::max<size_t>(lights, 1)),
        1e3 * query_total / double(std::max<size_t>(lights, 1)),
        query_total > 0 ? double(r.queries) / query_total / 1e6 : 0.0, cb::query_lanes(), 1e3 * r.bounds_seconds);
    if (o.compare)
        std::printf(
            "  compare -> %s: %llu pairs, %llu differ (%llu shadowed by the runtime alone, %llu by Embree alone; %llu "
            "ties, %llu near ties); %llu pixels differ, %llu other than by a tie or near tie; Embree %.3f s to "
            "build, %.3f s of rays\n",
            compare_path(a.out).c_str(), (unsigned long long)r.compare.pairs,
            (unsigned long long)(r.compare.runtime_only + r.compare.embree_only),
            (unsigned long long)r.compare.runtime_only, (unsigned long long)r.compare.embree_only,
            (unsigned long long)r.compare.ties, (unsigned long long)r.compare.near_ties,
            (unsigned long long)r.compare.pixels, (unsigned long long)r.compare.pixels_other, r.compare.build_seconds,
            r.compare.query_seconds);
    if (!a.write_points.empty()) std::printf("  visible points -> %s\n", a.write_points.c_str());
}

int run_render(const CLI::App* c, const RenderArgs& a) {
    cb::RenderOptions options;
    if (!parse_render(c, a, options)) return exit_usage;
    LoadedLevel level;
    if (!load_level(a.asset, level)) return exit_bad_input;
    ProgressLine progress(!a.quiet);
    cb::RenderResult r;
    try {
        r = cb::render_level(level.level, options, [&](const std::string& stage, double fraction) {
            if (fraction < 0) return progress.stage(stage);
            if (fraction == 0) progress.restart();  // the time left is the lights'
            progress.show(fraction, stage);
        });
    } catch (const std::runtime_error& e) {
        progress.clear();
        std::fprintf(stderr, "%s: %s\n", a.asset.c_str(), e.what());
        return exit_bad_input;
    }
    try {
        progress.stage("writing " + a.out);
        cb::write_file_atomic(a.out, cb::encode_png_rgb(r.rgb.data(), r.width, r.height));
        if (options.compare)
            cb::write_file_atomic(compare_path(a.out), cb::encode_png_rgb(r.compare_rgb.data(), r.width, r.height));
        if (!a.write_points.empty()) {
            std::string text = points_text(r.points);
            cb::write_file_atomic(a.write_points, std::vector<uint8_t>(text.begin(), text.end()));
        }
    } catch (const std::runtime_error& e) {  // names the path
        progress.clear();
        std::fprintf(stderr, "%s\n", e.what());
        return exit_bad_input;
    }
    progress.clear();
    if (a.json)
        print_json(a, options, r);
    else
        print_summary(a, options, r);
    return 0;
}

}  // namespace

Command add_render(CLI::App& app) {
    auto a = std::make_shared<RenderArgs>();
    CLI::App* c = app.add_subcommand("render",
                                     "Render an asset or a level to PNG: Lambert shading, exact shadows of a point or "
                                     "an area light or a sun from the runtime");
    c->add_option("asset", a->asset, "Asset (.cbk), or a level file placing several (JSON, docs/RUNTIME.md)")
        ->required();
    c->add_option("-o,--output", a->out, "Output PNG (written atomically)")->required();
    c->add_option("--light", a->light,
                  "Point light X,Y,Z (default: above the framed objects, 45 degrees to the camera's left, 50 up)");
    c->add_option("--sun", a->sun, "A sun: a light at infinity, X,Y,Z the world direction toward it (any length)");
    c->add_option("--area-light", a->area_light,
                  "Area light X,Y,Z,SIZE,N: a square of side SIZE (or a disc of that diameter) centred at X,Y,Z and "
                  "facing the scene's centre, sampled by N point lights (1 to 4096) on a jittered grid");
    c->add_option("--area-shape", a->area_shape, "square (default) or disc")->check(CLI::IsMember({"square", "disc"}));
    c->add_option("--eye", a->eye,
                  "Camera position X,Y,Z (default: a diagonal above the scene, or its objects when a ground is "
                  "left out)");
    c->add_option("--target", a->target, "Point the camera looks at X,Y,Z (default: the framed box's centre)");
    c->add_option("--up", a->up, "Direction kept upright in the picture X,Y,Z (default 0,1,0)");
    c->add_option("--fov", a->fov, "Vertical field of view in degrees (default: what holds the whole scene)");
    c->add_option("--size", a->size, "Picture size W or WxH in pixels, 16 to 4096 (default 640x480)");
    c->add_option("--aa", a->aa,
                  "Anti-aliasing: N x N samples a pixel on a regular grid, 1 to 4 (default 2; 1 above 2048x2048 "
                  "pixels)");
    c->add_flag("--ground", a->ground,
                "Add a ground plane just under the scene's box, lit and shadowed as the scene (the asset is "
                "unchanged)");
    c->add_flag("--one-sided", a->one_sided,
                "One-sided occluders: a triangle blocks only when the light is behind it "
                "(double-sided glTF primitives stay two-sided)");
    c->add_option("--bias", a->bias,
                  "Self-shadowing bias, a world distance: contacts nearer to the point do not count (default 0: "
                  "1/65536 of the largest side of the scene's world box)");
    c->add_flag("--compare", a->compare,
                "Also ask Embree's rays, and write OUTPUT's .compare.png: the pixels where the answers differ");
    c->add_option("--write-points", a->write_points,
                  "Write each covered pixel's visible point, text lines 'x y z' as query --points reads them");
    c->add_option("--threads", a->threads, threads_help("the picture does not depend on it"));
    c->add_flag("--force", a->force, "Write even over an existing file that is not a PNG");
    c->add_flag("--json", a->json, "Print the summary as JSON");
    c->add_flag("-q,--quiet", a->quiet, "No progress on stderr");
    return {c, [a, c] { return run_render(c, *a); }};
}

}  // namespace cb::cli
