// glTF as pipelines write it: scenes run through gltfpack and glTF-Transform (pinned in tests/node, installed
// by scripts/install-deps.sh) with their common options, each output loaded, compared with the original
// and baked. The scenes: a generated city of 50 buildings (mirrored ones among them) and five shared
// glTF scenes; a tool that is not installed, or a shared scene that is absent, skips visibly.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <unordered_map>
#include <vector>

#include <unistd.h>

#include "city.h"
#include "gltf_writer.h"
#include "load.h"
#include "scene_info.h"

namespace fs = std::filesystem;

namespace {

const std::string node_bin = std::string(CB_SOURCE_DIR) + "/tests/node/node_modules/.bin/";

// How an output's world positions are expected to relate to its original's.
enum class Positions {
    exact,      // the file's floats and transforms kept: equal to double rounding
    baked,      // transforms applied to the floats, or stored as floats: within float rounding of the extent
    quantized,  // positions quantized to `bits`: within one quantization step of the world extent
};

// What the output keeps of the original's instances.
enum class Instances {
    all,     // every instance (of the same meshes): the original's count
    shared,  // every instance of a mesh that several instances share; meshes used once may be merged
    any,     // the tool merges meshes into one (join)
};

struct ToolRun {
    std::string name;  // as the test prints it: "gltfpack -c", "gltf-transform meshopt"
    std::string tool;  // gltfpack or gltf-transform
    std::vector<std::string> args;
    Positions positions;
    Instances instances;
    bool gpu_instancing = false;  // shared meshes' instances come from EXT_mesh_gpu_instancing
    bool meshopt = false;         // the output's views are EXT_meshopt_compression streams
};

constexpr int position_bits = 14;  // gltfpack's default, and glTF-Transform's quantize, meshopt and draco

// gltfpack merges the meshes that one node each uses into one, flattening their nodes, makes identical
// meshes one, and keeps the ones several nodes share instanced (with -mi, through EXT_mesh_gpu_instancing
// when the nodes are siblings); it quantizes every mesh on one grid, in the mesh's frame. glTF-Transform's
// instance batches the sibling nodes of a mesh used at least 5 times (--min) into one node with the
// extension, their transforms stored as float accessors; its flatten and join compose transforms in float,
// join merging meshes into world space; its quantize and meshopt quantize each mesh in its own box.
const std::vector<ToolRun>& tool_runs() {
    static const std::vector<ToolRun> runs = {
        {"gltfpack", "gltfpack", {}, Positions::quantized, Instances::shared},
        {"gltfpack -c", "gltfpack", {"-c"}, Positions::quantized, Instances::shared, false, true},
        {"gltfpack -cc", "gltfpack", {"-cc"}, Positions::quantized, Instances::shared, false, true},
        {"gltfpack -mi", "gltfpack", {"-mi"}, Positions::quantized, Instances::shared, true},
        {"gltfpack -noq", "gltfpack", {"-noq"}, Positions::baked, Instances::shared},
        {"gltf-transform meshopt", "gltf-transform", {"meshopt"}, Positions::quantized, Instances::all, false, true},
        {"gltf-transform instance", "gltf-transform", {"instance"}, Positions::baked, Instances::all},
        {"gltf-transform instance --min 2",
         "gltf-transform",
         {"instance", "--min", "2"},
         Positions::baked,
         Instances::all,
         true},
        {"gltf-transform draco", "gltf-transform", {"draco"}, Positions::quantized, Instances::all},
        {"gltf-transform quantize", "gltf-transform", {"quantize"}, Positions::quantized, Instances::all},
        {"gltf-transform weld", "gltf-transform", {"weld"}, Positions::exact, Instances::all},
        {"gltf-transform join", "gltf-transform", {"join"}, Positions::baked, Instances::any},
        {"gltf-transform flatten", "gltf-transform", {"flatten"}, Positions::baked, Instances::all},
    };
    return runs;
}

// The instances whose mesh other instances use too.
uint64_t shared_instances(const cb::Scene& s) {
    std::vector<uint64_t> uses(s.meshes.size(), 0);
    for (const cb::Instance& inst : s.instances) ++uses[inst.mesh];
    uint64_t n = 0;
    for (uint64_t u : uses) n += u > 1 ? u : 0;
    return n;
}

std::string quoted(const std::string& s) { return "'" + s + "'"; }

// Runs a command with its output into `log`; returns its exit status.
int run(const std::string& command, const fs::path& log) {
    const int status = std::system((command + " >" + quoted(log.string()) + " 2>&1").c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string read_text(const fs::path& p) {
    std::ifstream in(p);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Every in-scene triangle corner in world space, in double, and the scale of its instance (the longest
// column of its transform's linear part): a mesh quantized in its own frame is as coarse in the world as its
// instance magnifies it.
struct Corners {
    std::vector<std::array<double, 3>> at;
    std::vector<double> scale;
};

Corners world_corners(const cb::Scene& s) {
    Corners out;
    for (const cb::Instance& inst : s.instances) {
        const cb::Mesh& m = s.meshes[inst.mesh];
        double scale = 0;
        for (int c = 0; c < 3; ++c)
            scale = std::max(scale, std::hypot(inst.world[c * 4], inst.world[c * 4 + 1], inst.world[c * 4 + 2]));
        for (uint32_t i : m.indices) {
            const float* p = &m.positions[size_t(i) * 3];
            out.at.push_back(cb::transform_point(inst.world, p[0], p[1], p[2]));
            out.scale.push_back(scale);
        }
    }
    return out;
}

// The worst, over the points of `a`, of the distance (the largest coordinate difference) to the nearest
// point of `b` divided by the tolerance of that pair, `tolerance(i, j)` for a[i] and b[j]; found in a grid of
// cells of `cell`, which must exceed every tolerance. A point with nothing within `cell` makes it infinite.
// `distance` gets the largest of those nearest distances.
template <class Tolerance>
double worst_ratio(const std::vector<std::array<double, 3>>& a, const std::vector<std::array<double, 3>>& b,
                   double cell, Tolerance tolerance, double& distance) {
    auto key = [cell](double x, double y, double z) {
        const int64_t i = int64_t(std::floor(x / cell)), j = int64_t(std::floor(y / cell)),
                      k = int64_t(std::floor(z / cell));
        return (uint64_t(i) * 73856093u) ^ (uint64_t(j) * 19349663u) ^ (uint64_t(k) * 83492791u);
    };
    std::unordered_multimap<uint64_t, size_t> grid;
    grid.reserve(b.size());
    for (size_t i = 0; i < b.size(); ++i) grid.emplace(key(b[i][0], b[i][1], b[i][2]), i);
    double worst = 0;
    distance = 0;
    for (size_t i = 0; i < a.size(); ++i) {
        const auto& p = a[i];
        double best = HUGE_VAL, nearest = HUGE_VAL;
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dz = -1; dz <= 1; ++dz) {
                    auto range = grid.equal_range(key(p[0] + dx * cell, p[1] + dy * cell, p[2] + dz * cell));
                    for (auto it = range.first; it != range.second; ++it) {
                        const auto& q = b[it->second];
                        const double d =
                            std::max({std::fabs(p[0] - q[0]), std::fabs(p[1] - q[1]), std::fabs(p[2] - q[2])});
                        best = std::min(best, d / tolerance(i, it->second));
                        nearest = std::min(nearest, d);
                    }
                }
        worst = std::max(worst, best);
        distance = std::max(distance, nearest);
    }
    return worst;
}

// The generated city as a GLB: the ground and 20 building meshes, 50 building nodes placed by matrices
// (a yaw, every seventh mirrored), all siblings, as a level editor exports them.
fs::path write_city(const fs::path& dir) {
    const cb::Scene city = cb::generate::city(50);
    cb::data::GltfWriter w;
    for (const cb::Mesh& m : city.meshes) w.mesh(m.name, {m.positions, m.indices}, -1);
    std::vector<int> roots;
    for (const cb::Instance& inst : city.instances)
        roots.push_back(w.node({{"mesh", inst.mesh}, {"name", inst.node_name}, {"matrix", inst.world}}));
    w.doc["scenes"] = cb::data::json::array({{{"nodes", roots}}});
    w.doc["scene"] = 0;
    const std::vector<uint8_t> bytes = w.glb();
    const fs::path path = dir / "city.glb";
    std::ofstream(path, std::ios::binary)
        .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    return path;
}

bool uses(const cb::Scene& s, const std::string& extension) {
    for (const cb::ExtensionUse& e : s.report.extensions)
        if (e.name == extension) return e.status == cb::ExtensionUse::Status::applied;
    return false;
}

// Runs every tool option over `input` and checks each output against the original.
void check_tools(const std::string& label, const fs::path& input, bool siblings = false) {
    for (const char* tool : {"gltfpack", "gltf-transform"})
        if (!fs::exists(node_bin + tool))
            GTEST_SKIP() << tool << " is not installed in tests/node (bash scripts/install-deps.sh)";
    // One folder per process: the suite without shared data runs this binary beside ctest's own runs.
    const fs::path work = fs::path(CB_TEST_WORK) / (label + "." + std::to_string(getpid()));
    fs::remove_all(work);
    fs::create_directories(work);
    const cb::Scene original = cb::load_scene(input.string());
    const cb::SceneInfo before = cb::describe(original);
    const Corners original_corners = world_corners(original);
    double extent = 0;
    for (int k = 0; k < 3; ++k) extent = std::max(extent, before.world_max[k] - before.world_min[k]);
    double grid_extent = extent;
    for (const cb::Mesh& m : original.meshes)
        for (int k = 0; k < 3; ++k) {
            float lo = HUGE_VALF, hi = -HUGE_VALF;
            for (size_t v = 0; v < m.vertex_count(); ++v) {
                lo = std::min(lo, m.positions[v * 3 + k]);
                hi = std::max(hi, m.positions[v * 3 + k]);
            }
            if (m.vertex_count()) grid_extent = std::max(grid_extent, double(hi) - double(lo));
        }
    const uint64_t shared = shared_instances(original);

    for (const ToolRun& t : tool_runs()) {
        SCOPED_TRACE(label + ": " + t.name);
        std::string slug = t.name;
        std::replace(slug.begin(), slug.end(), ' ', '_');
        const fs::path out = work / (slug + ".glb"), log = work / (slug + ".log");
        std::string command = node_bin + t.tool;
        if (t.tool == "gltfpack") {
            command += " -i " + quoted(input.string()) + " -o " + quoted(out.string());
            for (const std::string& a : t.args) command += " " + a;
        } else {
            command += " " + t.args[0] + " " + quoted(input.string()) + " " + quoted(out.string());
            for (size_t i = 1; i < t.args.size(); ++i) command += " " + t.args[i];
        }
        ASSERT_EQ(run(command, log), 0) << command << "\n" << read_text(log);

        cb::Scene s;
        try {
            s = cb::load_scene(out.string());
        } catch (const cb::LoadError& e) {
            ADD_FAILURE() << "refused: " << e.what();
            continue;
        }
        const cb::SceneInfo after = cb::describe(s);
        EXPECT_TRUE(after.warnings.empty()) << after.warnings.front();
        EXPECT_EQ(after.scene_triangles, before.scene_triangles);
        if (t.instances == Instances::all) EXPECT_EQ(after.instances, before.instances);
        if (t.instances == Instances::shared) EXPECT_GE(shared_instances(s), shared);
        if (t.meshopt) {
            EXPECT_TRUE(uses(s, "EXT_meshopt_compression"));
            EXPECT_GT(after.meshopt_views, 0u);
        }
        // Where the shared meshes' instances are siblings (the city), every one comes from the extension.
        if (t.gpu_instancing) EXPECT_EQ(after.gpu_instances, siblings ? shared : after.gpu_instances);
        if (t.gpu_instancing && siblings) EXPECT_GT(after.instanced_nodes, 0u);

        // World positions: every corner of the output near a corner of the original, and back.
        // Tolerances: double rounding where nothing changed; float rounding of the world coordinates where
        // the tool applied or stored transforms in float; where quantized, a step of the grid over the
        // scene's extent (or a mesh's own, were it larger), magnified by the instance's scale.
        const double magnitude = extent +
            std::max({std::fabs(before.world_min[0]), std::fabs(before.world_min[1]), std::fabs(before.world_min[2]),
                      std::fabs(before.world_max[0]), std::fabs(before.world_max[1]), std::fabs(before.world_max[2])});
        const double rounding = t.positions == Positions::exact ? 1e-9 * extent : std::ldexp(magnitude, -20);
        const double step = t.positions == Positions::quantized ? grid_extent / ((1 << position_bits) - 1) : 0;
        auto tolerance = [&](size_t original) {
            return rounding + step * std::max(1.0, original_corners.scale[original]);
        };
        double largest = 0;
        for (size_t i = 0; i < original_corners.at.size(); ++i) largest = std::max(largest, tolerance(i));
        const Corners corners = world_corners(s);
        const double cell = 4 * largest;
        double away_distance, missed_distance;
        const double away = worst_ratio(
            corners.at, original_corners.at, cell, [&](size_t, size_t original) { return tolerance(original); },
            away_distance);
        const double missed = worst_ratio(
            original_corners.at, corners.at, cell, [&](size_t original, size_t) { return tolerance(original); },
            missed_distance);
        EXPECT_LE(away, 1.0) << "an output corner is away from every original one, by up to " << away_distance;
        EXPECT_LE(missed, 1.0) << "an original corner is missing from the output, by up to " << missed_distance;
        std::printf(
            "%-24s %-24s triangles %6llu/%-6llu instances %4llu/%-4llu shared %4llu/%-4llu meshopt views %3llu, "
            "gpu instances %4llu, world error %.3g (%.2f of its tolerance)\n",
            label.c_str(), t.name.c_str(), (unsigned long long)after.scene_triangles,
            (unsigned long long)before.scene_triangles, (unsigned long long)after.instances,
            (unsigned long long)before.instances, (unsigned long long)shared_instances(s), (unsigned long long)shared,
            (unsigned long long)after.meshopt_views, (unsigned long long)after.gpu_instances,
            std::max(away_distance, missed_distance), std::max(away, missed));

        // And it bakes into an asset that validates.
        const fs::path asset = work / (slug + ".cbk");
        EXPECT_EQ(run(std::string(CB_CLI) + " bake " + quoted(out.string()) + " -o " + quoted(asset.string()) + " -q",
                      work / (slug + ".bake.log")),
                  0)
            << read_text(work / (slug + ".bake.log"));
        EXPECT_EQ(run(std::string(CB_CLI) + " validate " + quoted(asset.string()), work / (slug + ".validate.log")), 0)
            << read_text(work / (slug + ".validate.log"));
    }
    if (!::testing::Test::HasFailure()) fs::remove_all(work);
}

}  // namespace

TEST(GltfTools, GeneratedCity) {
    const fs::path dir = fs::path(CB_TEST_WORK) / ("city_input." + std::to_string(getpid()));
    fs::create_directories(dir);
    check_tools("city", write_city(dir), true);
}

class GltfToolsShared : public ::testing::TestWithParam<const char*> {};

TEST_P(GltfToolsShared, Scene) {
    const fs::path input = fs::path(CB_SHARED_DATA) / GetParam();
    if (!fs::exists(input)) GTEST_SKIP() << input << " is absent (no shared scenes beside the checkout)";
    std::string label = fs::path(GetParam()).stem().string();
    check_tools(label, input);
}

// Five of the shared glTF scenes: node hierarchies, a mesh instanced by two nodes, scaled instances,
// several meshes and primitives, a textured mesh. The skinned ones are left out (the tools pose them
// differently), and so is many-cubes, whose 501 meshes make each tool run take seconds.
INSTANTIATE_TEST_SUITE_P(Shared, GltfToolsShared,
                         ::testing::Values("gltf/CesiumMilkTruck/CesiumMilkTruck.gltf",
                                           "gltf/SpheresScaledInstances/spheres_scaled_instances.gltf",
                                           "gltf/TestScene/TestScene.gltf", "gltf/Duck.glb", "gltf/nested.glb"),
                         [](const ::testing::TestParamInfo<const char*>& info) {
                             std::string name = fs::path(info.param).stem().string();
                             for (char& c : name)
                                 if (!std::isalnum(uint8_t(c))) c = '_';
                             return name;
                         });
