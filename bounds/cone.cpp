// Normal cones with apexes: every point strictly inside the front cone sees every triangle of the cluster
// from its front side (Cone in runtime/cb_asset.h).
#include <algorithm>
#include <vector>

#include "fitting.h"

namespace cb::fitting {
namespace {

struct Plane {
    Vec n;      // unit normal (front side positive)
    Vec point;  // a vertex, world
};

// Where the apexes may start along the axis line through `centre`: the s at which centre + s * axis lies on
// each plane, the highest (front) and lowest (back) of them, and the smallest cosine between the axis and a
// normal. Every normal is within 90 degrees of the axis, so each cosine is positive.
struct ApexStart {
    double front = -INFINITY, back = INFINITY, min_cos = INFINITY;
};
ApexStart apex_start(const std::vector<Plane>& planes, const Vec& axis, const double* centre) {
    ApexStart a;
    for (const Plane& pl : planes) {
        double along = dot3(axis.data(), pl.n.data());
        Vec d = sub(pl.point.data(), centre);
        double need = dot3(d.data(), pl.n.data()) / along;
        a.front = std::max(a.front, need);
        a.back = std::min(a.back, need);
        a.min_cos = std::min(a.min_cos, along);
    }
    return a;
}

// An apex on the axis line through `centre`, strictly on the `sign` side of every plane as decoded: the
// distance along the axis is rounded to float and the apex computed as unpack_cone does, then its
// clearance re-measured, and the apex pushed further until it clears every plane by more than the
// measurement could err or another compiler's decode could move it (two float steps of its coordinates).
// False if it cannot be made to (never guess).
bool place_apex(const std::vector<Plane>& planes, const Vec& axis, const double* centre, double sign, double extent,
                const ApexStart& start, float& stored_s) {
    // The lowest s with sign * dot3(centre + s * axis - point, n) >= 0 for all planes (sign = -1 for the back).
    const double s = sign > 0 ? start.front : start.back, min_cos = start.min_cos;
    // The first push already clears what rounding the apex's coordinates to float may take back (their size
    // from the apex before it), so that one measurement usually settles it: 1.0 of them for an apex of the
    // dragons, where a push of 1e-7 * extent alone took 2.4.
    double reach = 0;
    for (int k = 0; k < 3; ++k) reach = std::max(reach, std::fabs(centre[k] + s * axis[k]));
    double push = 1e-7 * extent + 2.5 * axis_step * reach / min_cos;
    for (int attempt = 0; attempt < 40; ++attempt) {
        stored_s = float(s + sign * push);
        double stored[3], coord = 0;
        for (int k = 0; k < 3; ++k) {
            stored[k] = float(centre[k] + double(stored_s) * axis[k]);
            coord = std::max(coord, std::fabs(stored[k]));
        }
        // Signed clearance of the stored apex from the nearest plane, on the wanted side. The farthest point's
        // distance is the root of the largest squared one: the same double, as rounded roots keep their order.
        double d = INFINITY, scale2 = 0;
        for (const Plane& pl : planes) {
            Vec e = sub(stored, pl.point.data());
            d = std::min(d, sign * dot3(e.data(), pl.n.data()));
            scale2 = std::max(scale2, dot3(e.data(), e.data()));
        }
        const double scale = std::sqrt(scale2);
        double needed = 1e-12 * (scale + extent) + 2 * axis_step * coord;
        if (d > needed && std::isfinite(d)) return true;
        if (!std::isfinite(d) || !std::isfinite(scale)) return false;
        push = push * 4 + (needed - d) / min_cos;
    }
    return false;
}

// The direction of the normals' sum as stored (octahedral) and decoded; false without one.
bool cone_axis(size_t planes, const Vec& sum, PackedCone& packed, Vec& axis) {
    double l1 = std::fabs(sum[0]) + std::fabs(sum[1]) + std::fabs(sum[2]);
    if (planes == 0 || !(l1 > 0)) return false;
    double x = sum[0] / l1, y = sum[1] / l1;
    if (sum[2] < 0) {
        double fx = (1 - std::fabs(y)) * (x < 0 ? -1 : 1), fy = (1 - std::fabs(x)) * (y < 0 ? -1 : 1);
        x = fx;
        y = fy;
    }
    packed.axis[0] = int16_t(std::clamp(std::round(x * 32767), -32767.0, 32767.0));
    packed.axis[1] = int16_t(std::clamp(std::round(y * 32767), -32767.0, 32767.0));
    unpack_octahedral(packed.axis, axis.data());
    return true;
}

// x rounded to float, in a call of its own: with the rounding inlined here, GCC 12 at -O3 vectorises two
// of the axis's three and then reads back their unrounded doubles instead of the floats it stored.
[[gnu::noinline]] float to_float(double x) { return float(x); }

}  // namespace

PackedCone fit_cone(const float* positions, const uint32_t* indices, const uint32_t* tris, size_t count,
                    const double* centre, double extent, float normal[3]) {
    PackedCone none{};
    none.cos_half_angle = 2;  // no valid cone
    normal[0] = normal[1] = normal[2] = 0;
    thread_local std::vector<Plane> planes;  // scratch: no allocation per cluster
    planes.clear();
    Vec sum{0, 0, 0};
    for (size_t i = 0; i < count; ++i) {
        double p[3][3];
        for (int k = 0; k < 3; ++k)
            for (int j = 0; j < 3; ++j) p[k][j] = positions[size_t(indices[size_t(tris[i]) * 3 + k]) * 3 + j];
        Vec n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
        double len = norm(n);
        if (!(len > 0)) continue;  // zero area: no front side, never occludes
        for (int k = 0; k < 3; ++k) sum[k] += n[k];
        planes.push_back({{n[0] / len, n[1] / len, n[2] / len}, {p[0][0], p[0][1], p[0][2]}});
    }
    PackedCone cone{};
    Vec decoded;
    if (!cone_axis(planes.size(), sum, cone, decoded)) return none;
    // Angles are measured from the axis the runtime reads: the decoded one rounded to float.
    for (int k = 0; k < 3; ++k) normal[k] = to_float(decoded[k]);
    Vec axis{normal[0], normal[1], normal[2]};
    double axis_len = norm(axis);
    for (double& a : axis) a /= axis_len;
    double min_cos = INFINITY;
    for (const Plane& pl : planes) min_cos = std::min(min_cos, dot3(axis.data(), pl.n.data()));
    // Half-angle = 90 degrees - widest normal, less a margin that dwarfs the normals' rounding.
    constexpr double angle_margin = 1e-6;
    double widest = std::acos(std::clamp(min_cos, -1.0, 1.0));
    double half = M_PI / 2 - widest - angle_margin;
    if (!(half > 0)) return none;
    // The apexes lie on the decoded (double) axis line through the box centre, as unpack_cone computes
    // them; any line would do, as long as they clear every plane.
    const ApexStart start = apex_start(planes, decoded, centre);
    if (!place_apex(planes, decoded, centre, +1, extent, start, cone.front)) return none;
    if (!place_apex(planes, decoded, centre, -1, extent, start, cone.back)) return none;
    cone.cos_half_angle = round_up(std::cos(half));
    return cone;
}

}  // namespace cb::fitting
