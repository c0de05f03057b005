// Minimal spheres and circles (Welzl's algorithm with move to front), and Ritter's approximate sphere as a
// baseline.
#include <Eigen/LU>

#include <algorithm>
#include <numeric>
#include <vector>

#include "fitting.h"

namespace cb {
namespace fitting {
namespace {

Ball ball_of(const double* const* s, int k);

Ball farthest_pair_ball(const double* const* s, int k) {
    Ball best{{0, 0, 0}, -1};
    for (int i = 0; i < k; ++i)
        for (int j = i + 1; j < k; ++j) {
            const double* pair[2] = {s[i], s[j]};
            Ball b = ball_of(pair, 2);
            if (b.r2 > best.r2) best = b;
        }
    return best;
}

Ball ball_of(const double* const* s, int k) {
    Ball b{{0, 0, 0}, -1};
    if (k == 0) return b;
    if (k == 1) return {{s[0][0], s[0][1], s[0][2]}, 0};
    if (k == 2) {
        for (int i = 0; i < 3; ++i) b.c[i] = 0.5 * (s[0][i] + s[1][i]);
        Vec d = sub(s[0], s[1]);
        b.r2 = 0.25 * dot3(d.data(), d.data());
        return b;
    }
    Vec a = sub(s[1], s[0]), c = sub(s[2], s[0]);
    if (k == 3) {
        Vec n = cross(a, c);
        double n2 = dot3(n.data(), n.data());
        double scale = dot3(a.data(), a.data()) * dot3(c.data(), c.data());
        if (!(n2 > 1e-24 * scale)) return farthest_pair_ball(s, 3);  // collinear
        Vec t1 = cross(n, a), t2 = cross(c, n);
        double ca = dot3(c.data(), c.data()), aa = dot3(a.data(), a.data());
        for (int i = 0; i < 3; ++i) b.c[i] = s[0][i] + (ca * t1[i] + aa * t2[i]) / (2 * n2);
        Vec r = sub(b.c, s[0]);
        b.r2 = dot3(r.data(), r.data());
        return b;
    }
    // k == 4: circumsphere, or (coplanar) the smallest 3-point ball that holds the fourth.
    Vec d = sub(s[3], s[0]);
    Eigen::Matrix3d m;
    m << a[0], a[1], a[2], c[0], c[1], c[2], d[0], d[1], d[2];
    double det = m.determinant(), scale = norm(a) * norm(c) * norm(d);
    if (std::fabs(det) > 1e-12 * scale) {
        Eigen::Vector3d rhs(0.5 * dot3(a.data(), a.data()), 0.5 * dot3(c.data(), c.data()),
                            0.5 * dot3(d.data(), d.data()));
        Eigen::Vector3d x = m.partialPivLu().solve(rhs);
        for (int i = 0; i < 3; ++i) b.c[i] = s[0][i] + x[i];
        b.r2 = x.squaredNorm();
        return b;
    }
    Ball best{{0, 0, 0}, INFINITY};
    for (int skip = 0; skip < 4; ++skip) {
        const double* t[3];
        int j = 0;
        for (int i = 0; i < 4; ++i)
            if (i != skip) t[j++] = s[i];
        Ball cand = ball_of(t, 3);
        Vec e = sub(s[skip], cand.c);
        if (dot3(e.data(), e.data()) <= cand.r2 * (1 + 1e-9) && cand.r2 < best.r2) best = cand;
    }
    return std::isfinite(best.r2) ? best : farthest_pair_ball(s, 4);
}

bool outside(const Ball& b, const double* p) {
    Vec d = sub(p, b.c);
    return dot3(d.data(), d.data()) > b.r2 * (1 + 1e-12) + 1e-300;
}

// Gärtner's move-to-front Welzl: `order` is permuted as points move to the front.
Ball welzl(const double* pts, std::vector<uint32_t>& order, size_t end, const double** support, int k,
           int max_support) {
    Ball b = ball_of(support, k);
    if (k == max_support) return b;
    for (size_t i = 0; i < end; ++i) {
        const double* p = pts + size_t(order[i]) * 3;
        if (b.r2 >= 0 && !outside(b, p)) continue;
        support[k] = p;
        b = welzl(pts, order, i, support, k + 1, max_support);
        std::rotate(order.begin(), order.begin() + std::ptrdiff_t(i), order.begin() + std::ptrdiff_t(i) + 1);
    }
    return b;
}

}  // namespace

Ball min_ball(const double* pts, size_t n, int dims) {
    thread_local std::vector<uint32_t> order;
    order.resize(n);
    std::iota(order.begin(), order.end(), 0u);
    // Points likely on the final sphere first (the farthest from the first point, then from that one):
    // move-to-front then rarely has to restart.
    auto farthest = [&](uint32_t from) {
        uint32_t best = 0;
        double d = -1;
        for (uint32_t v = 0; v < n; ++v) {
            Vec e = sub(pts + size_t(v) * 3, pts + size_t(from) * 3);
            double dd = dot3(e.data(), e.data());
            if (dd > d) {
                d = dd;
                best = v;
            }
        }
        return best;
    };
    if (n > 2) {
        uint32_t a = farthest(0), b = farthest(a);
        std::swap(order[0], order[a]);
        std::swap(order[1], order[b == 0 ? a : b]);
    }
    const double* support[4] = {};
    return welzl(pts, order, n, support, 0, dims + 1);
}

Sphere store_sphere(const double* centre, const double* world, size_t n) {
    Sphere s;
    for (int k = 0; k < 3; ++k) s.center[k] = float(centre[k]);
    double c[3] = {s.center[0], s.center[1], s.center[2]}, r = 0;
    for (size_t v = 0; v < n; ++v) {
        Vec d = sub(world + v * 3, c);
        r = std::max(r, norm(d));
    }
    s.radius = round_up(r * (1 + measure_margin));
    return s;
}

}  // namespace fitting

using namespace fitting;

Sphere fit_sphere(const double* local, size_t n, const double* origin) {
    std::vector<double> world(n * 3);
    for (size_t i = 0; i < n * 3; ++i) world[i] = local[i] + origin[i % 3];
    Ball b = min_ball(local, n, 3);
    double c[3] = {b.c[0] + origin[0], b.c[1] + origin[1], b.c[2] + origin[2]};
    return store_sphere(c, world.data(), n);
}

Sphere ritter_sphere(const double* local, size_t n, const double* origin) {
    // Farthest point from the first, farthest from that, then grow to take in stragglers.
    auto farthest = [&](const double* from) {
        size_t best = 0;
        double d = -1;
        for (size_t v = 0; v < n; ++v) {
            Vec e = sub(local + v * 3, from);
            double dd = dot3(e.data(), e.data());
            if (dd > d) {
                d = dd;
                best = v;
            }
        }
        return local + best * 3;
    };
    const double* a = farthest(local);
    const double* b = farthest(a);
    double c[3] = {(a[0] + b[0]) / 2, (a[1] + b[1]) / 2, (a[2] + b[2]) / 2};
    double r = norm(sub(a, b)) / 2;
    for (size_t v = 0; v < n; ++v) {
        double d = norm(sub(local + v * 3, c));
        if (d > r) {
            double nr = (r + d) / 2, k = (nr - r) / d;
            for (int i = 0; i < 3; ++i) c[i] += (local[v * 3 + i] - c[i]) * k;
            r = nr;
        }
    }
    std::vector<double> world(n * 3);
    for (size_t i = 0; i < n * 3; ++i) world[i] = local[i] + origin[i % 3];
    double cw[3] = {c[0] + origin[0], c[1] + origin[1], c[2] + origin[2]};
    return store_sphere(cw, world.data(), n);
}

}  // namespace cb
