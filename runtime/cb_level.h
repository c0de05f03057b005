// A whole level at run time: instances of meshes from one or several opened assets, each placed by a world
// transform the caller gives and may change between frames, over a light-independent hierarchy of their
// world boxes. Shadow queries for a light (LevelShadow) cull the instances against each tile's pyramid from
// the light before any per-instance work, so that a tile's cost follows the instances its pyramid meets, not
// how many the level holds; only the instances some tile meets are set up for the light. Camera culling
// (cull_clusters over a Level) walks the same hierarchy.
//
// Work is split into ranges for the caller's job system; the runtime starts no thread. Building and
// committing allocate (std::vector); answering does not, is const, and may run from many threads at once.
// Header-only C++17, no exceptions. MIT licensed (runtime/LICENSE).
#pragma once

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <new>
#include <vector>

#include "cb_asset.h"
#include "cb_batch.h"
#include "cb_instance_shadow.h"
#include "cb_cull.h"
#include "detail/cb_math.h"
#include "cb_scan_bounds.h"
#include "cb_segment.h"
#include "cb_shadow.h"
#include "detail/cb_tile.h"

namespace cb {
inline namespace CB_LANES {

namespace level_detail {

// An allocator of these lanes' own: a std::vector of a plain type made through it is a type of these lanes,
// so that the linker never takes a wider build's copy of one of its members for the baseline's (cb_simd.h).
template <class T>
struct LaneAllocator : std::allocator<T> {
    template <class U>
    struct rebind {
        using other = LaneAllocator<U>;
    };
    LaneAllocator() = default;
    template <class U>
    LaneAllocator(const LaneAllocator<U>&) {}
};
template <class T>
using LaneVector = std::vector<T, LaneAllocator<T>>;

// An axis-aligned box in world space, in double; empty when lo > hi (it meets nothing).
struct Box {
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    bool empty() const { return !(lo[0] <= hi[0] && lo[1] <= hi[1] && lo[2] <= hi[2]); }
    void add(const Box& b) {
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], b.lo[k]);
            hi[k] = std::max(hi[k], b.hi[k]);
        }
    }
};

// The centre and half extents of the mesh-frame box `local`; false when it is empty or `m` is singular or not
// finite (placed so, it blocks nothing).
inline bool placed_halves(const Box& local, const double* m, double* c, double* h) {
    double inverse[12];
    if (local.empty() || !invert_instance(m, inverse)) return false;
    for (int k = 0; k < 3; ++k) {
        c[k] = 0.5 * (local.lo[k] + local.hi[k]);
        h[k] = 0.5 * (local.hi[k] - local.lo[k]);
    }
    return true;
}

// The world box of the mesh-frame box `local` under `m` (column-major 3x4): centre moved, half extents
// through |M|, then widened by 1e-9 of its size and distance from the origin, far above the rounding of
// these sums and of the inverse transform that the queries apply (so a contact the exact mesh-frame test
// finds lies inside it). Empty when the transform is singular or not finite (such an instance blocks
// nothing) or the mesh has no vertex.
inline Box transform_box(const Box& local, const double* m) {
    Box out;
    double c[3], h[3];
    if (!placed_halves(local, m, c, h)) return out;
    double wc[3], wh[3], size = 0;
    apply_instance(m, c, wc);
    for (int k = 0; k < 3; ++k) {
        wh[k] = std::fabs(m[k]) * h[0] + std::fabs(m[3 + k]) * h[1] + std::fabs(m[6 + k]) * h[2];
        size += std::fabs(wc[k]) + wh[k] + std::fabs(m[9 + k]);
    }
    const double pad = 1e-9 * size;
    if (!(pad < INFINITY)) return out;  // beyond double's range: nothing there can be tested exactly anyway
    for (int k = 0; k < 3; ++k) {
        out.lo[k] = wc[k] - wh[k] - pad;
        out.hi[k] = wc[k] + wh[k] + pad;
    }
    return out;
}

// A mesh flat along axis `axis` of its frame: every corner's coordinate on it within [lo, hi] (its box's).
// A segment that stays outside that slab meets none of the mesh's triangles, whatever their shape.
struct Slab {
    int axis = -1;  // none: the mesh is not flat
    double lo = 0, hi = 0;
};

// The slab of a mesh whose box is thinner along an axis than 1e-6 of its largest side (a ground plane of two
// triangles, a floor): points lying on it, whose segments rise off it toward the light, are settled by the
// slab alone (LevelShadow's flat test) instead of entering the instance.
inline Slab flat_slab(const Box& b) {
    Slab s;
    if (b.empty()) return s;
    double largest = 0;
    int thin = 0;
    for (int k = 0; k < 3; ++k) {
        largest = std::max(largest, b.hi[k] - b.lo[k]);
        if (b.hi[k] - b.lo[k] < b.hi[thin] - b.lo[thin]) thin = k;
    }
    if (!(largest < INFINITY) || !(b.hi[thin] - b.lo[thin] <= 1e-6 * largest)) return s;
    s.axis = thin;
    s.lo = b.lo[thin];
    s.hi = b.hi[thin];
    return s;
}

// A box in world space along three unit axes (rows), in double: centre c, half extents h; empty when h[0] is
// below 0 (it meets nothing).
struct OrientedBox {
    double c[3] = {0, 0, 0}, h[3] = {-1, -1, -1}, axis[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    bool empty() const { return !(h[0] >= 0); }
};

// The box about the mesh-frame box `local` under `m` (column-major 3x4) along m's columns made orthonormal
// (u0 along the first, u1 in the plane of the first two): on each axis u the half extent is the sum over
// local axes k of h_k |u . m_k|, which holds the placed box whatever m is (sheared too) and is tight for a
// rotation with scales; widened by 1e-9 of its size and distance from the origin, as transform_box is. Where
// the axes come out further than 1e-12 from orthonormal (a nearly singular shear), the world axes. Empty
// where transform_box's box is.
inline OrientedBox orient_box(const Box& local, const double* m) {
    OrientedBox out;
    double c[3], h[3];
    if (!placed_halves(local, m, c, h)) return out;
    apply_instance(m, c, out.c);
    double(&u)[3][3] = out.axis;
    const double* col[3] = {m, m + 3, m + 6};
    const double l0 = std::sqrt(math::dot3(col[0], col[0]));
    const double along = math::dot3(col[1], col[0]) / (l0 * l0);
    double v[3];
    for (int k = 0; k < 3; ++k) {
        u[0][k] = col[0][k] / l0;
        v[k] = col[1][k] - along * col[0][k];
    }
    const double l1 = std::sqrt(math::dot3(v, v));
    for (int k = 0; k < 3; ++k) u[1][k] = v[k] / l1;
    math::cross3(u[0], u[1], u[2]);
    bool orthonormal = true;
    for (int a = 0; a < 3; ++a)
        for (int b = a; b < 3; ++b)
            orthonormal = orthonormal && std::fabs(math::dot3(u[a], u[b]) - (a == b ? 1.0 : 0.0)) < 1e-12;
    if (!orthonormal)
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) u[a][b] = a == b ? 1.0 : 0.0;
    double size = 0;
    for (int a = 0; a < 3; ++a) {
        out.h[a] = 0;
        for (int k = 0; k < 3; ++k) out.h[a] += h[k] * std::fabs(math::dot3(u[a], col[k]));
        size += std::fabs(out.c[a]) + out.h[a] + std::fabs(m[9 + a]);
    }
    const double pad = 1e-9 * size;
    if (!(pad < INFINITY)) return OrientedBox();
    for (double& x : out.h) x += pad;
    return out;
}

// False only when the segment from p to q certainly misses the box (slabs, in double, widened by 1e-9 of
// the sizes involved).
inline bool segment_meets_box(const double* p, const double* q, const Box& b) {
    if (b.empty()) return false;
    double t0 = 0, t1 = 1;
    for (int k = 0; k < 3; ++k) {
        const double margin = 1e-9 * (std::fabs(p[k]) + std::fabs(q[k]) + std::fabs(b.lo[k]) + std::fabs(b.hi[k]));
        const double lo = b.lo[k] - margin, hi = b.hi[k] + margin, d = q[k] - p[k];
        if (!(std::fabs(d) > margin)) {  // along the slab (or not finite: kept)
            if (p[k] < lo || p[k] > hi) return false;
            continue;
        }
        double ta = (lo - p[k]) / d, tb = (hi - p[k]) / d;
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
        if (t0 > t1) return false;
    }
    return true;
}

// A pyramid from the light in world space that holds the segments of some points: four side planes
// through the light (inside: n . (x - light) >= 0) and a far plane across its axis at the farthest point.
struct WorldPyramid {
    double light[3], axis[3], dmax;
    // The sides' unit normals by coordinate and their absolute values, zero past the fourth (lanes that never
    // rule a box out): the four sides a vector of double lanes, or two.
    static constexpr uint32_t sides = 4 > simd::dwidth ? 4 : simd::dwidth;
    double nx[sides] = {}, ny[sides] = {}, nz[sides] = {}, ax[sides] = {}, ay[sides] = {}, az[sides] = {};
};

// False only when box b certainly lies outside the pyramid; `near` gets the distance along the axis from
// the light to the box's nearest side (an order for the instances met, never an answer).
inline bool pyramid_meets_box(const WorldPyramid& w, const Box& b, double& near) {
    if (b.empty()) return false;
    double c[3], h[3], scale = w.dmax;
    for (int k = 0; k < 3; ++k) {
        c[k] = 0.5 * (b.lo[k] + b.hi[k]) - w.light[k];
        h[k] = 0.5 * (b.hi[k] - b.lo[k]);
        scale += std::fabs(c[k]) + h[k];
    }
    const double eps = 1e-9 * scale;
    using simd::Doubles;
    const Doubles cx = simd::dsplat(c[0]), cy = simd::dsplat(c[1]), cz = simd::dsplat(c[2]), hx = simd::dsplat(h[0]),
                  hy = simd::dsplat(h[1]), hz = simd::dsplat(h[2]);
    for (uint32_t s = 0; s < 4; s += simd::dwidth) {
        const Doubles reach = simd::load(w.ax + s) * hx + simd::load(w.ay + s) * hy + simd::load(w.az + s) * hz;
        const Doubles side = simd::load(w.nx + s) * cx + simd::load(w.ny + s) * cy + simd::load(w.nz + s) * cz + reach;
        if (simd::bits(side < simd::dsplat(-eps))) return false;  // NaN: kept
    }
    const double* z = w.axis;
    near = math::dot3(z, c) - (std::fabs(z[0]) * h[0] + std::fabs(z[1]) * h[1] + std::fabs(z[2]) * h[2]);
    return !(near > w.dmax + eps);
}

