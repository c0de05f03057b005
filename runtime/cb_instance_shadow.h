// Shadow queries of point lights (and suns, below) over the asset's two-level cluster hierarchy, after the
// thesis's clustered partitioned shadow volumes (CPSV, chapter 2): for one light, find the few clusters whose
// shadow volume may hold a point and test only their triangles, exactly (cb_lit_triangles.h), so that the answers are
// those of occluded_reference (cb_shadow.h), faster. InstanceShadow holds one traversal, chosen at build
// time by ShadowBuildOptions::traversal, and forwards the query interface to it:
//
// - cb_scan.h, Traversal::scan (the default): no tree; the clusters' bounding spheres (cb_scan_bounds.h,
//   made once per asset) are scanned against each tile's pyramid from the light.
// - cb_top_tree.h, Traversal::top_two and Traversal::top_one: the thesis's ternary trees of planes through
//   the light over the clusters' shadow volumes, built per light.
// - cb_metric_tree.h, Traversal::mtsv_one and Traversal::mtsv_two: the thesis's second structure, ternary metric
//   trees over the cones and capsule-cones of the clusters' spheres and capsules, by angle from the light.
// - cb_sun.h, a sun (a light at infinity, given by its direction; build_sun): every volume is a prism along
//   the direction. Traversal::scan scans the clusters' spheres against each tile's prism; the others walk
//   trees across the direction built per sun (cb_sun_trees.h): lines over the boxes' prisms for top_two and
//   top_one, discs of the spheres for mtsv_one and mtsv_two.
// - cb_tile.h: what they share (the instance's frame, the tile of points, the box filters, the cluster
//   tests); cb_batch.h: batches of points, sorted by direction and taken in tiles.
//
// A new traversal is one more header with a class on TraversalBase, one more Traversal value and one more
// case in InstanceShadow::build and visit. Building allocates (std::vector; a BuildScratch lets rebuilds
// reuse memory); queries do not: occluded() takes a stack of stack_size() entries, occluded_batch a scratch
// of batch_scratch_size() words. Header-only C++17, no exceptions. MIT licensed (runtime/LICENSE).
#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>
#include <variant>

#include "cb_asset.h"
#include "cb_batch.h"
#include "detail/cb_metric_tree.h"
#include "detail/cb_scan.h"
#include "detail/cb_sun.h"
#include "cb_scan_bounds.h"
#include "cb_segment.h"
#include "detail/cb_tile.h"
#include "detail/cb_top_tree.h"

