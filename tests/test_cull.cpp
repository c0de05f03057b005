// Cluster culling: conservative against an independent oracle (triangles clipped against the frustum, and
// exact back-facing tests), and it does cull.
#include <gtest/gtest.h>

#include <cb_cull.h>
#include <detail/cb_exact.h>

#include <random>

#include "baked.h"

namespace {

// A perspective frustum from `eye` towards `target`: near, far and four sides through the eye.
cb::Frustum perspective(const double* eye, const double* target, double half_fov_tan, double near, double far) {
    double dir[3], len = 0;
    for (int k = 0; k < 3; ++k) {
        dir[k] = target[k] - eye[k];
        len += dir[k] * dir[k];
    }
    for (double& x : dir) x /= std::sqrt(len);
    double up0[3] = {0, 1, 0};
    if (std::fabs(dir[1]) > 0.9) {
        up0[0] = 1;
        up0[1] = 0;
    }
    double right[3] = {dir[1] * up0[2] - dir[2] * up0[1], dir[2] * up0[0] - dir[0] * up0[2],
                       dir[0] * up0[1] - dir[1] * up0[0]};
    double rl = std::sqrt(right[0] * right[0] + right[1] * right[1] + right[2] * right[2]);
    for (double& x : right) x /= rl;
    double up[3] = {right[1] * dir[2] - right[2] * dir[1], right[2] * dir[0] - right[0] * dir[2],
                    right[0] * dir[1] - right[1] * dir[0]};
    cb::Frustum f;
    for (int k = 0; k < 3; ++k) f.eye[k] = eye[k];
    auto set = [&](int i, const double* n, double d) {
        for (int k = 0; k < 3; ++k) f.plane[i][k] = n[k];
        f.plane[i][3] = d;
    };
    double ed = dir[0] * eye[0] + dir[1] * eye[1] + dir[2] * eye[2];
    set(0, dir, -(ed + near));
    double back[3] = {-dir[0], -dir[1], -dir[2]};
    set(1, back, ed + far);
    double corner[4][3];
    for (int c = 0; c < 4; ++c)
        for (int k = 0; k < 3; ++k)
            corner[c][k] = dir[k] + half_fov_tan * ((c == 0 || c == 3) ? -1 : 1) * right[k] +
                half_fov_tan * (c < 2 ? -1 : 1) * up[k];
    for (int c = 0; c < 4; ++c) {
        const double* a = corner[c];
        const double* b = corner[(c + 1) % 4];
        double n[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
        if (n[0] * dir[0] + n[1] * dir[1] + n[2] * dir[2] < 0)
            for (double& x : n) x = -x;
        set(2 + c, n, -(n[0] * eye[0] + n[1] * eye[1] + n[2] * eye[2]));
    }
    f.count = 6;
    return f;
}

// Does the triangle reach strictly inside the frustum (planes pulled in by `inset`)? Sutherland-Hodgman.
bool triangle_inside(const double tri[3][3], const cb::Frustum& f, double inset) {
    std::vector<std::array<double, 3>> poly = {
        {tri[0][0], tri[0][1], tri[0][2]}, {tri[1][0], tri[1][1], tri[1][2]}, {tri[2][0], tri[2][1], tri[2][2]}};
    for (int k = 0; k < f.count && !poly.empty(); ++k) {
        const double* pl = f.plane[k];
        double nl = std::sqrt(pl[0] * pl[0] + pl[1] * pl[1] + pl[2] * pl[2]);
        auto dist = [&](const std::array<double, 3>& p) {
            return (pl[0] * p[0] + pl[1] * p[1] + pl[2] * p[2] + pl[3]) / nl - inset;
        };
        std::vector<std::array<double, 3>> next;
        for (size_t i = 0; i < poly.size(); ++i) {
            const auto& a = poly[i];
            const auto& b = poly[(i + 1) % poly.size()];
            double da = dist(a), db = dist(b);
            if (da > 0) next.push_back(a);
            if ((da > 0) != (db > 0)) {
                double t = da / (da - db);
                next.push_back({a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])});
            }
        }
        poly.swap(next);
    }
    return !poly.empty();
}

}  // namespace