// Instances a group of tiles' pyramid or prism met (LevelShadow::cull), for each tile's own to test in lanes
// across them: each world box's centre and half extents, as pyramid_meets_box and prism_meets_box make them
// (the lanes past `count` hold whatever they held: each visit leaves them out).
struct MetBoxes {
    LaneVector<double> cx, cy, cz, hx, hy, hz;  // sized in whole vectors
    LaneVector<uint32_t> handle;
    uint32_t count = 0;
    bool usable = false;  // whether the group's pyramid was made (a point-light tile reads `met` only then)
    void clear() { count = 0; }
    void add(const Box& b, uint32_t h) {
        if (count == handle.size()) {
            const size_t size = (handle.size() * 2 + 64 + simd::dwidth - 1) / simd::dwidth * simd::dwidth;
            for (LaneVector<double>* v : {&cx, &cy, &cz, &hx, &hy, &hz}) v->resize(size);
            handle.resize(size);
        }
        cx[count] = 0.5 * (b.lo[0] + b.hi[0]);
        cy[count] = 0.5 * (b.lo[1] + b.hi[1]);
        cz[count] = 0.5 * (b.lo[2] + b.hi[2]);
        hx[count] = 0.5 * (b.hi[0] - b.lo[0]);
        hy[count] = 0.5 * (b.hi[1] - b.lo[1]);
        hz[count] = 0.5 * (b.hi[2] - b.lo[2]);
        handle[count++] = h;
    }
    // f(handle, near) for the lanes of `keep` in the vector from box i, near[k] lane k's.
    template <class F>
    void each(uint32_t i, uint32_t keep, const double* near, F& f) const {
        if (count - i < simd::dwidth) keep &= (1u << (count - i)) - 1;
        for (; keep; keep &= keep - 1) {
            const uint32_t k = math::lowest_bit(keep);
            f(handle[i + k], near[k]);
        }
    }
};

// f(handle, near) for each box of `met` that may meet pyramid w: pyramid_meets_box's test, in lanes across
// the boxes.
template <class F>
inline void visit_met(const WorldPyramid& w, const MetBoxes& met, F f) {
    using simd::Doubles;
    const double* z = w.axis;
    const Doubles dmax = simd::dsplat(w.dmax), nano = simd::dsplat(1e-9), lx = simd::dsplat(w.light[0]),
                  ly = simd::dsplat(w.light[1]), lz = simd::dsplat(w.light[2]), zx = simd::dsplat(z[0]),
                  zy = simd::dsplat(z[1]), zz = simd::dsplat(z[2]), ax = simd::dsplat(std::fabs(z[0])),
                  ay = simd::dsplat(std::fabs(z[1])), az = simd::dsplat(std::fabs(z[2]));
    alignas(64) double near[simd::dwidth];
    for (uint32_t i = 0; i < met.count; i += simd::dwidth) {
        const Doubles cx = simd::load(met.cx.data() + i) - lx, cy = simd::load(met.cy.data() + i) - ly,
                      cz = simd::load(met.cz.data() + i) - lz, hx = simd::load(met.hx.data() + i),
                      hy = simd::load(met.hy.data() + i), hz = simd::load(met.hz.data() + i);
        const Doubles scale = dmax + (simd::abs(cx) + hx) + (simd::abs(cy) + hy) + (simd::abs(cz) + hz);
        const Doubles eps = nano * scale, below = simd::dsplat(0) - eps;
        uint32_t out = 0;
        for (uint32_t s = 0; s < 4; ++s) {
            const Doubles reach = simd::dsplat(w.ax[s]) * hx + simd::dsplat(w.ay[s]) * hy + simd::dsplat(w.az[s]) * hz;
            const Doubles side =
                simd::dsplat(w.nx[s]) * cx + simd::dsplat(w.ny[s]) * cy + simd::dsplat(w.nz[s]) * cz + reach;
            out |= simd::bits(side < below);  // NaN: kept
        }
        const Doubles n = (zx * cx + zy * cy + zz * cz) - (ax * hx + ay * hy + az * hz);
        out |= simd::bits(n > dmax + eps);
        const uint32_t keep = ((1u << simd::dwidth) - 1) & ~out;
        if (!keep) continue;
        simd::store(near, n);
        met.each(i, keep, near, f);
    }
}

// A prism along a sun's direction in world space that holds the rays of some points: the rectangle [lo, hi]
// across the direction (on the unit axes a, b) that bounds their projections, from `low` (the lowest point
// along the unit direction z) up; `top` is the level's highest reach along z (an order for the instances met).
struct WorldPrism {
    double a[3], b[3], z[3], lo[2], hi[2], low, top, margin;
};

// False only when box b certainly lies outside the prism; `near` gets how far below `top` the box's top lies
// (the sun's side first, never an answer).
inline bool prism_meets_box(const WorldPrism& w, const Box& b, double& near) {
    if (b.empty()) return false;
    double c[3], h[3], size = w.margin;
    for (int k = 0; k < 3; ++k) {
        c[k] = 0.5 * (b.lo[k] + b.hi[k]);
        h[k] = 0.5 * (b.hi[k] - b.lo[k]);
        size += 1e-9 * (std::fabs(c[k]) + h[k]);
    }
    auto reach = [&](const double* n) {
        return std::fabs(n[0]) * h[0] + std::fabs(n[1]) * h[1] + std::fabs(n[2]) * h[2];
    };
    const double ca = math::dot3(c, w.a), ra = reach(w.a) + size, cb = math::dot3(c, w.b), rb = reach(w.b) + size;
    const double up = math::dot3(c, w.z) + reach(w.z) + size;
    if (ca + ra < w.lo[0] || ca - ra > w.hi[0] || cb + rb < w.lo[1] || cb - rb > w.hi[1] || up < w.low) return false;
    near = w.top - up > 0 ? w.top - up : 0.0;  // NaN: 0
    return true;
}

// f(handle, near) for each box of `met` that may meet prism w: prism_meets_box's test, in lanes across the
// boxes.
template <class F>
inline void visit_met(const WorldPrism& w, const MetBoxes& met, F f) {
    using simd::Doubles;
    const Doubles nano = simd::dsplat(1e-9), margin = simd::dsplat(w.margin), zero = simd::dsplat(0);
    Doubles axis[3][3], reach[3][3];  // a, b, z and their absolute values, by coordinate
    const double* n[3] = {w.a, w.b, w.z};
    for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k) {
            axis[j][k] = simd::dsplat(n[j][k]);
            reach[j][k] = simd::dsplat(std::fabs(n[j][k]));
        }
    alignas(64) double near[simd::dwidth];
    for (uint32_t i = 0; i < met.count; i += simd::dwidth) {
        const Doubles c[3] = {simd::load(met.cx.data() + i), simd::load(met.cy.data() + i),
                              simd::load(met.cz.data() + i)},
                      h[3] = {simd::load(met.hx.data() + i), simd::load(met.hy.data() + i),
                              simd::load(met.hz.data() + i)};
        Doubles size = margin;
        for (int k = 0; k < 3; ++k) size = size + nano * (simd::abs(c[k]) + h[k]);
        Doubles along[3], ends[3];  // the centre on a, b, z and the box's reach on them
        for (int j = 0; j < 3; ++j) {
            along[j] = axis[j][0] * c[0] + axis[j][1] * c[1] + axis[j][2] * c[2];
            ends[j] = reach[j][0] * h[0] + reach[j][1] * h[1] + reach[j][2] * h[2] + size;
        }
        const Doubles up = along[2] + ends[2];
        const uint32_t out = simd::bits(along[0] + ends[0] < simd::dsplat(w.lo[0])) |
            simd::bits(simd::dsplat(w.hi[0]) < along[0] - ends[0]) |
            simd::bits(along[1] + ends[1] < simd::dsplat(w.lo[1])) |
            simd::bits(simd::dsplat(w.hi[1]) < along[1] - ends[1]) | simd::bits(up < simd::dsplat(w.low));
        const uint32_t keep = ((1u << simd::dwidth) - 1) & ~out;
        if (!keep) continue;
        const Doubles below = simd::dsplat(w.top) - up;
        simd::store(near, simd::select(below > zero, below, zero));  // NaN: 0
        met.each(i, keep, near, f);
    }
}

// False only when the ray p + t d (t >= 0) certainly misses the box (slabs, in double, widened by 1e-9 of the
// sizes involved); anything not finite is kept.
inline bool ray_meets_box(const double* p, const double* d, const Box& b) {
    if (b.empty()) return false;
    double t0 = 0, t1 = INFINITY;
    for (int k = 0; k < 3; ++k) {
        const double margin = 1e-9 * (std::fabs(p[k]) + std::fabs(b.lo[k]) + std::fabs(b.hi[k]));
        const double lo = b.lo[k] - margin, hi = b.hi[k] + margin;
        if (!(std::fabs(lo) < INFINITY && std::fabs(hi) < INFINITY && std::fabs(p[k]) < INFINITY)) return true;
        if (!(std::fabs(d[k]) > 0)) {  // along the slab
            if (p[k] < lo || p[k] > hi) return false;
            continue;
        }
        double ta = (lo - p[k]) / d[k], tb = (hi - p[k]) / d[k];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
        if (t0 > t1) return false;
    }
    return true;
}

}  // namespace level_detail

class Level {
public:
    static constexpr uint32_t none = 0xffffffffu;

    // Adds an opened asset; the view (and the bytes under it) must stay alive and unchanged while the level
    // is used. Makes what queries read of it that does not depend on the light: its meshes' boxes and, unless
    // `scan_bounds` is false (no query will use Traversal::scan), the scan's bounds (ScanBounds). Returns the
    // asset's index.
    uint32_t add_asset(const AssetView& view, bool scan_bounds = true) {
        Asset a;
        a.view = view;
        if (scan_bounds) a.bounds = make_scan_bounds(view);
        a.mesh_boxes.resize(view.mesh_count);
        a.slabs.resize(view.mesh_count);
        for (uint32_t m = 0; m < view.mesh_count; ++m) {
            const MeshRecord& mesh = view.meshes[m];
            level_detail::Box& b = a.mesh_boxes[m];
            for (uint32_t v = 0; v < mesh.vertex_count; ++v) {
                const float* p = view.position(mesh, v);
                for (int k = 0; k < 3; ++k) {
                    b.lo[k] = std::min(b.lo[k], double(p[k]));
                    b.hi[k] = std::max(b.hi[k], double(p[k]));
                }
            }
            a.slabs[m] = level_detail::flat_slab(b);
        }
        assets_.push_back(std::move(a));
        return uint32_t(assets_.size() - 1);
    }

    // An instance of mesh `mesh` of asset `asset`, placed by `transform` (affine, column-major 3x4 doubles:
    // the x, y, z axes, then the translation; mirrored and sheared transforms are fine). Returns its handle,
    // or none when the asset or mesh does not exist. The hierarchy includes it at the next commit().
    uint32_t add_instance(uint32_t asset, uint32_t mesh, const double* transform) {
        if (asset >= assets_.size() || mesh >= assets_[asset].view.mesh_count) return none;
        uint32_t h;
        if (!free_.empty()) {
            h = free_.back();
            free_.pop_back();
        } else {
            h = uint32_t(instances_.size());
            instances_.emplace_back();
            leaf_.push_back(none);
            position_.push_back(none);
        }
        Instance& i = instances_[h];
        i.asset = asset;
        i.mesh = mesh;
        i.alive = true;
        place(h, transform);
        ++live_;
        rebuild_ = true;
        return h;
    }

    // Every instance of asset `asset` as baked, each under `matrix` (world = matrix x baked transform; null:
    // as baked). handles[i] (when given) gets the handle of the asset's instance i. Returns how many were added.
    uint32_t add_baked(uint32_t asset, const double* matrix = nullptr, uint32_t* handles = nullptr) {
        if (asset >= assets_.size()) return 0;
        const AssetView& v = assets_[asset].view;
        for (uint32_t i = 0; i < v.instance_count; ++i) {
            double world[12];
            if (matrix)
                compose_instance(matrix, v.instances[i].transform, world);
            else
                std::copy(v.instances[i].transform, v.instances[i].transform + 12, world);
            const uint32_t h = add_instance(asset, v.instances[i].mesh, world);
            if (handles) handles[i] = h;
        }
        return v.instance_count;
    }