namespace cb {
inline namespace CB_LANES {

class InstanceShadow {
public:
    static constexpr uint32_t none = TraversalBase::none;

    // One instance of the asset's meshes, for one light given in world space (ShadowBuildOptions says how).
    // Without coarse boxes in the asset, every traversal is one tree.
    void build(const AssetView& view, uint32_t instance, const double* world_light,
               const ShadowBuildOptions& options = {}) {
        build(view, placement_of(view, instance), world_light, options);
    }

    // The same for a mesh of the asset placed by the caller (a level's instance, cb_level.h).
    void build(const AssetView& view, Placement at, const double* world_light, const ShadowBuildOptions& options = {}) {
        sun_ = false;
        traversal_ =
            options.traversal == Traversal::scan && !view.coarse_bounds.obbs ? Traversal::top_one : options.traversal;
        switch (traversal_) {
            case Traversal::scan: return build_as<ScanTraversal>(view, at, world_light, options);
            case Traversal::top_two:
            case Traversal::top_one: return build_as<TopTreeTraversal>(view, at, world_light, options);
            case Traversal::mtsv_one:
            case Traversal::mtsv_two: return build_as<MetricTreeTraversal>(view, at, world_light, options);
        }
    }

    // One instance for a sun, given by `toward`, its world direction from the scene toward it (cb_segment.h,
    // "A sun"): SunTraversal (cb_sun.h), which finds the clusters as options.traversal names.
    void build_sun(const AssetView& view, uint32_t instance, const double* toward,
                   const ShadowBuildOptions& options = {}) {
        build_sun(view, placement_of(view, instance), toward, options);
    }
    void build_sun(const AssetView& view, Placement at, const double* toward, const ShadowBuildOptions& options = {}) {
        sun_ = true;
        traversal_ = options.traversal;
        build_as<SunTraversal>(view, at, toward, options);
    }

    // The traversal built (for a point light, Traversal::top_one where the asset has no coarse boxes).
    Traversal traversal() const { return traversal_; }
    // Built for a sun: world_light() is then the direction toward it.
    bool sun() const { return sun_; }

    // Entries the query stack needs.
    size_t stack_size() const {
        return visit([](const auto& t) { return t.stack_size(); });
    }

    // True when the segment from world point p to the light is blocked by this instance. `stack` holds
    // stack_size() entries. A batch (occluded_batch) is far faster per point.
    bool occluded(const double* world_p, uint32_t* stack, QueryStats* stats = nullptr) const {
        return visit([&](const auto& t) { return t.occluded(world_p, stack, stats); });
    }

    // Of the `count` world points points + 3 * index[i] (xyz doubles), those set in `alive` that this
    // instance shadows, as a mask (at most tile_capacity points); the same answers as occluded() point by
    // point. `stack` holds stack_size() entries; `cache` (may be null) keeps set-ups between tiles from the
    // same light, cleared when the traversals change.
    uint64_t occluded_tile(const double* points, const uint32_t* index, uint32_t count, uint64_t alive, uint32_t* stack,
                           QueryStats* stats = nullptr, TileCache* cache = nullptr) const {
        return visit([&](const auto& t) { return t.occluded_tile(points, index, count, alive, stack, stats, cache); });
    }

    const double* world_light() const {
        return visit([](const auto& t) { return t.world_light(); });
    }
    size_t node_count() const {
        return visit([](const auto& t) { return t.node_count(); });
    }
    // Bytes the traversal holds (the asset, and ScanBounds shared through the options, are not counted).
    size_t memory_bytes() const {
        return visit([](const auto& t) { return t.memory_bytes(); });
    }
    size_t always_tested() const {  // fine clusters without a volume, tested whenever their coarse one is entered
        return visit([](const auto& t) { return t.always_tested(); });
    }
    size_t skipped_clusters() const {  // one-sided: fine clusters the light sees from the front
        return visit([](const auto& t) { return t.skipped_clusters(); });
    }
    size_t capsules() const {  // metric trees: volumes taken as capsule-cones
        return visit([](const auto& t) { return t.capsules(); });
    }

private:
    template <class T>
    void build_as(const AssetView& view, Placement at, const double* world_light, const ShadowBuildOptions& options) {
        if (!std::holds_alternative<T>(held_)) held_.template emplace<T>();  // same type: its arrays are reused
        std::get_if<T>(&held_)->build(view, at, world_light, options);
    }

    // f(the traversal held): one switch per call, then direct, inlinable calls.
    template <class F>
    auto visit(F f) const -> decltype(f(std::declval<const ScanTraversal&>())) {
        if (sun_) return f(*std::get_if<SunTraversal>(&held_));
        switch (traversal_) {
            case Traversal::scan: return f(*std::get_if<ScanTraversal>(&held_));
            case Traversal::mtsv_one:
            case Traversal::mtsv_two: return f(*std::get_if<MetricTreeTraversal>(&held_));
            case Traversal::top_two:
            case Traversal::top_one: break;
        }
        return f(*std::get_if<TopTreeTraversal>(&held_));
    }

    Traversal traversal_ = Traversal::scan;
    bool sun_ = false;
    std::variant<ScanTraversal, TopTreeTraversal, MetricTreeTraversal, SunTraversal> held_;
};

}  // namespace CB_LANES
}  // namespace cb
