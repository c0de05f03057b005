// The speed-against-error report: every configuration of a sweep (method x fine size x box fitter) baked
// in memory, timed (median of runs), measured for tightness (box volumes, sampled shadow-volume
// conservativeness) and for runtime cost through the runtime's query API on camera-visible points; written
// as a self-contained HTML page (inline SVG plots, no scripts), JSON and CSV.
#pragma once

#include <nlohmann/json.hpp>

#include <functional>
#include <string>
#include <vector>

#include "bounds.h"
#include "cluster.h"
#include "cluster_stats.h"
#include "load.h"
#include "scene.h"
#include "scene_query.h"

namespace cb {

struct ReportOptions {
    std::vector<ClusterMethod> methods = {ClusterMethod::kmeans, ClusterMethod::vco, ClusterMethod::morton};
    std::vector<uint32_t> fine_sizes = {8, 16, 24, 32};
    std::vector<ObbMethod> obbs = {ObbMethod::refined, ObbMethod::pca};
    // How the runtime finds the clusters (cb::Traversal): each one a configuration of its own. A metric tree
    // (mtsv, mtsv_two) reads an asset baked with its spheres, capsules and slabs too.
    std::vector<Traversal> traversals = {Traversal::scan, Traversal::mtsv_one};
    uint32_t coarse_size = 2048;
    int runs = 3;        // bake timings are the median of this many runs
    int query_runs = 7;  // runtime timings: the median of this many rounds over every configuration
    double memory_budget = 2.0 * (1u << 30);  // bytes of assets held for the rounds; past it, one at a time
    uint32_t view = 128;                      // the camera's resolution; its first hits are the query points
    uint32_t frame_view = 1024;  // frame time is for this resolution: build + its visible points / queries per second
    uint32_t lights = 2;         // fixed light positions around the scene (report_lights)
    uint32_t suns = 0;           // fixed sun directions (report_suns), measured beside the lights
    bool one_sided = false;      // query mode
    LoadOptions load;            // what the scene files are trusted with (docs/SECURITY.md)
    StatsOptions stats{4, 8};    // lights and samples of the shadow-volume conservativeness
    unsigned threads = 0;        // bake threads (queries run on one thread)
    bool heatmap = false;        // per scene, the useless-tests heat map (k-means beside VCO) embedded in the HTML
    uint32_t heatmap_size = 256;
};

struct ConfigResult {
    ClusterMethod method;
    uint32_t fine_size;
    ObbMethod obb;
    Traversal traversal = Traversal::scan;
    uint64_t fine_clusters = 0, coarse_clusters = 0;
    double cluster_seconds = 0, fit_seconds = 0;  // medians
    double bytes_per_triangle = 0;                // the asset as io/asset_writer encodes it, boxes and cones
    double obb_volume_relative = 0;               // fine boxes over the scene box
    double useless_share = 0;                     // sampled, fine level (cluster_stats.h)
    double build_seconds = 0;                     // per light (lights and suns alike), all instances
    double queries_per_second = 0;
    double nodes_per_query = 0, clusters_per_query = 0, useless_per_query = 0, triangles_per_query = 0;
    double shadowed_share = 0;
    double frame_seconds = 0;  // one light's build plus a query per visible point of a frame_view frame
    double bake_seconds() const { return cluster_seconds + fit_seconds; }
    std::string name() const;  // e.g. "kmeans/16/refined", "kmeans/16/refined/mtsv"
};

struct SceneReport {
    std::string file, name;
    uint64_t triangles = 0, instances = 0, points = 0;
    std::vector<double> lights, suns;
    std::vector<ConfigResult> configs;
    std::vector<uint8_t> heatmap_png;  // empty unless asked for
    uint32_t heatmap_width = 0, heatmap_height = 0;
    std::string heatmap_caption;
};

struct Report {
    ReportOptions options;
    std::string cpu;
    unsigned cores = 0;
    std::vector<SceneReport> scenes;
    // The default it recommends: the lowest geometric-mean frame time over the scenes, each scene's frame
    // times divided by its best; within 3% of that, the smallest asset, then the shortest bake.
    std::string recommended, recommendation_reason;
};

// Progress messages go to `progress` when set. Throws std::runtime_error naming a file that does not load.
Report run_report(const std::vector<std::string>& files, const ReportOptions& options,
                  const std::function<void(const std::string&)>& progress = {});

std::string report_html(const Report& r);
nlohmann::json report_json(const Report& r);
std::string report_csv(const Report& r);
std::string report_table(const Report& r);  // the text table `clusterbake report` prints

// Writes DIR/report.html, report.json, report.csv (each atomically) and, with heat maps,
// DIR/heatmap-<scene>.png. Creates DIR.
void write_report(const Report& r, const std::string& dir);

// The CPU model from /proc/cpuinfo ("unknown" elsewhere).
std::string cpu_model();

}  // namespace cb