    // Places instance `handle` anew; the hierarchy is refitted along its path at the next commit(). False on
    // a handle that is not a live instance.
    bool move(uint32_t handle, const double* transform) {
        if (!alive(handle)) return false;
        place(handle, transform);
        moved_.push_back(handle);
        return true;
    }

    // Removes instance `handle` (its handle may be given to a later instance). False on a handle that is not a
    // live instance.
    bool remove(uint32_t handle) {
        if (!alive(handle)) return false;
        instances_[handle].alive = false;
        instances_[handle].box = level_detail::Box{};
        if (position_[handle] != none) item_boxes_[position_[handle]] = level_detail::Box{};
        free_.push_back(handle);
        --live_;
        if (leaf_[handle] != none) moved_.push_back(handle);  // an empty box: refitted out of its leaf
        return true;
    }

    // Brings the hierarchy up to date: rebuilt when instances were added, else refitted along the paths of the
    // instances moved or removed since the last commit (a move costs a refit of its leaf's ancestors, not a
    // rebuild). Queries and culling read the hierarchy as of the last commit.
    void commit() {
        if (rebuild_) {
            build();
        } else if (!moved_.empty()) {
            refit();
        }
        moved_.clear();
        rebuild_ = false;
    }

    bool alive(uint32_t handle) const { return handle < instances_.size() && instances_[handle].alive; }
    uint32_t asset_count() const { return uint32_t(assets_.size()); }
    const AssetView& asset(uint32_t a) const { return assets_[a].view; }
    uint32_t instance_count() const { return live_; }
    uint32_t handle_limit() const { return uint32_t(instances_.size()); }  // every handle is below it
    uint32_t asset_of(uint32_t handle) const { return instances_[handle].asset; }
    uint32_t mesh_of(uint32_t handle) const { return instances_[handle].mesh; }
    const double* transform_of(uint32_t handle) const { return instances_[handle].transform; }
    size_t node_count() const { return nodes_.size(); }
    // Bytes the level holds besides the assets' own (their scan bounds included).
    size_t memory_bytes() const {
        size_t bytes = instances_.capacity() * sizeof(Instance) + nodes_.capacity() * sizeof(Node) +
            (leaf_.capacity() + position_.capacity() + parent_.capacity() + items_.capacity() + free_.capacity() +
             moved_.capacity()) *
                sizeof(uint32_t) +
            item_boxes_.capacity() * sizeof(level_detail::Box);
        for (const Asset& a : assets_) {
            bytes += a.mesh_boxes.capacity() * sizeof(level_detail::Box);
            for (const ScanBounds& b : a.bounds) bytes += b.memory_bytes() + sizeof(ScanBounds);
        }
        return bytes;
    }

    // f(handle, near) for each live instance whose world box may meet pyramid `w` (as of the last commit),
    // near its box's distance along the pyramid's axis.
    template <class F>
    void visit_pyramid(const level_detail::WorldPyramid& w, F f) const {
        visit([&](const level_detail::Box& b, double& near) { return level_detail::pyramid_meets_box(w, b, near); }, f);
    }

    // f(handle, near) for each live instance whose world box may meet prism `w` (a sun's tile), near how far
    // below the prism's top its box's top lies.
    template <class F>
    void visit_prism(const level_detail::WorldPrism& w, F f) const {
        visit([&](const level_detail::Box& b, double& near) { return level_detail::prism_meets_box(w, b, near); }, f);
    }

    // f(handle) for each live instance with a box (as of the last commit).
    template <class F>
    void visit_all(F f) const {
        visit(
            [](const level_detail::Box& b, double& near) {
                near = 0;
                return !b.empty();
            },
            [&](uint32_t h, double) { f(h); });
    }

    // f(handle, 0) for each live instance whose world box may meet the ray p + t d, t >= 0.
    template <class F>
    void visit_ray(const double* p, const double* d, F f) const {
        visit(
            [&](const level_detail::Box& b, double& near) {
                near = 0;
                return level_detail::ray_meets_box(p, d, b);
            },
            f);
    }

    // The hierarchy's root box (the union of the live instances' world boxes as of the last commit; empty,
    // lo > hi, for an empty level).
    const double* world_lo() const { return nodes_.empty() ? empty_.lo : nodes_[0].box.lo; }
    const double* world_hi() const { return nodes_.empty() ? empty_.hi : nodes_[0].box.hi; }

    // f(handle, 0) for each live instance whose world box may meet the segment p-q.
    template <class F>
    void visit_segment(const double* p, const double* q, F f) const {
        visit(
            [&](const level_detail::Box& b, double& near) {
                near = 0;
                return level_detail::segment_meets_box(p, q, b);
            },
            f);
    }

    // f(handle) for each live instance whose world box may meet the frustum.
    template <class F>
    void visit_frustum(const Frustum& frustum, F f) const {
        visit(
            [&](const level_detail::Box& b, double& near) {
                near = 0;
                if (b.empty()) return false;
                for (int k = 0; k < frustum.count; ++k) {
                    const double* n = frustum.plane[k];
                    double far = n[3], scale = std::fabs(n[3]);
                    for (int j = 0; j < 3; ++j) {
                        far += n[j] * (n[j] >= 0 ? b.hi[j] : b.lo[j]);
                        scale += std::fabs(n[j]) * (std::fabs(b.lo[j]) + std::fabs(b.hi[j]));
                    }
                    if (far < -1e-9 * scale) return false;
                }
                return true;
            },
            [&](uint32_t h, double) { f(h); });
    }

    // The self-shadowing bias shadow queries take unless given one (ShadowBuildOptions::bias):
    // default_shadow_bias of the largest side of the level's world box (the hierarchy's root, the union of
    // the instances' world boxes) as of the last commit; 0 for an empty level.
    double shadow_bias() const {
        return nodes_.empty() || nodes_[0].box.empty()
            ? 0.0
            : default_shadow_bias(box_size(nodes_[0].box.lo, nodes_[0].box.hi));
    }

    // The sphere about instance `handle`'s oriented box: centre x, y, z and radius (INFINITY beyond double's
    // range), made when the instance is placed.
    const double* world_sphere(uint32_t handle) const { return instances_[handle].sphere; }
    // Instance `handle`'s world box, made when the instance is placed (empty: it blocks nothing).
    const level_detail::Box& world_box(uint32_t handle) const { return instances_[handle].box; }
    // And its box along its transform's axes (orient_box), tighter about a turned instance.
    const level_detail::OrientedBox& oriented_box(uint32_t handle) const { return instances_[handle].oriented; }

    // Where instance `handle` is, for a traversal's build.
    Placement placement(uint32_t handle) const { return {instances_[handle].mesh, instances_[handle].transform}; }
    // The slab that holds instance `handle`'s mesh when the mesh is flat along an axis of its frame (a ground, a
    // floor): axis < 0 otherwise.
    const level_detail::Slab& slab(uint32_t handle) const {
        return assets_[instances_[handle].asset].slabs[instances_[handle].mesh];
    }
    const ScanBounds* scan_bounds(uint32_t asset) const {
        return assets_[asset].bounds.empty() ? nullptr : assets_[asset].bounds.data();
    }

private:
    struct Asset {
        AssetView view;
        std::vector<ScanBounds> bounds;             // per mesh
        std::vector<level_detail::Box> mesh_boxes;  // per mesh, in its frame
        std::vector<level_detail::Slab> slabs;      // per mesh: its box's side along a flat mesh's thin axis
    };
    struct Instance {
        uint32_t asset = 0, mesh = 0;
        bool alive = false;
        double transform[12] = {};
        level_detail::Box box;  // in world space
        level_detail::OrientedBox oriented;
        double sphere[4] = {};  // about the oriented box: centre, radius
    };
    // A node of the hierarchy: an inner node's children are nodes first and first + 1; a leaf holds the
    // instances items_[first, first + count).
    struct Node {
        level_detail::Box box;
        uint32_t first = 0, count = 0;
    };
    static constexpr uint32_t leaf_size = 4;
    static constexpr int max_depth = 64;  // median splits: log2 of the instance count, far below this

    void place(uint32_t h, const double* transform) {
        Instance& i = instances_[h];
        std::copy(transform, transform + 12, i.transform);
        const level_detail::Box& local = assets_[i.asset].mesh_boxes[i.mesh];
        i.box = level_detail::transform_box(local, i.transform);
        i.oriented = level_detail::orient_box(local, i.transform);
        if (position_[h] != none) item_boxes_[position_[h]] = i.box;
        double r2 = 0;
        for (int k = 0; k < 3; ++k) {
            i.sphere[k] = i.oriented.c[k];
            r2 += i.oriented.h[k] * i.oriented.h[k];
        }
        const double radius = std::sqrt(r2) * (1 + 1e-12);
        i.sphere[3] = i.oriented.empty() ? 0.0 : radius < INFINITY ? radius : INFINITY;
    }

    // Top-down, median splits on the longest axis of the boxes' centres (ties by handle: deterministic).
    void build() {
        nodes_.clear();
        parent_.clear();
        items_.clear();
        item_boxes_.clear();
        std::fill(leaf_.begin(), leaf_.end(), none);
        std::fill(position_.begin(), position_.end(), none);
        for (uint32_t h = 0; h < instances_.size(); ++h)
            if (instances_[h].alive) items_.push_back(h);
        if (items_.empty()) return;
        auto centre = [&](uint32_t h, int k) {
            const level_detail::Box& b = instances_[h].box;
            return b.empty() ? 0.0 : 0.5 * (b.lo[k] + b.hi[k]);
        };
        nodes_.emplace_back();
        parent_.push_back(none);
        struct Range {
            uint32_t node, begin, end;
        };
        std::vector<Range> todo{{0, 0, uint32_t(items_.size())}};
        while (!todo.empty()) {
            const Range r = todo.back();
            todo.pop_back();
            if (r.end - r.begin <= leaf_size) {
                nodes_[r.node].first = r.begin;
                nodes_[r.node].count = r.end - r.begin;
                for (uint32_t i = r.begin; i < r.end; ++i) leaf_[items_[i]] = r.node;
                continue;
            }
            double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
            for (uint32_t i = r.begin; i < r.end; ++i)
                for (int k = 0; k < 3; ++k) {
                    lo[k] = std::min(lo[k], centre(items_[i], k));
                    hi[k] = std::max(hi[k], centre(items_[i], k));
                }
            int axis = 0;
            for (int k = 1; k < 3; ++k)
                if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
            const uint32_t mid = r.begin + (r.end - r.begin) / 2;
            std::nth_element(items_.begin() + r.begin, items_.begin() + mid, items_.begin() + r.end,
                             [&](uint32_t a, uint32_t b) {
                                 const double ca = centre(a, axis), cb = centre(b, axis);
                                 return ca < cb || (ca == cb && a < b);
                             });
            const uint32_t left = uint32_t(nodes_.size());
            nodes_[r.node].first = left;
            nodes_[r.node].count = 0;
            nodes_.emplace_back();
            nodes_.emplace_back();
            parent_.push_back(r.node);
            parent_.push_back(r.node);
            todo.push_back({left + 1, mid, r.end});
            todo.push_back({left, r.begin, mid});
        }
        for (uint32_t i = 0; i < items_.size(); ++i) {
            position_[items_[i]] = i;
            item_boxes_.push_back(instances_[items_[i]].box);
        }
        // Children follow their parents: boxes from the last node back.
        for (uint32_t n = uint32_t(nodes_.size()); n-- > 0;) fit(n);
    }

