// Point-light shadow queries over the asset's two-level cluster hierarchy, after the thesis's clustered
// partitioned shadow volumes (CPSV, chapter 2): for one light, find the few clusters whose shadow volume
// may hold a point and test only their triangles, exactly (cb_shadow.h), so that the answers are those of
// occluded_reference, faster. Two ways to find them (FineLevel):
//
// The scan (the default) builds no tree. A cluster's shadow volume is taken as the cone from the light
// around its bounding sphere (about its box). A batch's tile of points checks every coarse cluster's sphere
// against the pyramid from the light that holds the tile's directions, its points against the boxes of
// those that pass, then the fine spheres of the coarse clusters entered, a vector of spheres an
// instruction. The spheres and decoded boxes do not depend on the light (ScanBounds, made once per asset),
// so a light's build only sets up the coarse boxes. On 2 cores, a linear pass over a few thousand coarse
// spheres per tile measured cheaper than building and walking a tree over their volumes every frame
// (docs/RUNTIME.md).
//
// The TOP-trees (the thesis's method): ternary trees of planes through the light over the shadow volumes of
// cluster boxes. Each volume is a chain of its 4 planes: the inside branch of one plane leads to the next,
// and the last to a cluster node. A plane node has three children: inside (volumes entirely on its
// inside), outside (entirely outside) and straddling (both); a query follows the side its point is on, and
// the straddling child unless the point is farther from the plane than any volume down there reaches. A
// cluster node acts when the point is beyond the closing distance, then goes on into its own subtree:
// volumes inserted later that lie inside this one. Nothing is dropped there: a volume is only conservative,
// so a point inside it may still be lit by its cluster and shadowed by a later one. Volumes go in, one by
// one, in a shuffled order (fixed seed) that keeps the trees balanced. Clusters whose box holds the light,
// or is level with it, have no volume: they are tested for every point that gets that far. Two levels: a
// tree over the coarse clusters' volumes whose cluster nodes enter a tree over that coarse cluster's fine
// clusters (FineLevel::trees, when the asset has coarse boxes; otherwise, and with FineLevel::one_tree, one
// tree over the fine clusters).
//
// Every node also keeps the smallest closing distance of the volumes below it: a point nearer the light
// than that skips the whole subtree (nothing there can shadow it). Plane nodes and cluster nodes live in
// two arrays of 32-byte records; a child reference with the top bit set names a cluster node.
//
// Batches (occluded_batch) sort their points by direction from the light and take them in tiles of 64
// points, with a pyramid from the light that holds their directions (occluded_tile): one scan, or one walk
// of each tree, per tile; the answers are those of a walk per point.
//
// Building allocates (std::vector; a BuildScratch lets rebuilds reuse memory); queries do not: occluded()
// takes a stack of stack_size() entries, occluded_batch a scratch of batch_scratch_size() words.
// Header-only C++17, no exceptions. MIT licensed (runtime/LICENSE).
#pragma once

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <new>
#include <thread>
#include <vector>

#include "cb_asset.h"
#include "cb_shadow.h"

namespace cb {

// What ClusterShadowTree's scan (FineLevel::scan) reads of one mesh's clusters that does not depend on the
// light: their boxes, decoded, and the bounding spheres about them. Make them once per asset
// (make_scan_bounds) and pass them to every build. The spheres' centres are stored in float from `origin`,
// the middle of the mesh's coarse box centres, so that their precision follows the mesh's size rather than
// its distance from the frame's origin; each radius holds the box's corners (to 1e-6 of itself, more than
// the axes' departure from orthonormal) and its centre's rounding, rounded up.
struct ScanBounds {
    const PackedObb* source_fine = nullptr;  // the packed boxes they were made from (build() checks them)
    const PackedObb* source_coarse = nullptr;
    uint32_t fine_count = 0, coarse_count = 0;
    std::vector<Obb> fine_obbs, coarse_obbs;  // decoded (unpack_obb): the box set-ups read these
    uint32_t coarse_first = 0;  // the first coarse sphere's index: after the fine ones and a group of padding
    double origin[3] = {0, 0, 0};
    double extent = INFINITY;  // at least |centre|_1 + radius of every sphere; not below float_safe: unusable
    std::vector<float> x, y, z, r;  // fine spheres, padding, coarse spheres, padding (a lane group each)

    // Mesh `mesh` of `view`, which needs fine and coarse boxes (otherwise nothing is made, and the tree tests
    // every cluster).
    void make(const AssetView& view, uint32_t mesh_index) {
        const MeshRecord& mesh = view.meshes[mesh_index];
        *this = ScanBounds{};
        if (!view.fine_bounds.obbs || !view.coarse_bounds.obbs) return;
        const PackedObb *fine_boxes = view.fine_bounds.obbs + mesh.first_fine, *coarse_boxes = view.coarse_bounds.obbs + mesh.first_coarse;
        source_fine = fine_boxes, source_coarse = coarse_boxes;
        fine_count = mesh.fine_count, coarse_count = mesh.coarse_count;
        fine_obbs.resize(fine_count), coarse_obbs.resize(coarse_count);
        for (uint32_t f = 0; f < fine_count; ++f) fine_obbs[f] = unpack_obb(fine_boxes[f]);
        for (uint32_t c = 0; c < coarse_count; ++c) coarse_obbs[c] = unpack_obb(coarse_boxes[c]);
        const uint32_t w = simd::width;
        coarse_first = (fine_count + w - 1) / w * w + w;
        const size_t total = size_t(coarse_first) + (coarse_count + w - 1) / w * w + w;
        for (std::vector<float>* a : {&x, &y, &z, &r}) a->assign(total, 0.0f);
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (uint32_t c = 0; c < coarse_count; ++c)
            for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], double(coarse_boxes[c].center[k])), hi[k] = std::max(hi[k], double(coarse_boxes[c].center[k]));
        for (int k = 0; k < 3; ++k) origin[k] = coarse_count ? 0.5 * (lo[k] + hi[k]) : 0.0;
        extent = 0;
        auto fill = [&](const PackedObb* boxes, uint32_t count, uint32_t out) {
            for (uint32_t i = 0; i < count; ++i) {
                const PackedObb& b = boxes[i];
                const double pad = 1e-6 * (double(b.half[0]) + double(b.half[1]) + double(b.half[2]));
                const double h0 = b.half[0] + pad, h1 = b.half[1] + pad, h2 = b.half[2] + pad;
                const double cx = b.center[0] - origin[0], cy = b.center[1] - origin[1], cz = b.center[2] - origin[2];
                const double c1 = std::fabs(cx) + std::fabs(cy) + std::fabs(cz);
                const double radius = std::sqrt(h0 * h0 + h1 * h1 + h2 * h2) * (1 + 1e-6) + 2.4e-7 * c1;  // + the centre's rounding
                float f = float(radius);
                if (double(f) < radius) f = std::nextafter(f, INFINITY);
                x[out + i] = float(cx), y[out + i] = float(cy), z[out + i] = float(cz), r[out + i] = f;
                extent = c1 + double(f) < INFINITY ? std::max(extent, c1 + double(f)) : INFINITY;  // NaN too: unusable
            }
        };
        fill(fine_boxes, fine_count, 0);
        fill(coarse_boxes, coarse_count, coarse_first);
    }

    bool made_from(const AssetView& view, const MeshRecord& mesh) const {
        return source_fine && source_fine == view.fine_bounds.obbs + mesh.first_fine && source_coarse == view.coarse_bounds.obbs + mesh.first_coarse &&
               fine_count == mesh.fine_count && coarse_count == mesh.coarse_count;
    }

    size_t memory_bytes() const {
        return (x.capacity() + y.capacity() + z.capacity() + r.capacity()) * sizeof(float) + (fine_obbs.capacity() + coarse_obbs.capacity()) * sizeof(Obb);
    }
};

// The scan bounds of every mesh of `view`, indexed by mesh (what ClusterShadowTree::build takes).
inline std::vector<ScanBounds> make_scan_bounds(const AssetView& view) {
    std::vector<ScanBounds> all(view.mesh_count);
    for (uint32_t m = 0; m < view.mesh_count; ++m) all[m].make(view, m);
    return all;
}

class ClusterShadowTree {
public:
    static constexpr uint32_t none = 0xffffffffu;
    struct BuildScratch;  // working arrays of build(), reusable between builds (defined below)

    // How a query reaches the fine clusters.
    enum class FineLevel : uint8_t {
        scan,      // no tree: the coarse clusters' bounding spheres are scanned against a tile's pyramid, then
                   // each entered one's fine spheres against the pyramid of its points (the default: the only
                   // per-light work is setting up the coarse boxes)
        trees,     // a tree over the coarse clusters whose cluster nodes enter a tree over that coarse cluster's
                   // fine clusters (the thesis's two levels)
        one_tree,  // one tree over all the fine clusters
    };