TEST(Cull, ConservativeAndEffectiveOnTheDefaultScene) {
    cb::test::Baked baked = cb::test::bake(std::string(CB_SOURCE_DIR) + "/data/default_scene.glb");
    ASSERT_GT(baked.view.mesh_count, 0u) << "bake failed";
    const cb::AssetView& v = baked.view;

    std::mt19937 rng(4);
    std::uniform_real_distribution<double> u(-1, 1);
    size_t listed = 0, total = 0, missed = 0, wrong_backface = 0;
    cb::CullStats stats;
    std::vector<cb::VisibleCluster> out(v.fine_count * v.instance_count);
    for (int view = 0; view < 40; ++view) {
        double eye[3] = {u(rng) * 25, 1 + 6 * (u(rng) + 1), u(rng) * 25},
               target[3] = {u(rng) * 10, 0.5 * (u(rng) + 1), u(rng) * 10};
        cb::Frustum f = perspective(eye, target, 0.3 + 0.4 * (u(rng) + 1), 0.1, 25 + 15 * u(rng));
        bool backface = view % 2 == 0;
        size_t n = cb::cull_clusters(v, f, backface, out.data(), out.size(), &stats);
        ASSERT_LE(n, out.size());
        std::vector<std::vector<bool>> visible(v.instance_count, std::vector<bool>(v.fine_count, false));
        for (size_t i = 0; i < n; ++i) visible[out[i].instance][out[i].fine] = true;
        listed += n;
        for (uint32_t i = 0; i < v.instance_count; ++i) {
            const cb::MeshRecord& m = v.meshes[v.instances[i].mesh];
            double inv[12], eye_local[3];
            ASSERT_TRUE(cb::invert_instance(v.instances[i].transform, inv));
            cb::apply_instance(inv, eye, eye_local);
            for (uint32_t c = 0; c < m.fine_count; ++c) {
                ++total;
                if (visible[i][m.first_fine + c]) continue;
                const cb::FineCluster& r = v.fine[m.first_fine + c];
                bool all_back = true, any_inside = false;
                for (uint32_t t = r.first_triangle; t < r.first_triangle + r.triangle_count; ++t) {
                    double local[3][3], world[3][3];
                    uint32_t id[3];
                    v.triangle(m, c, t, id);
                    for (int k = 0; k < 3; ++k) {
                        const float* q = v.position(m, id[k]);
                        local[k][0] = q[0];
                        local[k][1] = q[1];
                        local[k][2] = q[2];
                        cb::apply_instance(v.instances[i].transform, local[k], world[k]);
                    }
                    any_inside |= triangle_inside(world, f, 1e-6);
                    // Back side of a triangle with an area: cb::exact::orient3d is +1 (checked against CGAL elsewhere).
                    int o = cb::exact::orient3d(local[0], local[1], local[2], eye_local);
                    double e1[3], e2[3];
                    for (int k = 0; k < 3; ++k) {
                        e1[k] = local[1][k] - local[0][k];
                        e2[k] = local[2][k] - local[0][k];
                    }
                    bool degenerate = e1[1] * e2[2] - e1[2] * e2[1] == 0 && e1[2] * e2[0] - e1[0] * e2[2] == 0 &&
                        e1[0] * e2[1] - e1[1] * e2[0] == 0;  // no area: no side to face
                    if (o != 1 && !degenerate) all_back = false;
                    if (v.double_sided(size_t(m.first_triangle) + t)) all_back = false;
                }
                // A cluster left out must have nothing inside the frustum, or (back-face culling on) face
                // away from the eye entirely.
                if (any_inside && !(backface && all_back)) ++missed;
                if (any_inside && backface && !all_back) ++wrong_backface;
            }
        }
    }
    std::printf(
        "%zu of %zu (instance, cluster) pairs listed over 40 views; culled: %llu coarse, %llu by frustum, %llu by back "
        "face; %zu wrongly culled\n",
        listed, total, (unsigned long long)stats.coarse_culled, (unsigned long long)stats.frustum_culled,
        (unsigned long long)stats.backface_culled, missed);
    EXPECT_EQ(missed, 0u);
    EXPECT_EQ(wrong_backface, 0u);
    EXPECT_LT(listed, total * 2 / 3);  // it does cull
    EXPECT_GT(stats.backface_culled, 0u);
    EXPECT_GT(stats.coarse_culled, 0u);
}