    void fit(uint32_t n) {
        Node& node = nodes_[n];
        node.box = level_detail::Box{};
        if (node.count) {
            for (uint32_t i = node.first; i < node.first + node.count; ++i) node.box.add(item_boxes_[i]);
        } else {
            node.box.add(nodes_[node.first].box);
            node.box.add(nodes_[node.first + 1].box);
        }
    }

    // Each moved instance's leaf and its ancestors refitted, in the order of the moves, up to the first node
    // whose box comes out the same: a node's last refit then follows every change below it, and no list of
    // the nodes touched needs sorting.
    void refit() {
        for (uint32_t h : moved_)
            for (uint32_t n = leaf_[h]; n != none; n = parent_[n]) {
                const level_detail::Box before = nodes_[n].box;
                fit(n);
                if (std::equal(before.lo, before.lo + 3, nodes_[n].box.lo) &&
                    std::equal(before.hi, before.hi + 3, nodes_[n].box.hi))
                    break;
            }
    }

    // f(handle, near) for each live instance of a leaf whose box, and whose ancestors' boxes, `meets` keeps.
    template <class Meets, class F>
    void visit(Meets meets, F f) const {
        if (nodes_.empty()) return;
        uint32_t stack[max_depth + 1];
        int top = 0;
        double near;
        if (!meets(nodes_[0].box, near)) return;
        stack[top++] = 0;
        while (top) {
            const Node& node = nodes_[stack[--top]];
            if (node.count) {
                for (uint32_t i = node.first; i < node.first + node.count; ++i)
                    if (meets(item_boxes_[i], near)) f(items_[i], near);  // a removed instance's box is empty
                continue;
            }
            for (uint32_t c = node.first; c < node.first + 2; ++c)
                if (top < max_depth && meets(nodes_[c].box, near)) stack[top++] = c;
        }
    }

    std::vector<Asset> assets_;
    std::vector<Instance> instances_;
    level_detail::LaneVector<uint32_t> leaf_;      // per handle, its leaf node (none before the first commit)
    level_detail::LaneVector<uint32_t> position_;  // per handle, its place in items_ (none before the first commit)
    level_detail::LaneVector<uint32_t> free_, moved_;
    std::vector<Node> nodes_;
    level_detail::LaneVector<uint32_t> parent_, items_;
    // The instances' world boxes in the order of items_: the walks and the refits read a leaf's boxes together.
    std::vector<level_detail::Box> item_boxes_;
    uint32_t live_ = 0;
    bool rebuild_ = false;
    level_detail::Box empty_;
};

// One light's shadows over a committed Level. Each frame (or light):
//   begin(level, light, points, n, options)  order the points by direction from the light into tiles
//   cull(first, last)                         the instances each of tiles [first, last) meets (ranges may run
//                                             on different threads)
//   gather()                                  the instances met, once each
//   build(first, last)                        set those [first, last) up for the light (ranges, threads)
//   occluded(first, last, out, scratch)       tiles [first, last): out[i] = 1 when point i is in shadow
//                                             (const, ranges, threads; scratch_size() words each)
// occluded_batch() runs them all on the calling thread. The level and the points must stay unchanged from
// begin() to the last answer. The answers are those of each instance's InstanceShadow for every point. A sun
// (a light at infinity, given by its direction) takes begin_sun() in place of begin(), or
// occluded_sun_batch(), and the same steps after.
class LevelShadow {
public:
    void begin(const Level& level, const double* light, const double* points, size_t n,
               const ShadowBuildOptions& options = {}) {
        start(level, light, points, n, options, false);
        batch_order(light, points, n, order_.data(), order_scratch_.data());
    }

    // The same steps for a sun, given by `toward`, its world direction from the scene toward it (cb_segment.h,
    // "A sun"): the tiles are prisms along it, and each instance is set up with InstanceShadow::build_sun.
    void begin_sun(const Level& level, const double* toward, const double* points, size_t n,
                   const ShadowBuildOptions& options = {}) {
        start(level, toward, points, n, options, true);
        sun_batch_order(toward, points, n, order_.data(), order_scratch_.data());
        sun_usable_ = finite3(toward) && direction_frame(toward, sun_frame_);
    }

    size_t tile_count() const { return tile_count_; }

    // The instances tiles [first, last) meet, each tile's nearest first: every instance when the level is not
    // culled (list_unculled). Otherwise tiles go in groups of group_tiles, the same groups whatever the range:
    // the group's pyramid (a sun's: prism) walks the level's hierarchy once, and each tile's own tests the
    // instances that walk met, in lanes (cull_point_tile, cull_sun_tile). Neighbouring tiles look the same way
    // from the light and meet mostly the same instances, and a tile's own walk tests several of the
    // hierarchy's boxes for each instance it meets. For a point light, the first group of every probe_tiles
    // decides whether the groups after it pay (pays); where not, their tiles walk the hierarchy themselves.
    void cull(size_t first, size_t last) {
        if (!unculled_.empty()) {
            for (size_t t = first; t < last; ++t) tile_lists_[t].assign(unculled_.begin(), unculled_.end());
            return;
        }
        level_detail::MetBoxes met;
        if (sun_) {
            SunTileCull tiles[group_tiles];
            for (size_t g = first / group_tiles * group_tiles; g < last; g += group_tiles) {
                const size_t end = std::min<size_t>(g + group_tiles, tile_count_);
                for (size_t t = g; t < end; ++t) {
                    if (t + 1 < end) prefetch_points(t + 1);
                    sun_tile_prism(t, tiles[t - g]);
                }
                cull_sun_group(tiles, uint32_t(end - g), met);
                for (size_t t = std::max(g, first); t < std::min(end, last); ++t) cull_sun_tile(t, tiles[t - g], met);
            }
            return;
        }
        TileOffsets tiles[group_tiles];
        bool grouped = true;
        const size_t first_group = first / group_tiles * group_tiles;
        for (size_t g = first_group; g < last; g += group_tiles) {
            const size_t end = std::min<size_t>(g + group_tiles, tile_count_);
            const size_t probe = g / probe_tiles * probe_tiles;
            if (g == probe) {
                grouped = probe_pays(probe, first, last, tiles, met);
                continue;
            }
            if (g == first_group) grouped = probe_pays(probe, first, last, tiles, met);  // its probe lies before
            offsets_of(g, end, tiles);
            if (grouped)
                cull_group(tiles, uint32_t(end - g), met);
            else
                met.usable = false;
            for (size_t t = std::max(g, first); t < std::min(end, last); ++t) cull_point_tile(t, tiles[t - g], met);
        }
    }

    // The instances met by any tile, once each, in the order of their first meeting; returns how many.
    size_t gather() {
        const uint32_t limit = level_->handle_limit();
        if (slot_of_.size() < limit) {
            slot_of_.resize(limit, none);
            stamp_.resize(limit, 0);
        }
        if (++generation_ == 0) {
            std::fill(stamp_.begin(), stamp_.end(), 0u);
            generation_ = 1;
        }
        needed_.clear();
        for (size_t t = 0; t < tile_count_; ++t)
            for (uint64_t& entry : tile_lists_[t]) {
                const uint32_t h = uint32_t(entry);
                if (stamp_[h] != generation_) {
                    stamp_[h] = generation_;
                    slot_of_[h] = uint32_t(needed_.size());
                    needed_.push_back(h);
                }
                entry = slot_of_[h];
            }
        if (shadows_.size() < needed_.size()) shadows_.resize(needed_.size());
        if (spheres_.size() < needed_.size()) spheres_.resize(needed_.size());
        built_count_ = needed_.size();
        return built_count_;
    }

    size_t build_count() const { return built_count_; }

    // Sets up the gathered instances [first, last) for the light. `scratch` (may be null) lets a thread's
    // successive tree builds reuse memory.
    void build(size_t first, size_t last, BuildScratch* scratch = nullptr) {
        ShadowBuildOptions o = options_;
        o.scratch = scratch;
        for (size_t i = first; i < last; ++i) {
            const uint32_t h = needed_[i];
            spheres_[i] = light_sphere(h);
            o.bounds = level_->scan_bounds(level_->asset_of(h));
            if (sun_)
                shadows_[i].build_sun(level_->asset(level_->asset_of(h)), level_->placement(h), light_, o);
            else
                shadows_[i].build(level_->asset(level_->asset_of(h)), level_->placement(h), light_, o);
        }
    }

    // Words of scratch occluded() needs: the deepest built structure's stack, a TileCache and the deferred
    // entries (Deferred).
    size_t scratch_size() const {
        const size_t deferred = sizeof(Deferred) + alignof(Deferred);
        return ordered_scratch_size(shadows_.data(), built_count_) +
            (deferred + sizeof(uint32_t) - 1) / sizeof(uint32_t);
    }

    // Tiles [first, last): out[i] = 1 when point i is in shadow, 0 otherwise. Each tile's points enter the
    // instances it lists, nearest first, until one shadows them, and only those their segment may meet. An
    // instance entered by few of a tile's points (at most Deferred::sparse) is put off, the points going on
    // down the list: once the chunk's tiles are done, each such instance answers the points of all its
    // entries still lit at once, in tiles of up to 64 of them. An instance's set-up per tile (frame, pyramid,
    // coarse scan) is most of the cost of a few points, and on a large level a tile meets tens of instances,
    // most entered by a few of its points.
    void occluded(size_t first, size_t last, uint8_t* out, uint32_t* scratch, QueryStats* stats = nullptr) const {
        uint32_t* stack = scratch;
        const uintptr_t at =
            reinterpret_cast<uintptr_t>(stack + detail::batch_stack_size(shadows_.data(), built_count_));
        const uintptr_t cache_at = (at + alignof(TileCache) - 1) / alignof(TileCache) * alignof(TileCache);
        TileCache* cache = new (reinterpret_cast<void*>(cache_at)) TileCache;
        cache->clear();
        const uintptr_t deferred_at =
            (cache_at + sizeof(TileCache) + alignof(Deferred) - 1) / alignof(Deferred) * alignof(Deferred);
        Deferred& d = *new (reinterpret_cast<void*>(deferred_at)) Deferred;
        alignas(64) float whole[tile_capacity];  // box_lanes over the whole segment
        std::fill(whole, whole + tile_capacity, 1.0f);
        Walk w{d, stack, stats, cache, whole, 0};
        for (size_t c = first; c < last; c += Deferred::chunk) {
            const size_t chunk_end = std::min(last, c + Deferred::chunk);
            w.first_tile = c;
            d.count = 0;
            for (size_t t = c; t < chunk_end; ++t) {
                d.shadowed[t - c] = 0;
                if (t + 1 < last) prefetch_points(t + 1);
                walk(w, uint32_t(t - c));
            }
            answer_deferred(w);
            for (size_t t = c; t < chunk_end; ++t) {
                const uint32_t* index = order_.data() + t * tile_capacity;
                for (uint32_t i = 0, count = tile_count_at(t); i < count; ++i)
                    out[index[i]] = uint8_t(d.shadowed[t - c] >> i & 1);
            }
        }
    }