    // One instance of the asset's meshes, for one light given in world space. In one-sided mode
    // (cb_shadow.h), clusters whose front cone holds the light, and that have no double-sided triangle,
    // cannot block anything and are left out. Without coarse boxes in the asset, every FineLevel builds one
    // tree. With FineLevel::trees, up to `threads` threads (std::thread) build the coarse clusters' fine trees;
    // the tree is the same for any thread count.
    //
    // `scratch`, when given, keeps the build's working arrays between builds (one per concurrent build):
    // a tree rebuilt every frame then reuses memory instead of asking the system for fresh pages. The
    // tree's own arrays are reused the same way when the tree object is.
    //
    // `bounds` (scan mode): the asset's ScanBounds, indexed by mesh (make_scan_bounds), read by every query
    // and so kept alive and unchanged while the tree is used. Without them, or when they were made from
    // another asset view, the tree makes its mesh's own at each build (a pass over its boxes).
    void build(const AssetView& view, uint32_t instance, const double* world_light, bool one_sided = false,
               FineLevel fine = FineLevel::scan, unsigned threads = 1, BuildScratch* scratch = nullptr,
               const ScanBounds* bounds = nullptr) {
        BuildScratch own;
        BuildScratch& work = scratch ? *scratch : own;
        view_ = &view;
        one_sided_ = one_sided;
        scan_ = false;
        skipped_ = 0;
        planes_.clear();
        leaves_.clear();
        always_fine_.clear();
        always_coarse_.clear();
        root_ = none;
        depth_ = 0;
        top_always_ = {};
        shared_bounds_ = nullptr;
        coarse_boxes_.clear();
        coarse_skipped_.clear();
        for (int k = 0; k < 3; ++k) world_light_[k] = world_light[k];
        // A singular transform flattens the mesh: it blocks nothing. A light that is not finite lights nothing.
        usable_ = invert_instance(view.instances[instance].transform, inverse_) && finite3(world_light);
        if (!usable_) return;
        apply_instance(inverse_, world_light, light_);
        mesh_ = &view.meshes[view.instances[instance].mesh];
        const bool two = fine != FineLevel::one_tree && view.coarse_bounds.obbs;
        scan_ = two && fine == FineLevel::scan;
        Nodes& all = work.built;
        all.planes.clear();
        all.leaves.clear();
        // At most 4 planes and a cluster node per volume.
        size_t volumes = scan_ ? 0 : mesh_->fine_count + (two ? mesh_->coarse_count : 0);
        all.planes.reserve(volumes * 4);
        all.leaves.reserve(volumes);

        if (!two) {
            // One level: every fine cluster in one tree; always-tested ones in one list.
            uint32_t fine_depth = 0;
            root_ = build_fine_tree(all, 0, mesh_->fine_count, fine_depth, always_fine_, skipped_);
            top_always_ = {0, uint32_t(always_fine_.size())};
            depth_ = fine_depth;
            shrink(all, work);
            return;
        }
        const uint32_t coarse_count = mesh_->coarse_count;
        if (scan_) {  // no tree: the scan bounds, and the coarse boxes set up for this light
            const uint32_t m = view.instances[instance].mesh;
            shared_bounds_ = bounds && bounds[m].made_from(view, *mesh_) ? &bounds[m] : nullptr;
            if (!shared_bounds_) own_bounds_.make(view, m);
            const ScanBounds& s = scan_bounds();
            for (int k = 0; k < 3; ++k) light_from_origin_[k] = light_[k] - s.origin[k];
            spheres_small_ = s.extent + shadow_detail::l1(light_from_origin_) < float_safe;
            coarse_boxes_.resize(coarse_count);
            coarse_skipped_.assign(coarse_count, 0);
            for (uint32_t c = 0; c < coarse_count; ++c) {
                coarse_boxes_[c] = box_filter_of(s.coarse_obbs.empty() ? view.coarse_bounds.obb(mesh_->first_coarse + c) : s.coarse_obbs[c]);
                if (one_sided_ && skippable(view.coarse_bounds, mesh_->first_coarse + c, coarse_triangles(c)))
                    skipped_ += view.coarse[mesh_->first_coarse + c].count, coarse_skipped_[c] = 1;
            }
            return;
        }
        // Fine trees: one per coarse cluster (parts of the coarse clusters on their own threads, each into its
        // own arrays, then appended in order), then the coarse tree over them.
        std::vector<uint32_t> fine_roots(coarse_count, none);
        std::vector<Range> fine_always(coarse_count);
        std::vector<uint8_t> wanted(coarse_count, 1);
        uint32_t part_count = std::max(1u, std::min<uint32_t>(std::min(threads, 255u), coarse_count / 8));
        std::vector<Part>& parts = work.parts;
        if (parts.size() < part_count) parts.resize(part_count);
        for (uint32_t k = 0; k < part_count; ++k) {
            Part& part = parts[k];
            part.nodes.planes.clear(), part.nodes.leaves.clear(), part.always.clear(), part.skipped = 0, part.depth = 0;
        }
        // Threads take coarse clusters one at a time (their costs vary with the light); part 0 builds
        // straight into the final arrays, the others are appended after it.
        std::vector<uint8_t>& part_of = work.part_of;
        part_of.assign(coarse_count, 0);
        std::atomic<uint32_t> next{0};
        auto build_part = [&](uint32_t k) {
            Part& part = parts[k];
            Nodes& nodes = k == 0 ? all : part.nodes;
            std::vector<uint32_t>& always = k == 0 ? always_fine_ : part.always;
            for (uint32_t c = next++; c < coarse_count; c = next++) {
                part_of[c] = uint8_t(k);
                const ClusterRange& r = view.coarse[mesh_->first_coarse + c];
                if (one_sided_ && skippable(view.coarse_bounds, mesh_->first_coarse + c, coarse_triangles(c))) {
                    part.skipped += r.count;
                    wanted[c] = 0;
                    continue;
                }
                uint32_t first_always = uint32_t(always.size()), depth = 0;
                fine_roots[c] = build_fine_tree(nodes, r.first, r.count, depth, always, part.skipped);
                fine_always[c] = {first_always, uint32_t(always.size()) - first_always};
                part.depth = std::max(part.depth, depth);
            }
        };
        if (part_count == 1) {
            build_part(0);
        } else {
            std::vector<std::thread> pool;
            for (uint32_t k = 1; k < part_count; ++k) pool.emplace_back(build_part, k);
            build_part(0);
            for (std::thread& t : pool) t.join();
        }
        uint32_t fine_depth = 0;
        std::vector<uint32_t> plane_base(part_count, 0), leaf_base(part_count, 0);
        auto move = [&](uint32_t k, uint32_t ref) {  // a node reference of part k, into the merged arrays
            return ref == none ? none : ref & leaf_bit ? ((ref & ~leaf_bit) + leaf_base[k]) | leaf_bit : ref + plane_base[k];
        };
        for (uint32_t k = 0; k < part_count; ++k) {
            Part& part = parts[k];
            skipped_ += part.skipped;
            fine_depth = std::max(fine_depth, part.depth);
            if (k == 0) continue;
            plane_base[k] = uint32_t(all.planes.size()), leaf_base[k] = uint32_t(all.leaves.size());
            for (PlaneNode n : part.nodes.planes) {
                for (uint32_t& c : n.child) c = move(k, c);
                all.planes.push_back(n);
            }
            for (Leaf l : part.nodes.leaves) {
                l.inside = move(k, l.inside), l.first_plane = move(k, l.first_plane);
                all.leaves.push_back(l);
            }
        }
        if (part_count > 1) {
            // Fine roots into the merged arrays, and the always-tested lists in coarse order, so that the
            // result does not depend on which thread took which cluster.
            std::vector<uint32_t>& always = work.always;
            always.clear();
            for (uint32_t c = 0; c < coarse_count; ++c) {
                uint32_t k = part_of[c];
                fine_roots[c] = move(k, fine_roots[c]);
                const std::vector<uint32_t>& from = k == 0 ? always_fine_ : parts[k].always;
                uint32_t first = uint32_t(always.size());
                always.insert(always.end(), from.begin() + fine_always[c].first, from.begin() + fine_always[c].first + fine_always[c].count);
                fine_always[c].first = first;
            }
            always_fine_.swap(always);
        }
        uint32_t coarse_depth = build_coarse_tree(all, wanted, [&](uint32_t c, Leaf& leaf) {
            leaf.fine_root = fine_roots[c];
            leaf.always = fine_always[c];
        });
        depth_ = coarse_depth + fine_depth + 1;
        shrink(all, work);
    }

    // Entries the query stack needs: pending siblings along the deepest path through both levels.
    size_t stack_size() const { return size_t(depth_) * 2 + 4; }

    // True when the segment from world point p to the light is blocked by this instance. `stack` holds
    // stack_size() entries. In scan mode the point is a tile of one (occluded_tile's stack use): a batch
    // is far faster per point.
    bool occluded(const double* world_p, uint32_t* stack, QueryStats* stats = nullptr) const {
        if (!usable_ || !finite3(world_p)) return false;  // a point that is not finite is never in shadow
        if (scan_) {  // a tile of one point (which walks alone when it must, see occluded_tile)
            const uint32_t first = 0;
            return occluded_tile(world_p, &first, 1, 1, stack, stats) != 0;
        }
        return walk_alone(world_p, stack, stats);
    }

    // A fine cluster's box set up for one light's float separating-axis test (box_filter).
    struct BoxFilter {
        float lo[3], hi[3], hf[3], w[3][3], ax[3][3], tol;
        bool usable;  // false where float could overflow: the points are then tested in double
    };

    // What one thread's batch keeps from tile to tile (neighbouring tiles meet many of the same fine
    // clusters): lit triangle groups and box filters, each under its tree's name. clear() before the trees
    // change.
    struct Cache {
        LitCache lit;
        static constexpr uint32_t box_slots = 256;
        const void* box_owner[box_slots];
        uint32_t box_cluster[box_slots];
        BoxFilter box[box_slots];
        void clear() {
            lit.clear();
            for (const void*& o : box_owner) o = nullptr;
        }
    };

    // Points a batch query walks together (cb::occluded_batch): with close directions from the light, one
    // walk with the pyramid that holds them all stands for a walk per point.
    static constexpr uint32_t tile_capacity = 64;

    // The tile walk: of the `count` world points points + 3 * index[i] (xyz doubles), those set in `alive`
    // that this instance shadows, as a mask; the same answers as occluded() point by point. The tree is
    // walked once with a pyramid from the light that holds every point's direction: a node is skipped only
    // when no point of the tile could reach it. At a cluster node, each point is tested against the node's
    // own volume (its 4 planes and closing distance) before its cluster's triangles, so a point meets the
    // clusters whose volumes hold it, as its own walk would. Points too far from the tile's mean direction
    // (over 60 degrees; in scan mode, these make a tile of one), at the light, not finite or beyond 1e30 walk
    // alone. `stack` holds stack_size() entries; uses about 13 KB of the thread's stack besides, twice that
    // for a tile of one inside (and a cluster test's, docs/RUNTIME.md).
    uint64_t occluded_tile(const double* points, const uint32_t* index, uint32_t count, uint64_t alive, uint32_t* stack,
                           QueryStats* stats = nullptr, Cache* cache = nullptr) const {
        if (!usable_ || alive == 0) return 0;
        Tile t;
        t.count = count;
        t.stats = stats;
        t.cache = cache;
        t.alive = t.shadowed = 0;
        t.pending_count = t.entered_count = 0;
        uint64_t alone = 0;
        for (uint32_t i = 0; i < count; ++i) {
            if (!(alive >> i & 1)) continue;
            const double* w = points + size_t(index[i]) * 3;
            apply_instance(inverse_, w, t.p[i]);
            for (int k = 0; k < 3; ++k) t.e[i][k] = t.p[i][k] - light_[k];
            t.dist[i] = std::sqrt(t.e[i][0] * t.e[i][0] + t.e[i][1] * t.e[i][1] + t.e[i][2] * t.e[i][2]);
            if (!(t.dist[i] > float_tiny) || !(t.dist[i] < 1e30)) {  // at or by the light, not finite, or beyond float's range
                alone |= uint64_t(1) << i;
                continue;
            }
            t.alive |= uint64_t(1) << i;
        }
        uint64_t held = t.alive ? make_frame(t, t.alive) : 0;
        const uint64_t off = t.alive & ~held;  // over 60 degrees off the mean: in scan mode, each a tile of its own
        alone |= scan_ ? 0 : off;
        t.alive &= held;
        if (t.alive) {
            make_pyramid(t, t.alive, t.pyramid);
            t.small = t.pyramid.dmax < float_safe;
            for (uint32_t i = 0; i < tile_capacity; ++i) {
                bool in = t.alive >> i & 1;
                t.ex[i] = in ? float(t.e[i][0]) : 0.0f, t.ey[i] = in ? float(t.e[i][1]) : 0.0f, t.ez[i] = in ? float(t.e[i][2]) : 0.0f;
                t.fd[i] = in ? float(t.dist[i]) : -1.0f;  // -1: never inside a volume
                t.slack[i] = 2e-6f * t.fd[i];
            }
            t.l1_lo = INFINITY, t.l1_hi = 0;
            for (uint64_t w = t.alive; w; w &= w - 1) {
                const uint32_t i = shadow_detail::lowest_bit(w);
                t.l1[i] = std::fabs(t.e[i][0]) + std::fabs(t.e[i][1]) + std::fabs(t.e[i][2]);
                t.vl[i] = float(t.l1[i] * 1.000001);
                t.l1_lo = std::min(t.l1_lo, t.l1[i]), t.l1_hi = std::max(t.l1_hi, t.l1[i]);
            }
            for (uint32_t i = top_always_.first; i < top_always_.first + top_always_.count && t.alive; ++i)
                test_points(always_fine_[i], t.alive, t);
            for (uint32_t node : always_coarse_)
                if (t.alive) tile_walk(node, t.alive, t, stack);
            if (scan_) {
                if (t.alive) scan_coarse(t);
            } else if (root_ != none && t.alive) {
                tile_walk(root_, t.alive, t, stack);
            }
            walk_entered(t, stack);
            test_pending(t);
        }
        for (uint32_t i = 0; i < count; ++i) {
            const bool own_tile = scan_ && (off >> i & 1);
            if ((own_tile && occluded_tile(points, index + i, 1, 1, stack, stats, cache)) ||
                ((alone >> i & 1) && walk_alone(points + size_t(index[i]) * 3, stack, stats)))
                t.shadowed |= uint64_t(1) << i;
        }
        return t.shadowed;
    }

