// Capsules about a cluster's box axis.
#include <algorithm>
#include <vector>

#include "fitting.h"

namespace cb::fitting {
namespace {

// The distance from p to segment a..b, an upper bound of the exact one but for a few units in the last
// place of max(|p - a|, |b - a|): any t in [0, 1] gives a point of the segment, so an inexact t only
// overestimates, and the offset is formed from differences alone. (The closest point itself, a + t (b - a),
// would be rounded to the absolute coordinates: 1e-11 at 1e5, far above a margin relative to the cluster.)
double segment_distance(const double* p, const double* a, const double* b) {
    Vec ab = sub(b, a), ap = sub(p, a);
    double len2 = dot3(ab.data(), ab.data());
    double t = len2 > 0 ? std::clamp(dot3(ap.data(), ab.data()) / len2, 0.0, 1.0) : 0.0;
    Vec d = {ap[0] - t * ab[0], ap[1] - t * ab[1], ap[2] - t * ab[2]};
    return norm(d);
}

}  // namespace

Capsule fit_capsule(const Frame& f, int major, const double* local, size_t n, const double* origin,
                    const double* world) {
    int u = (major + 1) % 3, w = (major + 2) % 3;
    std::vector<double> plane(n * 3, 0.0);
    for (size_t v = 0; v < n; ++v) {
        plane[v * 3] = dot3(local + v * 3, f.axis[u]);
        plane[v * 3 + 1] = dot3(local + v * 3, f.axis[w]);
    }
    Ball circle = min_ball(plane.data(), n, 2);
    double r = std::sqrt(std::max(0.0, circle.r2));
    double lo = INFINITY, hi = -INFINITY;  // t range the segment must cover
    for (size_t v = 0; v < n; ++v) {
        double t = dot3(local + v * 3, f.axis[major]);
        double du = plane[v * 3] - circle.c[0], dw = plane[v * 3 + 1] - circle.c[1];
        double s = std::sqrt(std::max(0.0, r * r - du * du - dw * dw));
        lo = std::min(lo, t + s);  // the segment must start no later than t + s
        hi = std::max(hi, t - s);  // and end no earlier than t - s
    }
    if (lo > hi) lo = hi = 0.5 * (lo + hi);
    Capsule cap;
    double a[3], b[3];
    for (int k = 0; k < 3; ++k) {
        double base = origin[k] + circle.c[0] * f.axis[u][k] + circle.c[1] * f.axis[w][k];
        a[k] = base + lo * f.axis[major][k];
        b[k] = base + hi * f.axis[major][k];
        cap.a[k] = float(a[k]);
        cap.b[k] = float(b[k]);
    }
    double fa[3] = {cap.a[0], cap.a[1], cap.a[2]}, fb[3] = {cap.b[0], cap.b[1], cap.b[2]};
    double worst = 0, reach = norm(sub(fb, fa));
    for (size_t v = 0; v < n; ++v) {
        worst = std::max(worst, segment_distance(world + v * 3, fa, fb));
        reach = std::max(reach, norm(sub(world + v * 3, fa)));
    }
    cap.radius = round_up(worst + measure_margin * reach);
    return cap;
}

}  // namespace cb::fitting