    // All steps on the calling thread (allocates its scratch).
    void occluded_batch(const Level& level, const double* light, const double* points, size_t n, uint8_t* out,
                        const ShadowBuildOptions& options = {}, QueryStats* stats = nullptr) {
        begin(level, light, points, n, options);
        cull(0, tile_count());
        build(0, gather());
        level_detail::LaneVector<uint32_t> scratch(scratch_size());
        occluded(0, tile_count(), out, scratch.data(), stats);
    }

    // The same for a sun in world direction `toward` (from the scene toward it).
    void occluded_sun_batch(const Level& level, const double* toward, const double* points, size_t n, uint8_t* out,
                            const ShadowBuildOptions& options = {}, QueryStats* stats = nullptr) {
        begin_sun(level, toward, points, n, options);
        cull(0, tile_count());
        build(0, gather());
        level_detail::LaneVector<uint32_t> scratch(scratch_size());
        occluded(0, tile_count(), out, scratch.data(), stats);
    }

    // The structure built for gathered instance i, and its handle in the level.
    const InstanceShadow& built(size_t i) const { return shadows_[i]; }
    uint32_t built_handle(size_t i) const { return needed_[i]; }
    // Instances met per tile, summed over the tiles (what the culling let through).
    size_t instances_met() const {
        size_t met = 0;
        for (size_t t = 0; t < tile_count_; ++t) met += tile_lists_[t].size();
        return met;
    }
    // Bytes held (the level's not counted).
    size_t memory_bytes() const {
        size_t bytes = (order_.capacity() + order_scratch_.capacity() + slot_of_.capacity() + stamp_.capacity() +
                        needed_.capacity()) *
                sizeof(uint32_t) +
            unculled_.capacity() * sizeof(uint64_t);
        for (const level_detail::LaneVector<uint64_t>& l : tile_lists_)
            bytes += l.capacity() * sizeof(uint64_t) + sizeof(l);
        for (size_t i = 0; i < shadows_.size(); ++i)
            bytes += sizeof(InstanceShadow) + (i < built_count_ ? shadows_[i].memory_bytes() : 0);
        bytes += spheres_.capacity() * sizeof(LightSphere);
        return bytes;
    }

private:
    static constexpr uint32_t none = 0xffffffffu;

    // Entries put off in a chunk of tiles (occluded): entry i, the instance of slot key[i] >> 32 entered by
    // points in[i] of the chunk's tile tile[i] (key's low word: i, so that a sort by key keeps each instance's
    // entries in tile order); and each tile's points found in shadow.
    struct Deferred {
        static constexpr uint32_t chunk = 256;      // tiles
        static constexpr uint32_t sparse = 32;      // an instance entered by at most this many points is put off
        static constexpr uint32_t capacity = 4096;  // entries held (when full, they are answered)
        uint32_t count = 0;
        uint64_t key[capacity], in[capacity];
        uint32_t tile[capacity];
        uint64_t shadowed[chunk];
    };
    struct Walk {
        Deferred& d;
        uint32_t* stack;
        QueryStats* stats;
        TileCache* cache;
        const float* whole;  // 1 in every lane: box_lanes over the whole segment
        size_t first_tile;   // the chunk's
    };

    // Asks for tile t's points, which lie anywhere in the caller's array, while the tile before it is worked.
    void prefetch_points(size_t t) const {
        const uint32_t* index = order_.data() + t * tile_capacity;
        for (uint32_t i = 0, count = tile_count_at(t); i < count; ++i) {
            const double* p = points_ + size_t(index[i]) * 3;
            simd::prefetch(p);
            simd::prefetch(p + 2);  // a point may straddle two cache lines
        }
    }

    uint32_t tile_count_at(size_t t) const { return uint32_t(std::min<size_t>(tile_capacity, n_ - t * tile_capacity)); }

    // The points of the chunk's tile `tile` down its list: each instance entered by many of them answers them
    // now, one entered by few is put off to answer_deferred.
    void walk(Walk& w, uint32_t tile) const {
        const size_t t = w.first_tile + tile;
        const level_detail::LaneVector<uint64_t>& list = tile_lists_[t];
        alignas(64) float ex[tile_capacity], ey[tile_capacity], ez[tile_capacity], fd[tile_capacity];
        alignas(64) double world[3][tile_capacity], dist[tile_capacity];
        double across[tile_capacity][3];
        SunTile sun_tile;
        const uint32_t count = tile_count_at(t);
        const uint32_t* index = order_.data() + t * tile_capacity;
        uint64_t alive = tile_lanes(count);
        // A point light's only instance takes every point: its traversal's first test (the coarse spheres) is
        // this one, finer, and the points asked of a lone mesh lie on it.
        const bool lone = !sun_ && level_->instance_count() == 1;
        const uint64_t regular = sun_ ? sun_across(index, count, across, world)
            : lone                    ? 0
                                      : directions(index, count, ex, ey, ez, fd, world, dist);
        if (sun_) sun_tile.make(across, regular);
        Deferred& d = w.d;
        for (uint64_t slot : list) {
            if (!alive) break;
            // Only the points whose segment may meet the instance's sphere and box enter it.
            uint64_t in = alive &
                (sun_       ? sun_instance_points(spheres_[slot], regular, count, across, sun_tile)
                     : lone ? ~uint64_t(0)
                            : instance_points(spheres_[slot], regular, ex, ey, ez, fd, w.whole));
            if (in && spheres_[slot].flat.usable) in &= ~clear_of_slab(spheres_[slot].flat, in, world, dist, sun_);
            if (!in) continue;
            if (math::bit_count(uint32_t(in)) + math::bit_count(uint32_t(in >> 32)) <= Deferred::sparse) {
                if (d.count == Deferred::capacity) {  // full: those put off so far are answered first
                    answer_deferred(w);
                    alive &= ~d.shadowed[tile];
                    if (!(in & alive)) continue;
                }
                d.key[d.count] = slot << 32 | d.count;
                d.tile[d.count] = tile;
                d.in[d.count++] = in & alive;
                continue;
            }
            const uint64_t s = shadows_[slot].occluded_tile(points_, index, count, in, w.stack, w.stats, w.cache);
            d.shadowed[tile] |= s;
            alive &= ~s;
        }
    }

    // Answers the entries put off, instance by instance: the points of its entries still lit gathered into
    // tiles of up to 64.
    void answer_deferred(Walk& w) const {
        Deferred& d = w.d;
        const uint32_t waiting = d.count;
        // A comparator of this namespace's own, as cull_point_tile's (std::sort of plain integers would be one
        // instance shared with code built for other lanes).
        std::sort(d.key, d.key + waiting, [](uint64_t a, uint64_t b) { return a < b; });
        uint32_t packed[tile_capacity];
        uint16_t lane_entry[tile_capacity];
        uint8_t lane_point[tile_capacity];
        for (uint32_t e = 0; e < waiting;) {
            const uint32_t slot = uint32_t(d.key[e] >> 32);
            uint32_t n = 0;
            auto answer = [&] {
                const uint64_t s =
                    shadows_[slot].occluded_tile(points_, packed, n, tile_lanes(n), w.stack, w.stats, w.cache);
                for (uint64_t bits = s; bits; bits &= bits - 1) {
                    const uint32_t i = math::lowest_bit(bits), entry = lane_entry[i];
                    const uint64_t bit = uint64_t(1) << lane_point[i];
                    d.shadowed[d.tile[entry]] |= bit;
                }
                n = 0;
            };
            for (; e < waiting && uint32_t(d.key[e] >> 32) == slot; ++e) {
                const uint32_t i = uint32_t(d.key[e]);
                const uint32_t* index = order_.data() + (w.first_tile + d.tile[i]) * tile_capacity;
                for (uint64_t bits = d.in[i] & ~d.shadowed[d.tile[i]]; bits; bits &= bits - 1) {
                    const uint32_t p = math::lowest_bit(bits);
                    packed[n] = index[p];
                    lane_entry[n] = uint16_t(i);
                    lane_point[n] = uint8_t(p);
                    if (++n == tile_capacity) answer();
                }
            }
            if (n) answer();
        }
        d.count = 0;
    }

    // A flat instance's slab (Level::slab) for a light off it, for clear_of_slab: the slab's coordinate in the
    // mesh's frame is row . (x, y, z, 1) of a world point; `sign` turns it so that the light lies above the
    // slab's near side `edge`. A point light at `light_side`, `light_terms` bounding that side's rounding; a
    // sun's ray rises by `light_side` from where its contacts start to count (sun_from times the direction's
    // coordinate), `light_terms` bounding that rise's rounding.
    struct FlatTest {
        bool usable = false;
        double row[4] = {0, 0, 0, 0}, sign = 1, edge = 0, light_side = 0, light_terms = 0, bias = 0;
    };

    // An instance's bounding sphere as the tiles test it for this light (instance_points, sun_instance_points):
    // `whole` when every point must enter the instance, the tests' range exceeded.
    struct LightSphere {
        double c[3], r, size;  // suns: the centre in the sun's frame, the radius, and |centre|_1 + r
        float f[4];            // points: the centre from the light and the grown radius, in float
        bool whole;
        // Points: the world box from the light (box_lanes), far tighter than the sphere about a tall or flat
        // instance; not usable for a sun, a level of one instance, or where float could overflow.
        BoxFilter box;
        FlatTest flat;
    };

    // The points of `in` whose segment, from where contacts start to count (shadow_from, the level's bias) to
    // the light, stays strictly above the slab, in exact arithmetic on the coordinates the instance's
    // traversal would compute (apply_instance): they meet none of its triangles. A point on a ground under the
    // light rises off it from its own point on, by shadow_from's fraction of the light's height; the test
    // asks bias (h_light - h_point) > (edge - h_point) |light - point| in double, without a division, each side
    // moved by 1e-13 of the terms it is made of, far beyond the rounding of the coordinates, of the distance
    // and of the products. For a sun (`dist` unused), the ray from sun_from on: it rises along the slab's axis
    // by f.light_side from the point to where its contacts start, and on from there, within the same margins.
    static uint64_t clear_of_slab(const FlatTest& f, uint64_t in, const double (*world)[tile_capacity],
                                  const double* dist, bool sun) {
        using simd::Doubles;
        const Doubles r0 = simd::dsplat(f.row[0]), r1 = simd::dsplat(f.row[1]), r2 = simd::dsplat(f.row[2]),
                      r3 = simd::dsplat(f.row[3]), sign = simd::dsplat(f.sign), edge = simd::dsplat(f.edge),
                      light = simd::dsplat(f.light_side), bias = simd::dsplat(f.bias),
                      fixed = simd::dsplat(std::fabs(f.row[3]) + f.light_terms + std::fabs(f.edge) +
                                           (sun ? f.light_side : 0.0)),
                      margin = simd::dsplat(1e-13), grow = simd::dsplat(1 + 1e-13);
        uint64_t clear = 0;
        for (uint32_t i = 0; i < tile_capacity; i += simd::dwidth) {
            if (!simd::double_group(in, i)) continue;
            const Doubles x = simd::load(world[0] + i), y = simd::load(world[1] + i), z = simd::load(world[2] + i);
            const Doubles tx = r0 * x, ty = r1 * y, tz = r2 * z;
            const Doubles h = sign * (tx + ty + tz + r3);  // apply_instance's order
            const Doubles e = margin * (simd::abs(tx) + simd::abs(ty) + simd::abs(tz) + fixed);
            const simd::DoubleMask rises =
                sun ? h - e > edge - light : bias * (light - h - e) > (edge - h + e) * simd::load(dist + i) * grow;
            clear |= uint64_t(simd::bits(rises)) << i;
        }
        return clear & in;
    }