    const double* world_light() const { return world_light_; }

    size_t node_count() const { return planes_.size() + leaves_.size(); }
    // Bytes this tree holds (the asset it reads is not counted).
    size_t memory_bytes() const {
        return planes_.capacity() * sizeof(PlaneNode) + leaves_.capacity() * sizeof(Leaf) +
               (always_fine_.capacity() + always_coarse_.capacity()) * sizeof(uint32_t) +
               own_bounds_.memory_bytes() + coarse_boxes_.capacity() * sizeof(BoxFilter) + coarse_skipped_.capacity();
    }
    size_t always_tested() const { return always_fine_.size(); }
    size_t skipped_clusters() const { return skipped_; }  // one-sided: fine clusters the light sees from the front

private:
    static constexpr uint32_t leaf_bit = 0x80000000u;
    // Sizes (distances, coordinates from the light) below which the float filters cannot overflow: their
    // largest terms are products of four such sizes.
    static constexpr double float_safe = 1e9;
    // And sizes above which their margins stay far above the absolute rounding of results that fall to
    // float's subnormals (1e-45): points nearer the light walk alone (in double), boxes and spheres that lie
    // wholly within this of it are not filtered in float.
    static constexpr double float_tiny = 1e-7;

    struct Range {
        uint32_t first = 0, count = 0;
    };

    // A plane through the light; inside: dot(n, p - light) >= 0.
    struct PlaneNode {          // 32 bytes
        float n[3];             // unit to float precision
        // Every point of every volume in the straddling subtree makes an angle with the plane whose sine is
        // at most this (rounded up); a point farther from the plane skips that subtree.
        float straddle_sine;
        float near_min;         // smallest closing distance below (rounded down)
        uint32_t child[3];      // inside, outside, straddling
    };

    // The end of a volume's chain: its cluster, then the volumes inserted later inside it.
    struct Leaf {               // 32 bytes
        float near = 0;         // closing distance (rounded down)
        float near_min = 0;     // the smaller of near and the closing distances in `inside`
        uint32_t inside = none;
        uint32_t fine_root = none;  // coarse: the root of its fine tree
        uint32_t cluster = none;    // fine: the fine cluster (mesh-local); none for a coarse cluster
        Range always;               // coarse: its fine clusters tested whenever it is entered (a range of
                                    // always_fine_)
        uint32_t first_plane = none;  // the 4 planes of its volume, consecutive (none: no volume)
    };

    static_assert(sizeof(PlaneNode) == 32 && sizeof(Leaf) == 32, "tree nodes are 32-byte records (RUNTIME.md)");
    static_assert(tile_capacity == 64, "a tile's points are the bits of a uint64_t");

    // Nodes while a tree is built (shrink() lays them out for queries).
    struct Nodes {
        std::vector<PlaneNode> planes;
        std::vector<Leaf> leaves;
    };

    // The fine trees of some coarse clusters, built on one thread.
    struct Part {
        Nodes nodes;
        std::vector<uint32_t> always;  // fine clusters without a volume, in ranges per coarse cluster
        size_t skipped = 0;
        uint32_t depth = 0;
    };

public:
    struct BuildScratch {
        Nodes built;               // every node before the walk-order layout
        std::vector<Part> parts;   // per build thread
        std::vector<uint32_t> plane_to, leaf_to, todo;  // the layout's renumbering
        std::vector<uint8_t> part_of;    // which thread built each coarse cluster's fine tree
        std::vector<uint32_t> always;    // always-tested fine clusters, put back in coarse order
        size_t memory_bytes() const {
            size_t b = built.planes.capacity() * sizeof(PlaneNode) + built.leaves.capacity() * sizeof(Leaf) +
                       (plane_to.capacity() + leaf_to.capacity() + todo.capacity() + always.capacity()) * sizeof(uint32_t) +
                       part_of.capacity();
            for (const Part& p : parts)
                b += p.nodes.planes.capacity() * sizeof(PlaneNode) + p.nodes.leaves.capacity() * sizeof(Leaf) +
                     p.always.capacity() * sizeof(uint32_t);
            return b;
        }
    };

private:


    struct Query {
        double p[3], e[3], dist;
        QueryStats* stats;
    };

    // A pyramid from the light that holds the directions of some points, and their distances to the light.
    struct Pyramid {
        alignas(16) float rx[4], ry[4], rz[4];  // unit edge rays (in float): every direction is a positive mix of them
        double dmax;
    };

    // The smallest and largest sine of the pyramid's rays against the plane with normal n (4 at once with SSE).
    static void ray_sines(const float* n, const Pyramid& P, float& smin, float& smax) {
#ifdef CB_SIMD_SSE2
        __m128 s = _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_set1_ps(n[0]), _mm_load_ps(P.rx)), _mm_mul_ps(_mm_set1_ps(n[1]), _mm_load_ps(P.ry))),
                              _mm_mul_ps(_mm_set1_ps(n[2]), _mm_load_ps(P.rz)));
        __m128 swapped = _mm_shuffle_ps(s, s, _MM_SHUFFLE(1, 0, 3, 2));
        __m128 lo = _mm_min_ps(s, swapped), hi = _mm_max_ps(s, swapped);
        smin = _mm_cvtss_f32(_mm_min_ss(lo, _mm_shuffle_ps(lo, lo, _MM_SHUFFLE(2, 3, 0, 1))));
        smax = _mm_cvtss_f32(_mm_max_ss(hi, _mm_shuffle_ps(hi, hi, _MM_SHUFFLE(2, 3, 0, 1))));
#else
        float s[4];
        for (int r = 0; r < 4; ++r) s[r] = n[0] * P.rx[r] + n[1] * P.ry[r] + n[2] * P.rz[r];
        smin = std::min(std::min(s[0], s[1]), std::min(s[2], s[3]));
        smax = std::max(std::max(s[0], s[1]), std::max(s[2], s[3]));
