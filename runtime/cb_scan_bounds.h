// The light-independent bounds the scan traversal (cb_scan.h) reads of one mesh's clusters: their boxes,
// decoded, and bounding spheres about them, made once per asset. Header-only C++17, no exceptions. MIT
// licensed (runtime/LICENSE).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "cb_asset.h"
#include "detail/cb_simd.h"

namespace cb {
inline namespace CB_LANES {

// What the scan traversal (ScanTraversal) reads of one mesh's clusters that does not depend on the light:
// their boxes, decoded, and the bounding spheres about them. Make them once per asset (make_scan_bounds)
// and pass them to every build (ShadowBuildOptions::bounds). The spheres' centres are stored in float from
// `origin`, the middle of the mesh's coarse box centres, so that their precision follows the mesh's size
// rather than its distance from the frame's origin; each radius holds the box's corners (to 1e-6 of itself,
// more than the axes' departure from orthonormal) and its centre's rounding, rounded up.
struct ScanBounds {
    const PackedObb* source_fine = nullptr;  // the packed boxes they were made from (build() checks them)
    const PackedObb* source_coarse = nullptr;
    uint32_t fine_count = 0, coarse_count = 0;
    std::vector<Obb> fine_obbs, coarse_obbs;  // decoded (unpack_obb): the box set-ups read these
    uint32_t coarse_first = 0;  // the first coarse sphere's index: after the fine ones and a group of padding
    double origin[3] = {0, 0, 0};
    double extent = INFINITY;       // at least |centre|_1 + radius of every sphere; not below float_safe: unusable
    std::vector<float> x, y, z, r;  // fine spheres, padding, coarse spheres, padding (a lane group each)

    // Mesh `mesh` of `view`, which needs fine and coarse boxes (otherwise nothing is made, and the scan tests
    // every cluster).
    void make(const AssetView& view, uint32_t mesh_index) {
        const MeshRecord& mesh = view.meshes[mesh_index];
        *this = ScanBounds{};
        if (!view.fine_bounds.obbs || !view.coarse_bounds.obbs) return;
        const PackedObb *fine_boxes = view.fine_bounds.obbs + mesh.first_fine,
                        *coarse_boxes = view.coarse_bounds.obbs + mesh.first_coarse;
        source_fine = fine_boxes;
        source_coarse = coarse_boxes;
        fine_count = mesh.fine_count;
        coarse_count = mesh.coarse_count;
        fine_obbs.resize(fine_count);
        coarse_obbs.resize(coarse_count);
        for (uint32_t f = 0; f < fine_count; ++f) fine_obbs[f] = unpack_obb(fine_boxes[f]);
        for (uint32_t c = 0; c < coarse_count; ++c) coarse_obbs[c] = unpack_obb(coarse_boxes[c]);
        const uint32_t w = simd::width;
        coarse_first = (fine_count + w - 1) / w * w + w;
        const size_t total = size_t(coarse_first) + (coarse_count + w - 1) / w * w + w;
        for (std::vector<float>* a : {&x, &y, &z, &r}) a->assign(total, 0.0f);
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (uint32_t c = 0; c < coarse_count; ++c)
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], double(coarse_boxes[c].center[k]));
                hi[k] = std::max(hi[k], double(coarse_boxes[c].center[k]));
            }
        for (int k = 0; k < 3; ++k) origin[k] = coarse_count ? 0.5 * (lo[k] + hi[k]) : 0.0;
        extent = 0;
        auto fill = [&](const PackedObb* boxes, uint32_t count, uint32_t out) {
            for (uint32_t i = 0; i < count; ++i) {
                const PackedObb& b = boxes[i];
                const double pad = 1e-6 * (double(b.half[0]) + double(b.half[1]) + double(b.half[2]));
                const double h0 = b.half[0] + pad, h1 = b.half[1] + pad, h2 = b.half[2] + pad;
                const double cx = b.center[0] - origin[0], cy = b.center[1] - origin[1], cz = b.center[2] - origin[2];
                const double c1 = std::fabs(cx) + std::fabs(cy) + std::fabs(cz);
                const double radius =
                    std::sqrt(h0 * h0 + h1 * h1 + h2 * h2) * (1 + 1e-6) + 2.4e-7 * c1;  // + the centre's rounding
                float f = float(radius);
                if (double(f) < radius) f = std::nextafter(f, INFINITY);
                x[out + i] = float(cx);
                y[out + i] = float(cy);
                z[out + i] = float(cz);
                r[out + i] = f;
                extent = c1 + double(f) < INFINITY ? std::max(extent, c1 + double(f)) : INFINITY;  // NaN too: unusable
            }
        };
        fill(fine_boxes, fine_count, 0);
        fill(coarse_boxes, coarse_count, coarse_first);
    }

    bool made_from(const AssetView& view, const MeshRecord& mesh) const {
        return source_fine && source_fine == view.fine_bounds.obbs + mesh.first_fine &&
            source_coarse == view.coarse_bounds.obbs + mesh.first_coarse && fine_count == mesh.fine_count &&
            coarse_count == mesh.coarse_count;
    }

    size_t memory_bytes() const {
        return (x.capacity() + y.capacity() + z.capacity() + r.capacity()) * sizeof(float) +
            (fine_obbs.capacity() + coarse_obbs.capacity()) * sizeof(Obb);
    }
};

// Five planes a scan tests spheres against (a tile's pyramid from a light, or its prism along a sun): sphere i
// may meet the tile only if n_q . c_i + r_i >= side_q for every plane q, c_i its centre as stored (from
// ScanBounds::origin). The caller lowers each side far enough below its double value to hold the float
// evaluation's errors.
struct SpherePlanes {
    float nx[5], ny[5], nz[5], side[5];
};

// Bit j for each sphere first + j of `s` (j < n <= 64) that passes every plane: in float, a vector of
// spheres an instruction (the arrays are padded past each level's last group).
inline uint64_t spheres_passing(const ScanBounds& s, uint32_t first, uint32_t n, const SpherePlanes& planes) {
    const float *x = &s.x[first], *y = &s.y[first], *z = &s.z[first], *rr = &s.r[first];
    uint64_t keep = 0;
    for (uint32_t j = 0; j < n; j += simd::width) {
        const simd::Floats cx = simd::loadu(x + j), cy = simd::loadu(y + j), cz = simd::loadu(z + j),
                           r = simd::loadu(rr + j);
        simd::Mask k =
            simd::dot_plus(cx, cy, cz, planes.nx[0], planes.ny[0], planes.nz[0], r) >= simd::splat(planes.side[0]);
        for (int q = 1; q < 5; ++q)
            k = k &
                (simd::dot_plus(cx, cy, cz, planes.nx[q], planes.ny[q], planes.nz[q], r) >=
                 simd::splat(planes.side[q]));
        keep |= uint64_t(simd::bits(k)) << j;
    }
    return n < 64 ? keep & ((uint64_t(1) << n) - 1) : keep;
}

// The scan bounds of every mesh of `view`, indexed by mesh (what ShadowBuildOptions::bounds points to).
inline std::vector<ScanBounds> make_scan_bounds(const AssetView& view) {
    std::vector<ScanBounds> all(view.mesh_count);
    for (uint32_t m = 0; m < view.mesh_count; ++m) all[m].make(view, m);
    return all;
}

}  // namespace CB_LANES
}  // namespace cb