    void start(const Level& level, const double* light, const double* points, size_t n,
               const ShadowBuildOptions& options, bool sun) {
        level_ = &level;
        points_ = points;
        n_ = n;
        sun_ = sun;
        options_ = options;
        options_.bounds = nullptr;
        if (!(options_.bias > 0)) options_.bias = level.shadow_bias();
        for (int k = 0; k < 3; ++k) light_[k] = light[k];
        order_.resize(n);
        order_scratch_.resize(batch_order_scratch_size(n));
        const size_t tiles = (n + tile_capacity - 1) / tile_capacity;
        if (tile_lists_.size() < tiles) tile_lists_.resize(tiles);
        tile_count_ = tiles;
        built_count_ = 0;
        list_unculled();
    }

    // A tile's list entry: the float bits of `near` (not below 0, so that entries order as integers; NaN: 0)
    // above the handle.
    static uint64_t entry(double near, uint32_t h) {
        const float key = near > 0 ? float(near) : 0.0f;
        uint32_t bits;
        std::memcpy(&bits, &key, 4);
        return uint64_t(bits) << 32 | h;
    }

    // A level of one instance, or for a point light of at most `few` instances, is not culled per tile: every
    // tile lists them all (unculled_), nearest the light first, and a point enters one only when its segment may
    // meet the instance's bounding sphere and world box (instance_points, float lanes). Making the tile's
    // pyramid and walking the hierarchy cost more than the tiles it could leave out save: listing was as fast
    // or faster up to 21 instances, even at 31, and culling faster from 41 on (docs/PERFORMANCE.md). Instances
    // without a box block nothing and are left out.
    static constexpr uint32_t few = 24;
    void list_unculled() {
        unculled_.clear();
        const uint32_t count = level_->instance_count();
        if (count != 1 && (sun_ || count > few)) return;
        level_->visit_all([&](uint32_t h) {
            const level_detail::Box& b = level_->world_box(h);
            double d2 = 0;  // the light's distance to the box, squared
            for (int k = 0; k < 3; ++k) {
                const double d = std::max({b.lo[k] - light_[k], 0.0, light_[k] - b.hi[k]});
                d2 += d * d;
            }
            unculled_.push_back(entry(sun_ ? 0.0 : std::sqrt(d2), h));
        });
        std::sort(unculled_.begin(), unculled_.end(), [](uint64_t x, uint64_t y) { return x < y; });
    }

    // A sun's tile: each point's coordinates in the sun's frame (across: a, b; along: z, up toward the sun),
    // and the points themselves into `world` (by coordinate) when given; returns the points whose coordinates
    // are finite and within 1e30 (the others meet every instance).
    uint64_t sun_across(const uint32_t* index, uint32_t count, double (*across)[3],
                        double (*world)[tile_capacity] = nullptr) const {
        uint64_t regular = 0;
        for (uint32_t i = 0; i < count; ++i) {
            const double* p = points_ + size_t(index[i]) * 3;
            if (world)
                for (int k = 0; k < 3; ++k) world[k][i] = p[k];
            across[i][0] = math::dot3(p, sun_frame_[1]);
            across[i][1] = math::dot3(p, sun_frame_[2]);
            across[i][2] = math::dot3(p, sun_frame_[0]);
            if (std::fabs(across[i][0]) + std::fabs(across[i][1]) + std::fabs(across[i][2]) < 1e30)
                regular |= uint64_t(1) << i;
        }
        return regular;
    }

    // A sun's tile in float for sun_instance_points: its regular points' coordinates in the sun's frame (from
    // sun_across) taken from the middle of their range, and the largest such coordinate's |.|_1.
    struct SunTile {
        double centre[3], size;
        alignas(64) float u[tile_capacity], v[tile_capacity], w[tile_capacity];
        void make(const double (*across)[3], uint64_t regular) {
            double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
            for (uint64_t b = regular; b; b &= b - 1)
                for (int k = 0; k < 3; ++k) {
                    lo[k] = std::min(lo[k], across[math::lowest_bit(b)][k]);
                    hi[k] = std::max(hi[k], across[math::lowest_bit(b)][k]);
                }
            for (int k = 0; k < 3; ++k) centre[k] = regular ? 0.5 * (lo[k] + hi[k]) : 0.0;
            size = 0;
            for (uint32_t i = 0; i < tile_capacity; ++i) {
                const bool in = regular >> i & 1;
                const double q[3] = {in ? across[i][0] - centre[0] : 0.0, in ? across[i][1] - centre[1] : 0.0,
                                     in ? across[i][2] - centre[2] : 0.0};
                u[i] = float(q[0]);
                v[i] = float(q[1]);
                w[i] = float(q[2]);
                size = std::max(size, std::fabs(q[0]) + std::fabs(q[1]) + std::fabs(q[2]));
            }
        }
    };

    // The tile's points whose ray toward the sun may meet an instance's sphere, and every point that is not
    // regular. In float over the lanes from the tile's centre (f, sun_sphere_points), the radius grown by 1e-6
    // of the sizes involved and by 1e-12 of the coordinates from the frame's origin (the double differences'
    // rounding); in double, the radius grown by 1e-9 of the sizes, where float could overflow or fall to
    // subnormals.
    uint64_t sun_instance_points(const LightSphere& sphere, uint64_t regular, uint32_t count, const double (*across)[3],
                                 const SunTile& f) const {
        if (sphere.whole) return ~uint64_t(0);
        const double *c = sphere.c, r = sphere.r, size = sphere.size;
        const uint64_t all = tile_lanes(count);
        const double d[3] = {c[0] - f.centre[0], c[1] - f.centre[1], c[2] - f.centre[2]};
        const double reach = std::fabs(d[0]) + std::fabs(d[1]) + std::fabs(d[2]) + r + f.size;
        const double slack = 1e-6 * reach + 1e-12 * (size + math::l1(f.centre));
        if (reach < 1e18 && slack > 1e-15)
            return sun_sphere_points(d[0], d[1], d[2], r, slack, regular, f.u, f.v, f.w) | (all & ~regular);
        uint64_t in = 0;
        for (uint64_t b = regular; b; b &= b - 1) {
            const uint32_t i = math::lowest_bit(b);
            const double* q = across[i];
            const double grown = r + 1e-9 * (size + std::fabs(q[0]) + std::fabs(q[1]) + std::fabs(q[2]));
            const double du = c[0] - q[0], dv = c[1] - q[1];
            if (du * du + dv * dv <= grown * grown && q[2] <= c[2] + grown) in |= uint64_t(1) << i;
        }
        return in | (all & ~regular);
    }

    // A sun's tile for culling: its points' coordinates in the sun's frame (sun_across), the regular ones, and
    // the prism that holds their rays.
    struct SunTileCull {
        double across[tile_capacity][3];
        uint64_t regular = 0;
        level_detail::WorldPrism w;
    };

    void sun_tile_prism(size_t t, SunTileCull& o) const {
        level_detail::WorldPrism& w = o.w;
        o.regular = sun_usable_ ? sun_across(order_.data() + t * tile_capacity, tile_count_at(t), o.across) : 0;
        for (int k = 0; k < 3; ++k) {
            w.a[k] = sun_frame_[1][k];
            w.b[k] = sun_frame_[2][k];
            w.z[k] = sun_frame_[0][k];
        }
        w.lo[0] = w.lo[1] = w.low = INFINITY;
        w.hi[0] = w.hi[1] = -INFINITY;
        double size = 0;
        for (uint64_t b = o.regular; b; b &= b - 1) {
            const double* q = o.across[math::lowest_bit(b)];
            w.lo[0] = std::min(w.lo[0], q[0]);
            w.hi[0] = std::max(w.hi[0], q[0]);
            w.lo[1] = std::min(w.lo[1], q[1]);
            w.hi[1] = std::max(w.hi[1], q[1]);
            w.low = std::min(w.low, q[2]);
            size = std::max(size, std::fabs(q[0]) + std::fabs(q[1]) + std::fabs(q[2]));
        }
        w.margin = 1e-9 * size;
        const double *lo = level_->world_lo(), *hi = level_->world_hi();
        double centre[3], reach = 0;
        for (int k = 0; k < 3; ++k) {
            centre[k] = 0.5 * (lo[k] + hi[k]);
            reach += std::fabs(w.z[k]) * 0.5 * (hi[k] - lo[k]);
        }
        w.top = math::dot3(centre, w.z) + reach;
    }

    // The prism holding the rays of a group of `n` sun tiles (all in the sun's frame: each tile's prism lies
    // in it), and into `met` the instances it may meet.
    void cull_sun_group(const SunTileCull* tiles, uint32_t n, level_detail::MetBoxes& met) const {
        met.clear();
        met.usable = false;
        level_detail::WorldPrism w = tiles[0].w;
        uint64_t regular = 0;
        for (uint32_t i = 0; i < n; ++i) {
            const level_detail::WorldPrism& t = tiles[i].w;
            w.lo[0] = std::min(w.lo[0], t.lo[0]);
            w.hi[0] = std::max(w.hi[0], t.hi[0]);
            w.lo[1] = std::min(w.lo[1], t.lo[1]);
            w.hi[1] = std::max(w.hi[1], t.hi[1]);
            w.low = std::min(w.low, t.low);
            w.margin = std::max(w.margin, t.margin);
            regular |= tiles[i].regular;
        }
        if (!regular) return;
        level_->visit_prism(w, [&](uint32_t h, double) { met.add(level_->world_box(h), h); });
        met.usable = true;
    }

    // The instances a sun's tile t meets, the sun's side first: those whose box meets the prism of its regular
    // points (from those its group met), and for the other finite points those whose box their ray may meet.
    void cull_sun_tile(size_t t, const SunTileCull& o, const level_detail::MetBoxes& met) {
        level_detail::LaneVector<uint64_t>& list = tile_lists_[t];
        list.clear();
        if (!sun_usable_) return;
        const uint32_t count = tile_count_at(t);
        const uint32_t* index = order_.data() + t * tile_capacity;
        auto add = [&](uint32_t h, double near) { list.push_back(entry(near, h)); };
        if (o.regular) level_detail::visit_met(o.w, met, add);
        uint64_t alone = 0;
        for (uint32_t i = 0; i < count; ++i)
            if (!(o.regular >> i & 1) && finite3(points_ + size_t(index[i]) * 3)) alone |= uint64_t(1) << i;
        for (uint64_t b = alone; b; b &= b - 1) {
            const double* p = points_ + size_t(index[math::lowest_bit(b)]) * 3;
            level_->visit_ray(p, light_, [&](uint32_t h, double) { list.push_back(entry(0, h)); });
        }
        if (alone) once_each(list);
        std::sort(list.begin(), list.end(), [](uint64_t x, uint64_t y) { return x < y; });
    }

    // Keeps each handle's first entry in the order of the entries (its nearest, once sorted).
    static void once_each(level_detail::LaneVector<uint64_t>& list) {
        auto handle = [](uint64_t x) { return uint32_t(x); };
        std::sort(list.begin(), list.end(),
                  [&](uint64_t x, uint64_t y) { return handle(x) < handle(y) || (handle(x) == handle(y) && x < y); });
        list.erase(
            std::unique(list.begin(), list.end(), [&](uint64_t x, uint64_t y) { return handle(x) == handle(y); }),
            list.end());
    }