#endif
    }

    // A tile's points in the mesh's frame, and the pyramid from the light that holds their directions.
    struct Tile {
        uint32_t count;
        uint64_t alive;           // in the pyramid and not yet found in shadow
        uint64_t shadowed;
        bool small;               // every live point within float_safe of the light: the float filters apply
        double p[tile_capacity][3], e[tile_capacity][3], dist[tile_capacity];
        alignas(64) float ex[tile_capacity], ey[tile_capacity], ez[tile_capacity], fd[tile_capacity];  // e and dist in float
        alignas(64) float slack[tile_capacity];  // the plane checks' tolerance, 2e-6 of the distance
        alignas(64) float vl[tile_capacity];  // |e|_1 (l1) and a float just above it, for the triangle tests (TileView)
        double l1[tile_capacity], l1_lo, l1_hi;
        double frame[3][3];        // the mean direction from the light and two axes across it (make_frame)
        double across[tile_capacity][2];  // each point's central projection in that frame
        Pyramid pyramid;          // holds the points walking now
        // Fine clusters met by the walk and the points inside their volumes, tested nearest to the light
        // first once the whole walk is done (or the list is full): a point in shadow then usually meets
        // its blocker before the cluster it lies on, and is not tested against that one. (Testing at the
        // end of each coarse cluster instead, so the walk could drop shadowed points sooner, measured
        // slower: blockers often lie in another coarse cluster.)
        struct Pending {
            float near;
            uint32_t cluster;
            uint64_t points;
        };
        static constexpr uint32_t pending_capacity = 128;
        Pending pending[pending_capacity];
        uint32_t pending_count;
        // Coarse clusters entered, likewise: their fine trees are walked nearest first, each one's clusters
        // tested before the next, so that farther ones leave out the points already found in shadow.
        struct Entered {
            float near;
            uint32_t id;  // its cluster node (trees), or the coarse cluster (scan)
            uint64_t points;
        };
        static constexpr uint32_t entered_capacity = 64;
        Entered entered[entered_capacity];
        uint32_t entered_count;
        QueryStats* stats;
        Cache* cache;  // kept between tiles (may be null)
    };

    // The tile's frame: the mean direction z from the light of the points `which` and two unit axes across
    // it, and each point's central projection onto the plane across z at distance 1. Returns the points it
    // holds: all but those over 60 degrees off the mean.
    static uint64_t make_frame(Tile& t, uint64_t which) {
        double m[3] = {0, 0, 0};
        for (uint64_t w = which; w; w &= w - 1) {
            uint32_t i = shadow_detail::lowest_bit(w);
            const double inv = 1 / t.dist[i];
            for (int k = 0; k < 3; ++k) m[k] += t.e[i][k] * inv;
        }
        double ml = std::sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
        if (!(ml > 0)) return 0;
        double *z = t.frame[0], *a = t.frame[1], *b = t.frame[2];
        for (int k = 0; k < 3; ++k) z[k] = m[k] / ml;
        int k0 = std::fabs(z[0]) < std::fabs(z[1]) ? (std::fabs(z[0]) < std::fabs(z[2]) ? 0 : 2) : (std::fabs(z[1]) < std::fabs(z[2]) ? 1 : 2);
        double axis[3] = {0, 0, 0};
        axis[k0] = 1;
        shadow_detail::cross3(z, axis, a);
        double al = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
        for (int k = 0; k < 3; ++k) a[k] /= al;
        shadow_detail::cross3(z, a, b);
        uint64_t held = 0;
        for (uint64_t w = which; w; w &= w - 1) {
            uint32_t i = shadow_detail::lowest_bit(w);
            const double* e = t.e[i];
            double depth = shadow_detail::dot3(e, z);
            if (!(depth > 0.5 * t.dist[i])) continue;  // over 60 degrees off: walks alone
            double inv = 1 / depth;
            t.across[i][0] = shadow_detail::dot3(e, a) * inv, t.across[i][1] = shadow_detail::dot3(e, b) * inv;
            held |= uint64_t(1) << i;
        }
        return held;
    }

    // The pyramid from the light through the rectangle in the tile's frame that bounds the projections of
    // the points `which` (held by the frame).
    static void make_pyramid(const Tile& t, uint64_t which, Pyramid& out) {
        double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
        out.dmax = 0;
        for (uint64_t w = which; w; w &= w - 1) {
            uint32_t i = shadow_detail::lowest_bit(w);
            const double x = t.across[i][0], y = t.across[i][1];
            lo[0] = std::min(lo[0], x), hi[0] = std::max(hi[0], x), lo[1] = std::min(lo[1], y), hi[1] = std::max(hi[1], y);
            out.dmax = std::max(out.dmax, t.dist[i]);
        }
        // Widened far beyond the rounding of x and y (a few 1e-16 for |x|, |y| below 2) and of the rays to
        // float (below 1e-7): the float rays still hold every point's direction.
        for (int k = 0; k < 2; ++k) lo[k] -= 1e-6, hi[k] += 1e-6;
        const double corner[4][2] = {{lo[0], lo[1]}, {hi[0], lo[1]}, {hi[0], hi[1]}, {lo[0], hi[1]}};
        const double *z = t.frame[0], *a = t.frame[1], *b = t.frame[2];
        for (int r = 0; r < 4; ++r) {
            double ray[3], l = 0;
            for (int k = 0; k < 3; ++k) ray[k] = z[k] + corner[r][0] * a[k] + corner[r][1] * b[k], l += ray[k] * ray[k];
            l = std::sqrt(l);
            out.rx[r] = float(ray[0] / l), out.ry[r] = float(ray[1] / l), out.rz[r] = float(ray[2] / l);
        }
    }

    // Refits the tile's pyramid to the points `in` when they are not all its live points (narrower, so fewer
    // fine volumes or spheres meet it); returns the tile's pyramid, to be put back.
    static Pyramid narrow_pyramid(Tile& t, uint64_t in) {
        const Pyramid whole = t.pyramid;
        if (in != t.alive) make_pyramid(t, in, t.pyramid);
        return whole;
    }

    // A coarse cluster's fine tree, walked by the points `in` with the pyramid narrowed to them.
    void walk_fine_tree(uint32_t root, uint64_t in, Tile& t, uint32_t* stack) const {
        const Pyramid whole = narrow_pyramid(t, in);
        tile_walk(root, in, t, stack);
        t.pyramid = whole;
    }

    // The points of `subset` that may lie in the volume of `leaf`: beyond its closing distance and inside
    // its planes with the walk's tolerance plus the float evaluation's error (below 6e-7 of the distance).
    // Bit k of `straddled` is set when plane k may cut the tile's pyramid; the others hold every point.
    // A vector of points an instruction, over the lane groups that hold some of the subset.
    uint64_t volume_points(const Leaf& leaf, uint64_t subset, uint32_t straddled, const Tile& t) const {
        if (!subset) return 0;
        float n[4][3];  // the planes to check
        int planes = 0;
        if (leaf.first_plane != none)
            for (int k = 0; k < 4; ++k) {
                if (!(straddled >> k & 1)) continue;
                const float* from = planes_[leaf.first_plane + k].n;
                n[planes][0] = from[0], n[planes][1] = from[1], n[planes][2] = from[2];
                ++planes;
            }
        uint32_t begin, end;
        simd::lane_span(subset, begin, end);
        const simd::Floats near = simd::splat(leaf.near), zero = simd::splat(0.0f);
        uint64_t in = 0;
        for (uint32_t i = begin; i < end; i += simd::width) {
            if (!simd::group(subset, i)) continue;
            const simd::Floats ex = simd::load(t.ex + i), ey = simd::load(t.ey + i), ez = simd::load(t.ez + i), slack = simd::load(t.slack + i);
            simd::Floats margin = simd::load(t.fd + i) - near;  // >= 0: inside everything checked (a float difference has the exact sign)
            for (int k = 0; k < planes; ++k) margin = simd::min(margin, simd::dot_plus(ex, ey, ez, n[k][0], n[k][1], n[k][2], slack));
            in |= uint64_t(simd::bits(margin >= zero)) << i;
        }
        return in & subset;
    }

    // A box (fine cluster f's, or a coarse cluster's) set up for box_points from this light. The box is taken
    // as the parallelepiped centre + sum of +-padded half[k] axis[k] (cb_asset.h), whose projection on any
    // direction those terms give exactly; the tolerances, 1e-6 of the sizes involved, exceed the float evaluation's errors (below
    // 5e-7 of them) and the axes' departure from orthonormal (2e-7). Not usable where float could overflow
    // (sizes from float_safe up): points are then tested in double.
    BoxFilter box_filter(uint32_t f) const { return box_filter_of(fine_obb(f)); }
    BoxFilter box_filter_of(const Obb& box) const {
        BoxFilter b{};
        double h[3], c[3], a[3][3];
        padded_halves(box, h);
        for (int k = 0; k < 3; ++k) {
            c[k] = double(box.center[k]) - light_[k];
            for (int j = 0; j < 3; ++j) a[k][j] = box.axis[k][j];
        }
        const double hs = h[0] + h[1] + h[2], c1 = std::fabs(c[0]) + std::fabs(c[1]) + std::fabs(c[2]);
        b.usable = c1 + hs < float_safe && c1 + hs > float_tiny;
        if (!b.usable) return b;
        for (int k = 0; k < 3; ++k) {
            double qk = shadow_detail::dot3(c, a[k]), reach = h[k] + 1e-6 * (hs + c1);
            b.lo[k] = float(qk - reach), b.hi[k] = float(qk + reach), b.hf[k] = float(h[k]);
            double wk[3];
            shadow_detail::cross3(a[k], c, wk);
            for (int j = 0; j < 3; ++j) b.w[k][j] = float(wk[j]), b.ax[k][j] = box.axis[k][j];
        }
        b.tol = float(2e-6 * (hs + c1));
        return b;
    }

    // Fine cluster f's box filter from the batch's cache, set up there when it is not yet.
    const BoxFilter& cached_box_filter(uint32_t f, Cache& cache) const {
        const uint32_t slot = f % Cache::box_slots;
        if (cache.box_owner[slot] != this || cache.box_cluster[slot] != f) {
            cache.box[slot] = box_filter(f);
            cache.box_owner[slot] = this, cache.box_cluster[slot] = f;
        }
        return cache.box[slot];
    }

    // The points of `subset` whose segment to the light may touch the box of `b` (usable, and the tile small):
    // separating axis tests in float over the subset's lanes, on the box's 3 axes and on the segment's
    // direction crossed with each.
    uint64_t box_points(const BoxFilter& b, uint64_t subset, const Tile& t) const {
        const float(&lo)[3] = b.lo, (&hi)[3] = b.hi, (&hf)[3] = b.hf, (&w)[3][3] = b.w, (&ax)[3][3] = b.ax;
        const float tol = b.tol;
        uint32_t begin, end;
        simd::lane_span(subset, begin, end);
        uint64_t keep = 0;
        // Per lane, the smallest margin of the 9 checks (>= 0: no separating axis): on box axis k, the segment's
        // shadow [min(0, g), max(0, g)] must meet [lo, hi]; on e x axis k, where the segment projects to 0, the
        // box's centre projects to e . (axis k x c) = e . w[k], and its support is hf[j] |g[m]| + hf[m] |g[j]|.
        using simd::Floats;
        const Floats zero = simd::splat(0.0f), micro = simd::splat(1e-6f), vtol = simd::splat(tol);
        for (uint32_t i = begin; i < end; i += simd::width) {
            if (!simd::group(subset, i)) continue;  // no point in these lanes (the subset is often sparse)
            const Floats ex = simd::load(t.ex + i), ey = simd::load(t.ey + i), ez = simd::load(t.ez + i), d = simd::load(t.fd + i);
            const Floats slack = micro * d;
            const Floats g[3] = {simd::dot(ex, ey, ez, ax[0][0], ax[0][1], ax[0][2]), simd::dot(ex, ey, ez, ax[1][0], ax[1][1], ax[1][2]),
                                 simd::dot(ex, ey, ez, ax[2][0], ax[2][1], ax[2][2])};
            Floats m = simd::splat(INFINITY);
            for (int k = 0; k < 3; ++k) {
                m = simd::min(m, (simd::splat(hi[k]) + slack) - simd::min(g[k], zero));
                m = simd::min(m, (simd::max(g[k], zero) + slack) - simd::splat(lo[k]));
            }
            const Floats a[3] = {simd::abs(g[0]), simd::abs(g[1]), simd::abs(g[2])};
            const Floats td = vtol * d;
            for (int k = 0; k < 3; ++k) {
                const int j = (k + 1) % 3, n = (k + 2) % 3;
                const Floats support = simd::fma(simd::splat(hf[j]), a[n], simd::fma(simd::splat(hf[n]), a[j], td));
                m = simd::min(m, support - simd::abs(simd::dot(ex, ey, ez, w[k][0], w[k][1], w[k][2])));
            }
            keep |= uint64_t(simd::bits(m >= zero)) << i;
        }
        return subset & keep;
    }

    // Tests fine cluster f's triangles for the points of `subset` still alive whose segment may touch its box.
    void test_points(uint32_t f, uint64_t subset, Tile& t) const { test_triangles(f, box_points_of(f, subset & t.alive, t), t); }

    // The points of `subset` whose segment may touch fine cluster f's box.
    uint64_t box_points_of(uint32_t f, uint64_t subset, Tile& t) const {
        if (!view_->fine_bounds.obbs || !subset) return subset;
        BoxFilter own;
        const BoxFilter& b = t.cache ? cached_box_filter(f, *t.cache) : (own = box_filter(f));
        if (b.usable && t.small) return box_points(b, subset, t);
        const Obb box = fine_obb(f);
        for (uint64_t w = subset; w; w &= w - 1) {
            uint32_t i = shadow_detail::lowest_bit(w);
            if (!segment_may_touch_box(box, t.p[i], light_)) subset &= ~(uint64_t(1) << i);
        }
        return subset;
    }

    // Tests fine cluster f's triangles for the points of `subset` still alive.
    void test_triangles(uint32_t f, uint64_t subset, Tile& t) const {
        const uint64_t todo = subset & t.alive;
        if (!todo) return;
        // The tile's pyramid holds every point of `todo`: it is narrowed only while a scan or a fine walk works
        // for some points, and the clusters tested then are those that scan or walk found for them.
        const shadow_detail::TileView tile{t.ex, t.ey, t.ez, t.vl, t.l1, t.l1_lo, t.l1_hi, t.pyramid.rx, t.pyramid.ry, t.pyramid.rz};
        uint64_t hit = cluster_blocks_points(*view_, *mesh_, f, t.p, todo, light_, one_sided_, t.stats, nullptr, t.cache ? &t.cache->lit : nullptr, this, &tile);
        t.alive &= ~hit, t.shadowed |= hit;
    }

    // One point on its own, in double: the tree walk; in scan mode, every sphere (for the points a tile
    // cannot take: beside the light or beyond float's range).
    bool walk_alone(const double* world_p, uint32_t* stack, QueryStats* stats) const {
        if (!usable_ || !finite3(world_p)) return false;
        Query q;
        apply_instance(inverse_, world_p, q.p);
        for (int k = 0; k < 3; ++k) q.e[k] = q.p[k] - light_[k];
        q.dist = std::sqrt(q.e[0] * q.e[0] + q.e[1] * q.e[1] + q.e[2] * q.e[2]);
        q.stats = stats;
        if (scan_) {
            if (!(q.dist > 0)) return false;  // at the light: the segment is a point, which blocks nothing
            const ScanBounds& s = scan_bounds();
            const bool spheres = s.source_fine != nullptr;  // none without fine boxes: every cluster is tested
            for (uint32_t c = 0; c < mesh_->coarse_count; ++c) {
                if ((one_sided_ && coarse_skipped_[c]) || (spheres && !segment_may_touch_sphere(s.coarse_first + c, q))) continue;
                const ClusterRange& r = view_->coarse[mesh_->first_coarse + c];
                for (uint32_t f = r.first; f < r.first + r.count; ++f)
                    if ((!spheres || segment_may_touch_sphere(f, q)) && !skippable_fine(f) && test_cluster(f, q)) return true;
            }
            return false;
        }
        for (uint32_t i = top_always_.first; i < top_always_.first + top_always_.count; ++i)
            if (test_cluster(always_fine_[i], q)) return true;
        for (uint32_t node : always_coarse_)  // coarse clusters around the light, one walk each
            if (walk(node, stack, q)) return true;
        return root_ != none && walk(root_, stack, q);
    }

    // The entered coarse clusters, nearest first: their fine spheres scanned (scan mode), or their
    // always-tested fine clusters then their fine trees; each one's pending clusters are tested before the
    // next coarse cluster's.
    void walk_entered(Tile& t, uint32_t* stack) const {
        Tile::Entered* e = t.entered;
        const uint32_t count = t.entered_count;
        t.entered_count = 0;
        sort_by_near(e, count);
        for (uint32_t i = 0; i < count && t.alive; ++i) {
            uint64_t in = e[i].points & t.alive;
            if (!in) continue;
            if (scan_) {
                const ClusterRange& r = view_->coarse[mesh_->first_coarse + e[i].id];
                scan_fine({r.first, r.count}, in, t);
            } else {
                const Leaf& leaf = leaves_[e[i].id];
                for (uint32_t k = leaf.always.first; k < leaf.always.first + leaf.always.count; ++k) test_points(always_fine_[k], in, t);
                if (leaf.fine_root != none && (in & t.alive)) walk_fine_tree(leaf.fine_root, in & t.alive, t, stack);
            }
            test_pending(t);
        }
    }

    // Sorts by closing distance, ties in list order: each entry goes straight to its rank, the entries before it
    // in that order, counted a vector of keys an instruction (no branch on the keys: an insertion sort
    // mispredicted one per entry). NaN counts as infinity.
    template <class T>
    static void sort_by_near(T* a, uint32_t count) {
        constexpr uint32_t most = 128;  // the longest list (Tile's capacities)
        static_assert(Tile::pending_capacity <= most && Tile::entered_capacity <= most, "lists sort_by_near can sort");
        if (count < 2 || count > most) return;
        alignas(64) float key[most + simd::width];
        for (uint32_t i = 0; i < count; ++i) key[i] = a[i].near == a[i].near ? a[i].near : INFINITY;
        const uint32_t groups = (count + simd::width - 1) / simd::width * simd::width;
        for (uint32_t i = count; i < groups; ++i) key[i] = INFINITY;  // past the end: never before anything
        T sorted[most];
        for (uint32_t i = 0; i < count; ++i) {
            const simd::Floats k = simd::splat(key[i]);
            uint32_t rank = 0;
            for (uint32_t g = 0; g < groups; g += simd::width) {
                const simd::Floats v = simd::load(key + g);
                const uint32_t less = simd::bits(v < k), tied = simd::bits(v <= k) & ~less;
                const uint32_t earlier = i >= g + simd::width ? ~0u : i > g ? (1u << (i - g)) - 1 : 0u;  // lanes before i
                rank += shadow_detail::bit_count(less) + shadow_detail::bit_count(tied & earlier);
            }
            sorted[rank] = a[i];
        }
        std::copy(sorted, sorted + count, a);
    }

    // Tests the pending clusters, nearest closing distance first. A cluster's box is tested three clusters
    // ahead of its triangles, and only when some point may touch it are its triangles and new vertices asked
    // for then, its reused vertices one test ahead (unless its first group is lit already): on large meshes
    // these reads otherwise miss the cache one after another.
    void test_pending(Tile& t) const {
        Tile::Pending* p = t.pending;
        const uint32_t n = t.pending_count;
        sort_by_near(p, n);
        auto ask = [&](uint32_t i, int step) {
            if (t.cache && t.cache->lit.holds(this, p[i].cluster, 0)) return;
            shadow_detail::prefetch_lit(*view_, *mesh_, view_->fine[mesh_->first_fine + p[i].cluster], step);
        };
        auto look = [&](uint32_t i) {  // the box test, into the entry's points
            if (i >= n) return;
            p[i].points = box_points_of(p[i].cluster, p[i].points & t.alive, t);
            if (p[i].points) ask(i, 0);
        };
        look(0), look(1), look(2);
        if (n && p[0].points) ask(0, 1);
        for (uint32_t i = 0; i < n && t.alive; ++i) {
            look(i + 3);
            if (i + 1 < n && (p[i + 1].points & t.alive)) ask(i + 1, 1);
            test_triangles(p[i].cluster, p[i].points, t);
        }
        t.pending_count = 0;
    }

    // The walk of `walk` for a tile's points `subset` at once (see occluded_tile).
    void tile_walk(uint32_t start, uint64_t subset, Tile& t, uint32_t* stack) const {
        size_t top = 0;
        stack[top++] = start;
        // The walk's tolerance (1e-9), and room for the float evaluation (the sines below err by under 4e-7).
        const float tol = 1e-6f;
        const Pyramid& P = t.pyramid;
        while (top && (subset & t.alive)) {
            uint32_t ref = stack[--top];
            // Bit k: the k-th last plane passed on the way down may cut the pyramid (a chain's 4 planes are
            // the last 4 before its cluster node; unknown planes count as cutting).
            uint32_t straddled = 15;
            for (;;) {
                if (t.stats) ++t.stats->nodes_visited;
                if (ref & leaf_bit) {
                    const Leaf& leaf = leaves_[ref & ~leaf_bit];
                    if (P.dmax < leaf.near_min) break;
                    if (leaf.inside != none) stack[top++] = leaf.inside;
                    if (P.dmax < leaf.near) break;
                    // Planes 0..3 of the chain are bits 3..0 of the history.
                    uint32_t chain = (straddled >> 3 & 1) | (straddled >> 1 & 2) | (straddled << 1 & 4) | (straddled << 3 & 8);
                    uint64_t in = volume_points(leaf, subset & t.alive, chain, t);
                    if (!in) break;
                    if (leaf.cluster != none) {
                        if (t.pending_count == Tile::pending_capacity) test_pending(t);
                        t.pending[t.pending_count++] = {leaf.near, leaf.cluster, in};
                    } else {
                        if (t.entered_count == Tile::entered_capacity) walk_entered(t, stack + top);
                        t.entered[t.entered_count++] = {leaf.near, uint32_t(&leaf - leaves_.data()), in};
                    }
                    break;
                }
                const PlaneNode& node = planes_[ref];
                if (P.dmax < node.near_min) break;
                float smin, smax;
                ray_sines(node.n, P, smin, smax);
                // Every point's sine against the plane is at least smin when smin >= 0, at most smax when
                // smax <= 0 (a positive mix of unit rays is no longer than its weights).
                float reach = node.straddle_sine + tol;
                if (node.child[2] != none && !(smin > reach || smax < -reach)) stack[top++] = node.child[2];
                if (smin <= tol && node.child[1] != none) stack[top++] = node.child[1];
                if (smax < -tol || node.child[0] == none) break;
                straddled = (straddled << 1 | (smin > tol ? 0u : 1u)) & 15;
                ref = node.child[0];
            }
        }
    }

    const ScanBounds& scan_bounds() const { return shared_bounds_ ? *shared_bounds_ : own_bounds_; }

    // Fine cluster f's box: decoded already in scan mode (ScanBounds), otherwise from the asset.
    Obb fine_obb(uint32_t f) const {
        return scan_ && !scan_bounds().fine_obbs.empty() ? scan_bounds().fine_obbs[f] : view_->fine_bounds.obb(mesh_->first_fine + f);
    }

    bool skippable_fine(uint32_t f) const {
        if (!one_sided_) return false;
        const FineCluster& r = view_->fine[mesh_->first_fine + f];
        return skippable(view_->fine_bounds, mesh_->first_fine + f, {r.first_triangle, r.triangle_count});
    }

    // Sphere i of scan_bounds() from the light, for the float tests of sphere_points: the centre in
    // float, the radius grown by 2e-5 of itself and of the distance (|d|_1 bounds it), far more than the
    // rounding of the centre to float (below 1e-7 of the distance) and the errors of the float tests (below
    // 1e-6). A sphere wholly within float_tiny of the light holds every point (float products of such sizes
    // could fall to subnormals).
    struct LitSphere {
        float x, y, z, r;
        bool everything;
    };
    LitSphere lit_sphere(uint32_t i) const {
        const ScanBounds& s = scan_bounds();
        const double x = double(s.x[i]) - light_from_origin_[0], y = double(s.y[i]) - light_from_origin_[1], z = double(s.z[i]) - light_from_origin_[2];
        const double d1 = std::fabs(x) + std::fabs(y) + std::fabs(z), r = s.r[i], grown = r + 2e-5 * (r + d1);
        return {float(x), float(y), float(z), float(grown), d1 + grown < float_tiny};
    }

    // Conservative, in double: the segment from the query point to the light may meet sphere i.
    bool segment_may_touch_sphere(uint32_t i, const Query& q) const {
        const ScanBounds& s = scan_bounds();
        const double c[3] = {double(s.x[i]) - light_from_origin_[0], double(s.y[i]) - light_from_origin_[1], double(s.z[i]) - light_from_origin_[2]};
        const double r = s.r[i];
        double t = (c[0] * q.e[0] + c[1] * q.e[1] + c[2] * q.e[2]) / q.dist;
        t = std::min(std::max(t, 0.0), q.dist);
        double d2 = 0;
        for (int k = 0; k < 3; ++k) {
            double x = c[k] - t * q.e[k] / q.dist;
            d2 += x * x;
        }
        double reach = r * (1 + 1e-9) + 1e-9 * (q.dist + shadow_detail::l1(c));
        return d2 <= reach * reach;
    }

    // The points of `subset` whose segment to the light may meet sphere s: the ray from the light passes
    // within the radius (|c x e| <= r |e|) and the sphere is not wholly behind the light or beyond the point.
    // Float, branch-free; the radius holds the float errors (lit_sphere).
    uint64_t sphere_points(const LitSphere& s, uint64_t subset, const Tile& t) const {
        uint32_t begin, end;
        simd::lane_span(subset, begin, end);
        using simd::Floats;
        const Floats x = simd::splat(s.x), y = simd::splat(s.y), z = simd::splat(s.z), r = simd::splat(s.r), r2 = simd::splat(s.r * s.r),
                     zero = simd::splat(0.0f);
        uint64_t keep = 0;
        for (uint32_t i = begin; i < end; i += simd::width) {
            if (!simd::group(subset, i)) continue;
            const Floats ex = simd::load(t.ex + i), ey = simd::load(t.ey + i), ez = simd::load(t.ez + i), d = simd::load(t.fd + i);
            const Floats a = simd::fms(y, ez, z * ey), b = simd::fms(z, ex, x * ez), c = simd::fms(x, ey, y * ex);
            const Floats along = simd::dot(ex, ey, ez, x, y, z), cross2 = simd::dot(a, b, c, a, b, c);
            Floats m = simd::fms(r2 * d, d, cross2);
            m = simd::min(m, simd::fma(r, d, along));
            m = simd::min(m, simd::fms(d + r, d, along));
            keep |= uint64_t(simd::bits(m >= zero)) << i;
        }
        return keep & subset;
    }

    // Asks for fine cluster f's decoded box (scan mode) and record ahead of its test (pending clusters are
    // tested once the whole coarse cluster is scanned): on large meshes these reads otherwise miss the cache.
    void prefetch(uint32_t f) const {
        const std::vector<Obb>& boxes = scan_bounds().fine_obbs;
        if (!boxes.empty()) {
            const char* box = reinterpret_cast<const char*>(&boxes[f]);
            simd::prefetch(box), simd::prefetch(box + sizeof(Obb) - 1);  // it may straddle two lines
        }
        simd::prefetch(view_->fine + size_t(mesh_->first_fine) + f);
    }

    // The scan over spheres [first, first + count) of scan_bounds() for the tile's points `in`: those
    // that may meet the pyramid of these points, nearer the light than the farthest, go to
    // pass(sphere, points, key) with the points whose segment may meet them (every point of `in` when
    // `each_point` is false) and a key that orders them by distance from the light. When the float tests
    // could overflow, every sphere passes with every point.
    //
    // A sphere (centre c from the light, radius r) may meet the pyramid only if it reaches the inside of
    // each side plane, n . c + r >= 0, and of the plane across the tile's axis z at the farthest point's
    // distance, -z . c + r >= -dmax. The centres are stored from the spheres' origin o, so with c = s - l
    // (l the light from o), each test is n . s + r >= n . l (the right side once per scan, in double): a
    // vector of spheres an instruction. The right sides are lowered by 1e-6 of |s|_1 + |l|_1 + dmax, above
    // the float products' errors (3 float epsilons of |s|_1) and the rounding of n (the pyramid's
    // tolerance, which make_pyramid leaves for it).
    template <bool each_point, class Pass>
    void scan_spheres(uint32_t first_sphere, uint32_t count, uint64_t in, Tile& t, Pass pass) const {
        if (!t.small || !spheres_small_) {
            for (uint32_t i = first_sphere; i < first_sphere + count; ++i) pass(i, in, 0.0f);
            return;
        }
        const Pyramid whole = narrow_pyramid(t, in);
        const Pyramid& P = t.pyramid;
        const double* l = light_from_origin_;
        const double slack = 1e-6 * (scan_bounds().extent + shadow_detail::l1(l) + P.dmax);
        float nx[5], ny[5], nz[5], side[5];
        double sum[3] = {0, 0, 0};
        for (int r = 0; r < 4; ++r) sum[0] += P.rx[r], sum[1] += P.ry[r], sum[2] += P.rz[r];
        for (int r = 0; r < 4; ++r) {
            int q = (r + 1) & 3;
            double a[3] = {P.rx[r], P.ry[r], P.rz[r]}, b[3] = {P.rx[q], P.ry[q], P.rz[q]}, n[3];
            shadow_detail::cross3(a, b, n);
            double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            if (shadow_detail::dot3(n, sum) < 0) len = -len;
            if (!(len != 0)) {  // two rays alike: no plane there
                nx[r] = ny[r] = nz[r] = 0, side[r] = -INFINITY;
                continue;
            }
            const double inv = 1 / len;
            nx[r] = float(n[0] * inv), ny[r] = float(n[1] * inv), nz[r] = float(n[2] * inv);
            side[r] = round_down(nx[r] * l[0] + ny[r] * l[1] + nz[r] * l[2] - slack);
        }
        const double* axis = t.frame[0];
        nx[4] = float(-axis[0]), ny[4] = float(-axis[1]), nz[4] = float(-axis[2]);
        side[4] = round_down(nx[4] * l[0] + ny[4] * l[1] + nz[4] * l[2] - P.dmax - slack);
        const float ax = float(axis[0]), ay = float(axis[1]), az = float(axis[2]);
        const ScanBounds& s = scan_bounds();
        const uint32_t stop = first_sphere + count;
        for (uint32_t first = first_sphere; first < stop; first += 64) {
            const uint32_t n = std::min<uint32_t>(64, stop - first);
            const float *x = &s.x[first], *y = &s.y[first], *z = &s.z[first], *rr = &s.r[first];
            uint64_t keep = 0;  // bit j: sphere first + j may meet the pyramid
            for (uint32_t j = 0; j < n; j += simd::width) {  // the arrays are padded past each level's last group
                const simd::Floats cx = simd::loadu(x + j), cy = simd::loadu(y + j), cz = simd::loadu(z + j), r = simd::loadu(rr + j);
                simd::Mask k = simd::dot_plus(cx, cy, cz, nx[4], ny[4], nz[4], r) >= simd::splat(side[4]);
                for (int q = 0; q < 4; ++q) k = k & (simd::dot_plus(cx, cy, cz, nx[q], ny[q], nz[q], r) >= simd::splat(side[q]));
                keep |= uint64_t(simd::bits(k)) << j;
            }
            if (n < 64) keep &= (uint64_t(1) << n) - 1;
            for (; keep; keep &= keep - 1) {
                const uint32_t i = first + shadow_detail::lowest_bit(keep);
                const LitSphere lit = lit_sphere(i);
                const uint64_t points = lit.everything || !each_point ? in : sphere_points(lit, in, t);
                if (points) pass(i, points, lit.x * ax + lit.y * ay + lit.z * az - lit.r);
            }
        }
        t.pyramid = whole;
    }

    // The coarse clusters whose spheres the tile's pyramid may meet, with the points whose segment may meet
    // their boxes (or spheres, where a box's float test could overflow), onto the entered list.
    void scan_coarse(Tile& t) const {
        const uint32_t first = scan_bounds().coarse_first;
        const bool narrow = t.small && spheres_small_;
        scan_spheres<false>(first, mesh_->coarse_count, t.alive, t, [&](uint32_t i, uint64_t points, float key) {
            const uint32_t c = i - first;
            if (one_sided_ && coarse_skipped_[c]) return;
            if (narrow) {
                const BoxFilter& b = coarse_boxes_[c];
                points = b.usable ? box_points(b, points, t) : sphere_points(lit_sphere(i), points, t);
                if (!points) return;
            }
            if (t.entered_count == Tile::entered_capacity) walk_entered(t, nullptr);
            t.entered[t.entered_count++] = {key, c, points};
        });
    }

    // The fine clusters `range` of an entered coarse cluster whose spheres may meet the segments of the
    // points `in`, onto the pending list.
    void scan_fine(Range range, uint64_t in, Tile& t) const {
        scan_spheres<true>(range.first, range.count, in, t, [&](uint32_t f, uint64_t points, float key) {
            if (skippable_fine(f)) return;
            prefetch(f);
            if (t.pending_count == Tile::pending_capacity) test_pending(t);
            t.pending[t.pending_count++] = {key, f, points};
        });
    }

    // The float nearest x on one side (x not NaN).
    static float round_down(double x) {
        const float f = float(x);
        return double(f) > x ? shadow_detail::next_float(f, false) : f;
    }
    static float round_up(double x) {
        const float f = float(x);
        return double(f) < x ? shadow_detail::next_float(f, true) : f;
    }

    static uint32_t add_leaf(Nodes& nodes, const Leaf& leaf) {
        nodes.leaves.push_back(leaf);
        return uint32_t(nodes.leaves.size() - 1) | leaf_bit;
    }

    // Renumbers the nodes in the order a walk meets them (depth first, the inside branch next), so that a
    // query reads mostly consecutive memory, into planes_ and leaves_, sized to what is used.
    void shrink(const Nodes& built, BuildScratch& work) {
        std::vector<uint32_t>&plane_to = work.plane_to, &leaf_to = work.leaf_to, &todo = work.todo;
        plane_to.assign(built.planes.size(), none), leaf_to.assign(built.leaves.size(), none), todo.clear();
        std::vector<PlaneNode>& planes = planes_;
        std::vector<Leaf>& leaves = leaves_;
        planes.clear(), leaves.clear();
        planes.reserve(built.planes.size());
        leaves.reserve(built.leaves.size());
        auto visit = [&](uint32_t start) {
            todo.push_back(start);
            while (!todo.empty()) {
                uint32_t ref = todo.back();
                todo.pop_back();
                if (ref == none) continue;
                if (ref & leaf_bit) {
                    const Leaf& l = built.leaves[ref & ~leaf_bit];
                    leaf_to[ref & ~leaf_bit] = uint32_t(leaves.size());
                    leaves.push_back(l);
                    todo.push_back(l.inside);
                    todo.push_back(l.fine_root);
                } else {
                    const PlaneNode& n = built.planes[ref];
                    plane_to[ref] = uint32_t(planes.size());
                    planes.push_back(n);
                    todo.push_back(n.child[2]);
                    todo.push_back(n.child[1]);
                    todo.push_back(n.child[0]);
                }
            }
        };
        visit(root_);
        for (uint32_t r : always_coarse_) visit(r);
        auto map = [&](uint32_t ref) {
            return ref == none ? none : ref & leaf_bit ? (leaf_to[ref & ~leaf_bit] | leaf_bit) : plane_to[ref];
        };
        for (PlaneNode& n : planes)
            for (uint32_t& c : n.child) c = map(c);
        // A chain's planes stay consecutive: the walk order takes the inside child right after its plane.
        for (Leaf& l : leaves)
            l.inside = map(l.inside), l.fine_root = map(l.fine_root), l.first_plane = l.first_plane == none ? none : plane_to[l.first_plane];
        root_ = map(root_);
        for (uint32_t& r : always_coarse_) r = map(r);
    }

    bool walk(uint32_t start, uint32_t* stack, const Query& q) const {
        size_t top = 0;
        stack[top++] = start;
        while (top) {
            uint32_t ref = stack[--top];
            for (;;) {  // down the inside children directly; the other children wait on the stack
                if (q.stats) ++q.stats->nodes_visited;
                if (ref & leaf_bit) {
                    const Leaf& leaf = leaves_[ref & ~leaf_bit];
                    if (q.dist < leaf.near_min) break;  // nearer the light than everything here
                    if (leaf.inside != none) stack[top++] = leaf.inside;
                    if (q.dist < leaf.near) break;
                    if (leaf.cluster != none) {  // its triangles
                        if (test_cluster(leaf.cluster, q)) return true;
                    } else {  // into its fine tree
                        for (uint32_t i = leaf.always.first; i < leaf.always.first + leaf.always.count; ++i)
                            if (test_cluster(always_fine_[i], q)) return true;
                        if (leaf.fine_root != none) stack[top++] = leaf.fine_root;
                    }
                    break;
                }
                const PlaneNode& node = planes_[ref];
                if (q.dist < node.near_min) break;
                double s = node.n[0] * q.e[0] + node.n[1] * q.e[1] + node.n[2] * q.e[2];
                double tol = 1e-9 * q.dist;  // near the plane: both sides
                if (node.child[2] != none && std::fabs(s) <= (double(node.straddle_sine) + 1e-9) * q.dist)
                    stack[top++] = node.child[2];
                if (s <= tol && node.child[1] != none) stack[top++] = node.child[1];
                if (s < -tol || node.child[0] == none) break;
                ref = node.child[0];
            }
        }
        return false;
    }

    // Insertion order for n items, the same for every build (xorshift with a fixed seed).
    static std::vector<uint32_t> shuffled(uint32_t n) {
        std::vector<uint32_t> order(n);
        for (uint32_t i = 0; i < n; ++i) order[i] = i;
        uint64_t state = 0x9e3779b97f4a7c15ULL;
        for (uint32_t i = n; i > 1; --i) {
            state ^= state << 13, state ^= state >> 7, state ^= state << 17;
            std::swap(order[i - 1], order[state % i]);
        }
        return order;
    }

    Range coarse_triangles(uint32_t c) const {
        const ClusterRange& r = view_->coarse[mesh_->first_coarse + c];
        const FineCluster& a = view_->fine[mesh_->first_fine + r.first];
        const FineCluster& z = view_->fine[mesh_->first_fine + r.first + r.count - 1];
        return {a.first_triangle, z.first_triangle + z.triangle_count - a.first_triangle};
    }

    // One-sided: a cluster the light sees entirely from the front, with no double-sided triangle.
    bool skippable(const LevelBounds& bounds, uint32_t index, Range triangles) const {
        if (!bounds.cones || !light_in_front_cone(bounds.cone(index), light_)) return false;
        for (uint32_t t = triangles.first; t < triangles.first + triangles.count; ++t)
            if (view_->double_sided(size_t(mesh_->first_triangle) + t)) return false;
        return true;
    }

    // The tree over the coarse clusters set in `wanted`, in the shuffled order, into root_; `fill(c, leaf)`
    // says where each one's cluster node leads. A coarse cluster whose box holds the light (or is level
    // with it) gets no volume: its node goes to always_coarse_, entered by every point. Returns the depth.
    template <class Fill>
    uint32_t build_coarse_tree(Nodes& all, const std::vector<uint8_t>& wanted, Fill fill) {
        uint32_t depth = 0;
        for (uint32_t c : shuffled(mesh_->coarse_count)) {
            if (!wanted[c]) continue;
            ShadowVolume v = make_shadow_volume(view_->coarse_bounds.obb(mesh_->first_coarse + c), light_);
            Leaf leaf;
            fill(c, leaf);
            if (!v.valid) {
                leaf.near = leaf.near_min = 0;
                always_coarse_.push_back(add_leaf(all, leaf));
                continue;
            }
            insert(all, root_, v, leaf, depth);
        }
        return depth;
    }

    // A tree over the fine clusters [first, first + count) of the mesh; returns its root. Clusters without
    // a volume go to `always`.
    uint32_t build_fine_tree(Nodes& nodes, uint32_t first, uint32_t count, uint32_t& depth, std::vector<uint32_t>& always,
                             size_t& skipped) const {
        uint32_t root = none;
        for (uint32_t i : shuffled(count)) {
            uint32_t f = first + i;
            const FineCluster& r = view_->fine[mesh_->first_fine + f];
            if (one_sided_ && skippable(view_->fine_bounds, mesh_->first_fine + f, {r.first_triangle, r.triangle_count})) {
                ++skipped;
                continue;
            }
            ShadowVolume v = view_->fine_bounds.obbs ? make_shadow_volume(view_->fine_bounds.obb(mesh_->first_fine + f), light_)
                                                     : ShadowVolume{};
            if (!v.valid) {
                always.push_back(f);
                continue;
            }
            Leaf leaf;
            leaf.cluster = f;
            insert(nodes, root, v, leaf, depth);
        }
        return root;
    }

    // The 4 edge rays of a volume's cone: where pairs of its planes meet.
    static void edge_rays(const ShadowVolume& v, double rays[4][3]) {
        const int pairs[4][2] = {{0, 2}, {2, 1}, {1, 3}, {3, 0}};
        for (int r = 0; r < 4; ++r) {
            const float* a = v.normal[pairs[r][0]];
            const float* b = v.normal[pairs[r][1]];
            double c[3] = {double(a[1]) * b[2] - double(a[2]) * b[1], double(a[2]) * b[0] - double(a[0]) * b[2],
                           double(a[0]) * b[1] - double(a[1]) * b[0]};
            // Orient each ray into the cone: on the inside of the other two planes.
            const float* other = v.normal[pairs[(r + 2) % 4][0]];
            double s = c[0] * other[0] + c[1] * other[1] + c[2] * other[2];
            double len = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
            for (int k = 0; k < 3; ++k) rays[r][k] = (s < 0 ? -c[k] : c[k]) / len;
        }
    }

    // Inserts volume `v` ending in `leaf` into the tree rooted at `root` (a variable outside the arrays).
    static void insert(Nodes& nodes, uint32_t& root, const ShadowVolume& v, Leaf leaf, uint32_t& max_depth) {
        float near = round_down(v.near);
        double rays[4][3];
        edge_rays(v, rays);
        // Every direction in the cone is a positive mix of the rays, whose length is at least `spread` times
        // the mix's weight: |cos| against any plane is at most max over rays / spread.
        double dir[3] = {0, 0, 0};
        for (const double* r : rays)
            for (int k = 0; k < 3; ++k) dir[k] += r[k];
        double dl = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]), spread = 1;
        for (const double* r : rays) spread = std::min(spread, (r[0] * dir[0] + r[1] * dir[1] + r[2] * dir[2]) / dl);
        // The rays in float, to classify 4 at once. Their rounding and the float sines err by under 3e-7,
        // so the thresholds below are 1e-6: a volume goes to one side only when it is clearly there.
        Pyramid cone;
        for (int r = 0; r < 4; ++r) cone.rx[r] = float(rays[r][0]), cone.ry[r] = float(rays[r][1]), cone.rz[r] = float(rays[r][2]);
        // Walk down while the volume falls clearly on one side; stop at the first empty slot, named by the
        // node that holds it (indices, since the appends below may move the arrays).
        uint32_t* slot = &root;
        uint32_t parent = none, depth = 0;
        int which = 0;
        for (uint32_t at = root; at != none;) {
            ++depth;
            parent = at;
            if (at & leaf_bit) {  // past an earlier volume's chain: into its subtree
                Leaf& l = nodes.leaves[at & ~leaf_bit];
                l.near_min = std::min(l.near_min, near);
                which = 0;
                at = l.inside;
                continue;
            }
            PlaneNode& node = nodes.planes[at];
            node.near_min = std::min(node.near_min, near);
            float smin, smax;
            ray_sines(node.n, cone, smin, smax);
            which = smin > 1e-6f ? 0 : smax < -1e-6f ? 1 : 2;
            if (which == 2) {
                double widest = std::max(double(smax), -double(smin)) + 1e-6;
                double sine = spread > 0 ? std::min(1.0, widest / spread + 1e-7) : 1.0;
                node.straddle_sine = std::max(node.straddle_sine, round_up(sine));
            }
            at = node.child[which];
        }
        // The chain: plane 0 -inside-> plane 1 -> plane 2 -> plane 3 -> the leaf.
        uint32_t first = uint32_t(nodes.planes.size());
        for (int k = 0; k < 4; ++k) {
            PlaneNode plane{};
            for (int j = 0; j < 3; ++j) plane.n[j] = v.normal[k][j];
            plane.near_min = near;
            plane.child[0] = first + uint32_t(k) + 1;
            plane.child[1] = plane.child[2] = none;
            nodes.planes.push_back(plane);
        }
        leaf.near = leaf.near_min = near;
        leaf.first_plane = first;
        nodes.planes.back().child[0] = add_leaf(nodes, leaf);
        if (parent == none) *slot = first;
        else if (parent & leaf_bit) nodes.leaves[parent & ~leaf_bit].inside = first;
        else nodes.planes[parent].child[which] = first;
        max_depth = std::max(max_depth, depth + 5);
    }

    // A cluster's triangles, unless the segment certainly misses its box (a volume only says the point
    // is in the box's shadow cone, which a 4-plane outline makes wider than the box).
    bool test_cluster(uint32_t f, const Query& q) const {
        if (view_->fine_bounds.obbs && !segment_may_touch_box(fine_obb(f), q.p, light_))
            return false;
        return cluster_blocks(*view_, *mesh_, f, q.p, light_, one_sided_, q.stats);
    }

    const AssetView* view_ = nullptr;
    const MeshRecord* mesh_ = nullptr;
    double inverse_[12] = {}, light_[3] = {}, world_light_[3] = {};
    bool usable_ = false, one_sided_ = false;
    size_t skipped_ = 0;
    std::vector<PlaneNode> planes_;
    std::vector<Leaf> leaves_;
    std::vector<uint32_t> always_fine_;    // fine clusters tested without a volume (ranges per coarse node)
    // Scan mode: the scan bounds (shared, or the tree's own), the light from their origin, the coarse boxes set up
    // for this light, and which coarse clusters one-sided mode leaves out.
    const ScanBounds* shared_bounds_ = nullptr;
    ScanBounds own_bounds_;
    double light_from_origin_[3] = {};
    std::vector<BoxFilter> coarse_boxes_;
    std::vector<uint8_t> coarse_skipped_;
    bool scan_ = false;
    bool spheres_small_ = false;  // every sphere's coordinates and radius, and the light's, below float_safe
    std::vector<uint32_t> always_coarse_;  // coarse cluster nodes entered for every query
    Range top_always_;                     // one level: the always-tested fine clusters
    uint32_t root_ = none;
    uint32_t depth_ = 0;
};