    // The tile's points from the light in float (lanes past `count` and irregular points: distance -1, in no
    // sphere), and in double the points themselves (`world`, by coordinate) and their distances (`dist`);
    // returns the regular ones, whose distance lies between the float filters' bounds (float_tiny and
    // float_safe, cb_tile.h).
    uint64_t directions(const uint32_t* index, uint32_t count, float* ex, float* ey, float* ez, float* fd,
                        double (*world)[tile_capacity], double* dist) const {
        alignas(64) double e[3][tile_capacity];
        offsets(index, count, e, dist, world);
        using simd::Doubles;
        const Doubles zero = simd::dsplat(0), unset = simd::dsplat(-1), lo = simd::dsplat(float_tiny),
                      hi = simd::dsplat(float_safe);
        const uint64_t lanes = tile_lanes(count);
        uint64_t regular = 0;
        for (uint32_t i = 0; i < tile_capacity; i += simd::dwidth) {
            const Doubles d = simd::load(dist + i);
            const simd::DoubleMask in = simd::double_lanes(simd::double_group(lanes, i)) & (d > lo) & (d < hi);
            regular |= uint64_t(simd::bits(in)) << i;
            simd::store_floats(ex + i, simd::select(in, simd::load(e[0] + i), zero));
            simd::store_floats(ey + i, simd::select(in, simd::load(e[1] + i), zero));
            simd::store_floats(ez + i, simd::select(in, simd::load(e[2] + i), zero));
            simd::store_floats(fd + i, simd::select(in, d, unset));
        }
        return regular;
    }

    // The offsets from the light of tile points points_ + 3 * index[i], by coordinate, and their lengths, in
    // double lanes (past `count`: the light's own, zero), and the points themselves into `world` when given;
    // returns the points whose coordinates are finite.
    uint64_t offsets(const uint32_t* index, uint32_t count, double (*e)[tile_capacity], double* dist,
                     double (*world)[tile_capacity] = nullptr) const {
        for (uint32_t i = 0; i < tile_capacity; ++i) {
            const double* p = i < count ? points_ + size_t(index[i]) * 3 : light_;
            for (int k = 0; k < 3; ++k) e[k][i] = p[k];
        }
        using simd::Doubles;
        const Doubles largest = simd::dsplat(DBL_MAX);
        uint64_t finite = 0;
        for (uint32_t i = 0; i < tile_capacity; i += simd::dwidth) {
            Doubles d[3];
            simd::DoubleMask bounded = simd::double_lanes(~0u);
            for (int k = 0; k < 3; ++k) {
                const Doubles p = simd::load(e[k] + i);
                if (world) simd::store(world[k] + i, p);
                bounded = bounded & (simd::abs(p) <= largest);
                d[k] = p - simd::dsplat(light_[k]);
                simd::store(e[k] + i, d[k]);
            }
            simd::store(dist + i, simd::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]));
            finite |= uint64_t(simd::bits(bounded)) << i;
        }
        return finite & tile_lanes(count);
    }

    // Instance sphere `sphere` (centre, radius) and world box `box` for this light. For a point light, the
    // radius grown by 2e-5 of itself and of the centre's distance, as the scan's spheres are, and rounded up to
    // float; past the float test's range (lit_sphere_points) every point enters. For a sun, the centre in the
    // sun's frame.
    LightSphere light_sphere(uint32_t h) const {
        const double* sphere = level_->world_sphere(h);
        const level_detail::OrientedBox& box = level_->oriented_box(h);
        LightSphere s{};
        s.r = sphere[3];
        if (sun_) {
            s.c[0] = math::dot3(sphere, sun_frame_[1]);
            s.c[1] = math::dot3(sphere, sun_frame_[2]);
            s.c[2] = math::dot3(sphere, sun_frame_[0]);
            s.size = std::fabs(sphere[0]) + std::fabs(sphere[1]) + std::fabs(sphere[2]) + sphere[3];
            s.whole = !(s.size < 1e30);
            s.flat = flat_test(h);
            return s;
        }
        const double c[3] = {sphere[0] - light_[0], sphere[1] - light_[1], sphere[2] - light_[2]}, r = sphere[3];
        const double d1 = std::fabs(c[0]) + std::fabs(c[1]) + std::fabs(c[2]), grown = r + 2e-5 * (r + d1);
        s.whole = !(d1 + grown < float_safe && d1 + grown > float_tiny);
        if (s.whole) return s;
        float fr = float(grown);
        if (double(fr) < grown) fr = std::nextafter(fr, INFINITY);
        s.f[0] = float(c[0]);
        s.f[1] = float(c[1]);
        s.f[2] = float(c[2]);
        s.f[3] = fr;
        if (!box.empty() && level_->instance_count() > 1) {  // one instance takes every point (walk)
            const double centre[3] = {box.c[0] - light_[0], box.c[1] - light_[1], box.c[2] - light_[2]};
            s.box = make_box_filter(centre, box.h, box.axis);
            s.flat = flat_test(h);
        }
        return s;
    }

    // Instance h's slab test for this light (clear_of_slab): usable when its mesh is flat and the light
    // lies off the slab by more than the test's margins.
    FlatTest flat_test(uint32_t h) const {
        FlatTest f;
        const level_detail::Slab& slab = level_->slab(h);
        double inverse[12];
        if (slab.axis < 0 || !(options_.bias > 0 && options_.bias < INFINITY) ||
            !invert_instance(level_->transform_of(h), inverse))
            return f;
        const int k = slab.axis;
        const double row[4] = {inverse[k], inverse[3 + k], inverse[6 + k], inverse[9 + k]};
        const double t[3] = {row[0] * light_[0], row[1] * light_[1], row[2] * light_[2]};
        if (sun_) {  // the direction's coordinate along the axis, as apply_linear makes it
            const double along = t[0] + t[1] + t[2], from = sun_from(light_, options_.bias);
            const double terms = std::fabs(t[0]) + std::fabs(t[1]) + std::fabs(t[2]);
            f.sign = along > 0 ? 1.0 : -1.0;
            f.edge = f.sign > 0 ? slab.hi : -slab.lo;
            f.light_side = from * f.sign * along;
            f.light_terms = from * terms;
            std::copy(row, row + 4, f.row);
            f.usable = f.sign * along > 1e-12 * terms && from < INFINITY && f.light_terms < 1e300 &&
                std::isfinite(row[0] + row[1] + row[2] + row[3]);
            return f;
        }
        const double b = t[0] + t[1] + t[2] + row[3];  // apply_instance's order
        f.light_terms = std::fabs(t[0]) + std::fabs(t[1]) + std::fabs(t[2]) + std::fabs(row[3]);
        f.sign = b > slab.hi ? 1.0 : -1.0;
        f.edge = f.sign > 0 ? slab.hi : -slab.lo;
        f.light_side = f.sign * b;
        std::copy(row, row + 4, f.row);
        f.bias = options_.bias;
        const double margin = 1e-13 * (f.light_terms + std::fabs(f.edge));
        f.usable = f.light_side - f.edge > 2 * margin && f.light_terms < 1e300 &&
            std::isfinite(row[0] + row[1] + row[2] + row[3]);
        return f;
    }

    // The tile's points whose segment may meet an instance's sphere and then its world box: the regular ones by
    // the float tests (the box's where it is usable; `whole` is 1 in every lane), every other point, and all of
    // them where the sphere is not within the float test's range.
    static uint64_t instance_points(const LightSphere& s, uint64_t regular, const float* ex, const float* ey,
                                    const float* ez, const float* fd, const float* whole) {
        if (s.whole) return ~uint64_t(0);
        uint64_t in = lit_sphere_points(s.f[0], s.f[1], s.f[2], s.f[3], regular, ex, ey, ez, fd);
        if (in && s.box.usable) in = box_lanes(s.box, in, ex, ey, ez, fd, whole);
        return in | ~regular;
    }

    // A point light's tile, by coordinate from the light (offsets), and which of its points a pyramid takes:
    // `taken` (finite, beyond float_tiny of the light and within 1e30), `alone` (the others finite and not at
    // the light: they walk the hierarchy on their own segment), m the sum of the taken ones' unit directions;
    // `group_held`, those the tile's group's pyramid holds (cull_group).
    struct TileOffsets {
        alignas(64) double e[3][tile_capacity], dist[tile_capacity];
        uint64_t taken = 0, alone = 0, group_held = 0;
        double m[3] = {0, 0, 0};
    };
    static constexpr uint32_t group_tiles = 8;
    // Every probe_tiles tiles, the first group decides whether the next ones cull in groups (pays): a group
    // pays while it meets at most group_cost times the instances of one of its tiles.
    static constexpr uint32_t probe_tiles = 64, group_cost = 4;

    void tile_offsets(size_t t, TileOffsets& o) const {
        const uint32_t count = tile_count_at(t);
        const uint32_t* index = order_.data() + t * tile_capacity;
        const uint64_t finite = offsets(index, count, o.e, o.dist);  // a point not finite is never in shadow
        // By the light, or beyond what a pyramid holds well: alone; at the light (no length): neither.
        using simd::Doubles;
        const Doubles zero = simd::dsplat(0), one = simd::dsplat(1), tiny = simd::dsplat(float_tiny),
                      huge = simd::dsplat(1e30);
        const uint64_t lanes = tile_lanes(count);
        uint64_t taken = 0, alone = 0;
        for (uint32_t i = 0; i < tile_capacity; i += simd::dwidth) {
            const Doubles d = simd::load(o.dist + i);
            const simd::DoubleMask in = simd::double_lanes(simd::double_group(lanes, i));
            taken |= uint64_t(simd::bits(in & (d > tiny) & (d < huge))) << i;
            alone |= uint64_t(simd::bits(in & (d > zero))) << i;
        }
        o.alone = alone & finite & ~taken;
        o.taken = taken;
        Doubles sum[3] = {zero, zero, zero};
        for (uint32_t i = 0; i < tile_capacity; i += simd::dwidth) {
            const uint32_t group = simd::double_group(taken, i);
            if (!group) continue;
            const simd::DoubleMask in = simd::double_lanes(group);
            const Doubles inv = one / simd::load(o.dist + i);
            for (int k = 0; k < 3; ++k) sum[k] = sum[k] + simd::select(in, simd::load(o.e[k] + i) * inv, zero);
        }
        for (int k = 0; k < 3; ++k) o.m[k] = simd::lane_sum(sum[k]);
    }

    // The pyramid of a group of `n` tiles (every taken point of theirs within 60 degrees of their mean
    // direction; each tile's group_held) and into `met` the instances it may meet; met.usable false when
    // there is none such pyramid.
    void cull_group(TileOffsets* tiles, uint32_t n, level_detail::MetBoxes& met) const {
        met.clear();
        met.usable = false;
        double m[3] = {0, 0, 0}, frame[3][3];
        for (uint32_t i = 0; i < n; ++i)
            for (int k = 0; k < 3; ++k) m[k] += tiles[i].m[k];
        for (uint32_t i = 0; i < n; ++i) tiles[i].group_held = 0;
        if (!direction_frame(m, frame)) return;
        PyramidSpan span;
        uint64_t held = 0;
        for (uint32_t i = 0; i < n; ++i) {
            tiles[i].group_held = span.add(frame, tiles[i].e, tiles[i].dist, tiles[i].taken);
            held |= tiles[i].group_held;
        }
        if (!held) return;
        level_detail::WorldPyramid w;
        span.finish(frame, light_, w);
        level_->visit_pyramid(w, [&](uint32_t h, double) { met.add(level_->world_box(h), h); });
        met.usable = true;
    }

    // Whether culling in groups pays, from a probe group of n tiles: their group's pyramid met `group_met`
    // instances and their own pyramids `tiles_met` in all. Where a group meets many times what one of its
    // tiles does (light from above onto a wide level: each tile's pyramid is wide against the instances),
    // the group's walk costs more than the tiles' own walks it saves.
    static bool pays(uint32_t group_met, uint32_t tiles_met, uint32_t n) {
        return uint64_t(group_met) * n <= uint64_t(group_cost) * tiles_met;
    }

    // The offsets of tiles [g, end) into `tiles`.
    void offsets_of(size_t g, size_t end, TileOffsets* tiles) const {
        for (size_t t = g; t < end; ++t) {
            if (t + 1 < end) prefetch_points(t + 1);
            tile_offsets(t, tiles[t - g]);
        }
    }

    // The probe group from tile `probe` (the first of probe_tiles), culled in a group with its tiles' lists
    // kept for those in the range [first, last); returns `pays` for it, counted over all its tiles: the same
    // decision whatever the ranges (a range that starts past its probe counts it and keeps nothing).
    bool probe_pays(size_t probe, size_t first, size_t last, TileOffsets* tiles, level_detail::MetBoxes& met) {
        const size_t end = std::min<size_t>(probe + group_tiles, tile_count_);
        offsets_of(probe, end, tiles);
        cull_group(tiles, uint32_t(end - probe), met);
        uint32_t met_by_tiles = 0;
        for (size_t t = probe; t < end; ++t)
            met_by_tiles += cull_point_tile(t, tiles[t - probe], met, t >= first && t < last);
        return pays(met.count, met_by_tiles, uint32_t(end - probe));
    }

    // The instances point-light tile t's pyramid (and the segments of its points the pyramid does not hold) may
    // meet, nearest first: each entry the float bits of its distance along the pyramid's axis (not below 0, so
    // they order as integers) above its handle. The pyramid's from those its group met (`met`) when the group's
    // pyramid holds every point the tile's holds, else from the level's hierarchy.
    uint32_t cull_point_tile(size_t t, const TileOffsets& o, const level_detail::MetBoxes& met, bool keep = true) {
        level_detail::LaneVector<uint64_t>& list = tile_lists_[t];
        if (keep) list.clear();
        const uint32_t* index = order_.data() + t * tile_capacity;
        level_detail::WorldPyramid w;
        const uint64_t held = o.taken ? make_pyramid(o.e, o.dist, o.taken, o.m, w) : 0;
        uint32_t count = 0;
        auto add = [&](uint32_t h, double near) {
            ++count;
            if (keep) list.push_back(entry(near, h));
        };
        if (held) {
            if (met.usable && !(held & ~o.group_held))
                level_detail::visit_met(w, met, add);
            else
                level_->visit_pyramid(w, add);
        }
        if (!keep) return count;
        const uint64_t alone = o.alone | (o.taken & ~held);  // over 60 degrees off the tile's mean direction
        for (uint64_t b = alone; b; b &= b - 1) {
            const double* p = points_ + size_t(index[math::lowest_bit(b)]) * 3;
            level_->visit_segment(p, light_, [&](uint32_t h, double) { list.push_back(entry(0, h)); });
        }
        if (alone) once_each(list);  // once each, at its nearest
        // A comparator of this namespace's own: std::sort's instantiation for plain integers would be shared
        // with the builds for other lanes (cb_simd.h), and the linker could keep a wider build's copy.
        std::sort(list.begin(), list.end(), [](uint64_t x, uint64_t y) { return x < y; });
        return count;
    }

    // The bounding rectangle of some points' central projections in a frame (direction_frame: z, then the
    // axes a and b across it) and their largest distance, over one tile or several (add), and the pyramid
    // from the light through that rectangle widened by 1e-6, far above the projections' rounding (finish).
    struct PyramidSpan {
        simd::Doubles lo0 = simd::dsplat(INFINITY), lo1 = simd::dsplat(INFINITY), hi0 = simd::dsplat(-INFINITY),
                      hi1 = simd::dsplat(-INFINITY), far = simd::dsplat(0);

        // Takes the points of `taken` (e from the light, by coordinate, dist their lengths) within 60 degrees of
        // z; returns them.
        uint64_t add(const double (*frame)[3], const double (*e)[tile_capacity], const double* dist, uint64_t taken) {
            const double *z = frame[0], *a = frame[1], *b = frame[2];
            using simd::Doubles;
            const Doubles inf = simd::dsplat(INFINITY), ninf = simd::dsplat(-INFINITY), zero = simd::dsplat(0);
            uint64_t held = 0;
            for (uint32_t i = 0; i < tile_capacity; i += simd::dwidth) {
                const uint32_t group = simd::double_group(taken, i);
                if (!group) continue;
                const Doubles x = simd::load(e[0] + i), y = simd::load(e[1] + i), v = simd::load(e[2] + i),
                              d = simd::load(dist + i);
                const Doubles depth = x * simd::dsplat(z[0]) + y * simd::dsplat(z[1]) + v * simd::dsplat(z[2]);
                const simd::DoubleMask in = simd::double_lanes(group) & (depth > simd::dsplat(0.5) * d);
                const Doubles u = (x * simd::dsplat(a[0]) + y * simd::dsplat(a[1]) + v * simd::dsplat(a[2])) / depth,
                              s = (x * simd::dsplat(b[0]) + y * simd::dsplat(b[1]) + v * simd::dsplat(b[2])) / depth;
                lo0 = simd::min(lo0, simd::select(in, u, inf));
                hi0 = simd::max(hi0, simd::select(in, u, ninf));
                lo1 = simd::min(lo1, simd::select(in, s, inf));
                hi1 = simd::max(hi1, simd::select(in, s, ninf));
                far = simd::max(far, simd::select(in, d, zero));
                held |= uint64_t(simd::bits(in)) << i;
            }
            return held;
        }

        // The pyramid through the rectangle (some point added and held).
        void finish(const double (*frame)[3], const double* light, level_detail::WorldPyramid& w) const {
            const double lo[2] = {simd::lane_min(lo0) - 1e-6, simd::lane_min(lo1) - 1e-6},
                         hi[2] = {simd::lane_max(hi0) + 1e-6, simd::lane_max(hi1) + 1e-6};
            w.dmax = simd::lane_max(far);
            const double corner[4][2] = {{lo[0], lo[1]}, {hi[0], lo[1]}, {hi[0], hi[1]}, {lo[0], hi[1]}};
            double ray[4][3], inside[3];
            for (int r = 0; r < 4; ++r) frame_ray(frame, corner[r][0], corner[r][1], ray[r]);
            // Each side's normal turned toward the rectangle's centre: the mean direction z may lie outside the
            // rectangle when points over 60 degrees off it were left out.
            frame_ray(frame, 0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), inside);
            for (int r = 0; r < 4; ++r) {
                double n[3];
                math::cross3(ray[r], ray[(r + 1) & 3], n);
                if (math::dot3(n, inside) < 0)
                    for (int k = 0; k < 3; ++k) n[k] = -n[k];
                const double nl = std::sqrt(math::dot3(n, n));
                for (int k = 0; k < 3; ++k) n[k] = nl > 0 ? n[k] / nl : 0.0;
                w.nx[r] = n[0];
                w.ny[r] = n[1];
                w.nz[r] = n[2];
                w.ax[r] = std::fabs(n[0]);
                w.ay[r] = std::fabs(n[1]);
                w.az[r] = std::fabs(n[2]);
            }
            for (int k = 0; k < 3; ++k) {
                w.light[k] = light[k];
                w.axis[k] = frame[0][k];
            }
        }
    };

    // The pyramid from the light holding the directions of the points `taken` (e from the light, by
    // coordinate, dist their lengths, m the sum of their unit directions): a frame on their mean direction and
    // the points' PyramidSpan. Returns the points it holds: those of `taken` within 60 degrees of the mean
    // direction.
    uint64_t make_pyramid(const double (*e)[tile_capacity], const double* dist, uint64_t taken, const double* m,
                          level_detail::WorldPyramid& w) const {
        double frame[3][3];
        if (!direction_frame(m, frame)) return 0;
        PyramidSpan span;
        const uint64_t held = span.add(frame, e, dist, taken);
        if (held) span.finish(frame, light_, w);
        return held;
    }

    const Level* level_ = nullptr;
    const double* points_ = nullptr;
    size_t n_ = 0, tile_count_ = 0, built_count_ = 0;
    double light_[3] = {0, 0, 0};  // the light, or the direction toward the sun
    bool sun_ = false, sun_usable_ = false;
    double sun_frame_[3][3] = {};  // the sun's direction and two unit axes across it (direction_frame)
    ShadowBuildOptions options_;
    level_detail::LaneVector<uint32_t> order_, order_scratch_;
    level_detail::LaneVector<uint64_t> unculled_;  // the entries every tile lists when not culled (list_unculled)
    level_detail::LaneVector<level_detail::LaneVector<uint64_t>>
        tile_lists_;  // per tile: cull's entries, then (gather) slots of needed_
    level_detail::LaneVector<uint32_t> slot_of_, stamp_, needed_;
    uint32_t generation_ = 0;
    std::vector<InstanceShadow> shadows_;
    std::vector<LightSphere> spheres_;  // per gathered instance (gather)
};