// The batch form. `trees` holds one tree per instance, all built for the same light; out[i] is 1 when point i
// (xyz doubles) is in shadow. The points are sorted by their direction from the light (cube face, then a
// Z-order curve on it) and walked in tiles of ClusterShadowTree::tile_capacity. `scratch` holds
// batch_scratch_size() words. The trees are const: callers may split the points across threads, each with
// its own scratch. To split one batch across threads, order it once (batch_order) and give each thread
// ranges of that order (occluded_ordered): points close in direction then share tiles, and slices of the
// caller's array would not (a slice of an image is a band of it, whose tiles are narrower and more of them
// meet its edges).
namespace cpsv_detail {

// The batch's stack: room for the deepest of the trees.
inline size_t batch_stack_size(const ClusterShadowTree* trees, size_t tree_count) {
    size_t stack = 0;
    for (size_t t = 0; t < tree_count; ++t) stack = std::max(stack, trees[t].stack_size());
    return stack;
}

}  // namespace cpsv_detail

// Words of scratch batch_order needs for n points (batch_order_from_keys: n fewer).
inline size_t batch_order_scratch_size(size_t n) { return 2 * n + 6144; }

// keys[i - first] for the points [first, last) (xyz doubles): what batch_order sorts them by, their direction
// from `light`, 23 bits: the cube face (3 bits), then the two face coordinates' bits interleaved (10 each), a
// Z-order curve on the face; zero or non-finite directions get the largest key. Threads may each take a part
// of a batch's points. The order only groups points into tiles, never decides an answer, so the keys are made
// in float (a difference beyond float's range rounds to infinity, IEEE 754, and so gets the largest key), with
// selects and a sign bit rather than a comparison that could trap in a branch: GCC then makes 16 keys an
// instruction (65,553 points: 0.09 ms, against 0.34 ms for the scalar loop in double it kept before).
inline void batch_keys(const double* light, const double* points, size_t first, size_t last, uint32_t* keys) {
    const double lx = light[0], ly = light[1], lz = light[2];
    auto spread = [](uint32_t v) {  // bit i of v to bit 2i
        v = (v | v << 8) & 0x00ff00ffu, v = (v | v << 4) & 0x0f0f0f0fu;
        v = (v | v << 2) & 0x33333333u, v = (v | v << 1) & 0x55555555u;
        return v;
    };
    for (size_t i = first; i < last; ++i) {
        const float x = float(points[i * 3] - lx), y = float(points[i * 3 + 1] - ly), z = float(points[i * 3 + 2] - lz);
        const float ax = std::fabs(x), ay = std::fabs(y), az = std::fabs(z);
        const bool on_x = (ax >= ay) & (ax >= az), on_y = !on_x & (ay >= az);  // the major axis m (else z)
        const float major = on_x ? ax : on_y ? ay : az, sign = on_x ? x : on_y ? y : z;
        const float a = on_x ? y : on_y ? z : x, b = on_x ? z : on_y ? x : y;  // axes m + 1 and m + 2 (mod 3)
        const float scale = 511.5f / major;
        float ca = a * scale + 511.5f, cb = b * scale + 511.5f;  // in [0, 1023] to rounding; NaN goes to 0
        ca = ca > 0 ? ca : 0.0f, cb = cb > 0 ? cb : 0.0f;
        ca = ca < 1023.0f ? ca : 1023.0f, cb = cb < 1023.0f ? cb : 1023.0f;
        const uint32_t face = uint32_t(on_x ? 0 : on_y ? 2 : 4) + uint32_t(std::signbit(sign));
        const uint32_t key = face << 20 | spread(uint32_t(int32_t(ca))) | spread(uint32_t(int32_t(cb))) << 1;
        keys[i - first] = (major > 0) & (major < INFINITY) ? key : 0x7fffffu;  // zero or not finite: last
    }
}

// order[0, n): the indices 0..n-1 sorted by keys[0, n) (batch_keys), stably. `scratch` holds
// batch_order_scratch_size(n) - n words.
inline void batch_order_from_keys(const uint32_t* keys, size_t n, uint32_t* order, uint32_t* scratch) {
    // Radix sort, 12 then 11 bits, both counts in one pass. The passes move indices only, the second reading
    // each key through its index: half the bytes written of moving key and index together, and 2-4% off the
    // horse's frames (the keys, just read by the first pass, are mostly still in cache).
    uint32_t *moved = scratch, *low = scratch + n, *high = low + 4096;
    std::fill(low, low + 4096 + 2048, 0u);
    for (size_t i = 0; i < n; ++i) ++low[keys[i] & 4095], ++high[keys[i] >> 12 & 2047];
    auto starts = [](uint32_t* count, int buckets) {
        uint32_t sum = 0;
        for (int b = 0; b < buckets; ++b) sum += count[b], count[b] = sum - count[b];
    };
    starts(low, 4096), starts(high, 2048);
    for (size_t i = 0; i < n; ++i) moved[low[keys[i] & 4095]++] = uint32_t(i);
    for (size_t i = 0; i < n; ++i) order[high[keys[moved[i]] >> 12 & 2047]++] = moved[i];
}