// The fine clusters of every live instance that a camera may see (cull_clusters of cb_cull.h over an asset),
// walking the level's hierarchy first: out[i].instance is the level's handle, out[i].fine the index into that
// instance's asset's fine clusters. Returns how many there are (which may exceed capacity).
inline size_t cull_clusters(const Level& level, const Frustum& f, bool backface, VisibleCluster* out, size_t capacity,
                            CullStats* stats = nullptr) {
    size_t count = 0;
    level.visit_frustum(f, [&](uint32_t h) {
        count = cull_instance(level.asset(level.asset_of(h)), level.placement(h), h, f, backface, out, capacity, count,
                              stats);
    });
    return count;
}

// The level's live instances, in handle order, for reference_query (cb_shadow.h).
inline auto level_placements(const Level& level) {
    return [&level](auto visit) {
        for (uint32_t h = 0; h < level.handle_limit(); ++h)
            if (level.alive(h) && !visit(level.asset(level.asset_of(h)), level.placement(h))) return;
    };
}

// The reference query over a level: every live instance, in handle order, as instance_occludes_reference
// (cb_shadow.h) tests it, with the self-shadowing `bias` (zero or less: the level's shadow_bias()); no
// hierarchy, no per-light structure. Returns true when p is in shadow.
inline bool occluded_reference(const Level& level, const double* p, const double* light, double bias,
                               bool one_sided = false, QueryStats* stats = nullptr) {
    return reference_query(level_placements(level), p, light, bias > 0 ? bias : level.shadow_bias(), false, one_sided,
                           stats);
}

// The sun's reference query over a level (cb_shadow.h, occluded_sun_reference), every live instance in
// handle order, with the self-shadowing `bias` (zero or less: the level's shadow_bias()).
inline bool occluded_sun_reference(const Level& level, const double* p, const double* toward, double bias,
                                   bool one_sided = false, QueryStats* stats = nullptr) {
    return reference_query(level_placements(level), p, toward, bias > 0 ? bias : level.shadow_bias(), true, one_sided,
                           stats);
}

}  // namespace CB_LANES
}  // namespace cb