// order[0, n): the indices of the n points (xyz doubles) sorted by direction from `light`, the order
// occluded_batch takes them in: batch_keys then batch_order_from_keys. `scratch` holds
// batch_order_scratch_size(n) words.
inline void batch_order(const double* light, const double* points, size_t n, uint32_t* order, uint32_t* scratch) {
    uint32_t* keys = scratch + n + 6144;  // past what batch_order_from_keys uses
    batch_keys(light, points, 0, n, keys);
    batch_order_from_keys(keys, n, order, scratch);
}

// Words of scratch occluded_ordered needs: the stack and the tables kept from tile to tile.
inline size_t ordered_scratch_size(const ClusterShadowTree* trees, size_t tree_count) {
    const size_t cache = sizeof(ClusterShadowTree::Cache) + alignof(ClusterShadowTree::Cache);
    return cpsv_detail::batch_stack_size(trees, tree_count) + (cache + sizeof(uint32_t) - 1) / sizeof(uint32_t);
}

// The points order[0, count) of `points`, in that order (a range of batch_order's), in tiles: out[order[i]]
// is 1 when that point is in shadow. `scratch` holds ordered_scratch_size() words.
inline void occluded_ordered(const ClusterShadowTree* trees, size_t tree_count, const double* points, const uint32_t* order, size_t count,
                             uint8_t* out, uint32_t* scratch, QueryStats* stats = nullptr) {
    if (tree_count == 0) {
        for (size_t i = 0; i < count; ++i) out[order[i]] = 0;
        return;
    }
    uint32_t* stack = scratch;
    using Cache = ClusterShadowTree::Cache;
    const uintptr_t at = reinterpret_cast<uintptr_t>(stack + cpsv_detail::batch_stack_size(trees, tree_count));
    Cache* cache = new (reinterpret_cast<void*>((at + alignof(Cache) - 1) / alignof(Cache) * alignof(Cache))) Cache;
    cache->clear();
    for (size_t first = 0; first < count; first += ClusterShadowTree::tile_capacity) {
        uint32_t tile = uint32_t(std::min<size_t>(ClusterShadowTree::tile_capacity, count - first));
        // The next tile's points, asked for now: sorted by direction, they lie all over the caller's array.
        for (size_t i = first + tile; i < std::min(count, first + tile + ClusterShadowTree::tile_capacity); ++i)
            simd::prefetch(points + size_t(order[i]) * 3);
        uint64_t alive = tile == 64 ? ~uint64_t(0) : (uint64_t(1) << tile) - 1, shadowed = 0;
        for (size_t t = 0; t < tree_count && alive; ++t) {
            uint64_t s = trees[t].occluded_tile(points, order + first, tile, alive, stack, stats, cache);
            shadowed |= s, alive &= ~s;
        }
        for (uint32_t i = 0; i < tile; ++i) out[order[first + i]] = uint8_t(shadowed >> i & 1);
    }
}

inline size_t batch_scratch_size(const ClusterShadowTree* trees, size_t tree_count, size_t n) {
    return n + std::max(batch_order_scratch_size(n), ordered_scratch_size(trees, tree_count));
}

// batch_order, then occluded_ordered over the whole order.
inline void occluded_batch(const ClusterShadowTree* trees, size_t tree_count, const double* points, size_t n, uint8_t* out,
                           uint32_t* scratch, QueryStats* stats = nullptr) {
    if (tree_count == 0) {
        std::fill(out, out + n, uint8_t(0));
        return;
    }
    uint32_t* order = scratch;
    batch_order(trees[0].world_light(), points, n, order, scratch + n);
    occluded_ordered(trees, tree_count, points, order, n, out, scratch + n, stats);
}

}  // namespace cb
