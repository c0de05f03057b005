// Every mesh file in ../shared/data loads with the counts its README states, or fails the way it predicts.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <set>
#include <fstream>
#include <regex>
#include <sstream>

#include "load.h"
#include "scene_info.h"

namespace fs = std::filesystem;

namespace {

struct ReadmeRow {
    std::string path;
    uint64_t unique = 0, in_scene = 0;
    long long degenerate = -1;  // -1: the README states none
    std::string notes;
};

uint64_t parse_count(const std::string& s) {
    std::string digits;
    for (char c : s)
        if (std::isdigit(static_cast<unsigned char>(c))) digits += c;
    return digits.empty() ? 0 : std::stoull(digits);
}

// Rows of the README's tables: | `path` | size | triangles | source | licence | shape facts | notes |
std::vector<ReadmeRow> readme_rows(const fs::path& readme) {
    std::ifstream in(readme);
    std::vector<ReadmeRow> rows;
    std::string line;
    std::regex row_re(R"(^\| `([^`]+)` \| [^|]* \| ([^|]*) \|[^|]*\|[^|]*\| ([^|]*) \| ([^|]*) \|)");
    std::regex scene_re(R"(([\d,]+) unique / ([\d,]+) in scene)");
    std::regex degenerate_re(R"((\d+) degenerate)");
    std::smatch m;
    while (std::getline(in, line)) {
        if (!std::regex_search(line, m, row_re)) continue;
        ReadmeRow row;
        row.path = m[1];
        std::string tris = m[2], facts = m[3];
        row.notes = m[4];
        if (tris.find_first_of("0123456789") == std::string::npos) continue;  // a buffer or texture
        std::smatch s;
        if (std::regex_search(tris, s, scene_re)) {
            row.unique = parse_count(s[1]);
            row.in_scene = parse_count(s[2]);
        } else {
            row.unique = row.in_scene = parse_count(tris);
        }
        if (std::regex_search(facts, s, degenerate_re)) row.degenerate = std::stoll(s[1]);
        rows.push_back(row);
    }
    return rows;
}

bool is_mesh_file(const fs::path& p) { return cb::format_from_path(p.string()) != cb::FileFormat::unknown; }

fs::path shared_data() { return fs::path(CB_SHARED_DATA); }

}  // namespace

TEST(SharedData, EveryFileLoadsWithReadmeCounts) {
    if (!fs::exists(shared_data() / "README.md")) GTEST_SKIP() << "../shared/data is absent: real-data tests skipped";
    std::vector<ReadmeRow> rows = readme_rows(shared_data() / "README.md");
    ASSERT_GE(rows.size(), 30u) << "README table parsing broke";

    std::set<std::string> listed;
    for (const ReadmeRow& row : rows) {
        listed.insert(row.path);
        fs::path file = shared_data() / row.path;
        SCOPED_TRACE(row.path);
        ASSERT_TRUE(fs::exists(file));
        // The README marks inf/NaN coordinates as an invalid-input test: loading must refuse the file.
        bool predicted_invalid = row.notes.find("invalid input") != std::string::npos;
        if (predicted_invalid) {
            try {
                cb::load_scene(file.string());
                ADD_FAILURE() << "loaded a file the README calls invalid";
            } catch (const cb::LoadError& e) {
                std::string what = e.what();
                EXPECT_NE(what.find(file.string()), std::string::npos) << what;
                EXPECT_NE(what.find("not a finite"), std::string::npos) << what;
                EXPECT_EQ(what.find('\n'), std::string::npos) << "error must be one line";
            }
            continue;
        }
        cb::Scene scene = cb::load_scene(file.string());
        cb::SceneInfo info = cb::describe(scene);
        EXPECT_EQ(info.unique_triangles, row.unique);
        EXPECT_EQ(info.scene_triangles, row.in_scene);
        // The README counts degenerate triangles in double from the file's text; we count them on the stored
        // float32 positions, relative to the mesh's centre. They agree except where rounding to float moves
        // an exactly collinear vertex off its line: one of the 3dfier terrain's needle triangles. The README
        // also counts a polygon's triangles as its fan, whose zero-area triangles (at collinear vertices) the
        // loader's triangulation avoids: a file with polygons may have fewer.
        if (row.degenerate >= 0) {
            if (info.polygons.total > 0) {
                EXPECT_LE(info.degenerate_triangles, uint64_t(row.degenerate));
            } else if (row.path.find("3dfier") == std::string::npos) {
                EXPECT_EQ(info.degenerate_triangles, uint64_t(row.degenerate));
            } else {
                EXPECT_LE(info.degenerate_triangles, uint64_t(row.degenerate));
            }
        }
    }
    // Every mesh file on disk is covered by a README row, so no file escapes the test.
    for (const auto& e : fs::recursive_directory_iterator(shared_data()))
        if (e.is_regular_file() && is_mesh_file(e.path())) {
            EXPECT_TRUE(listed.count(fs::relative(e.path(), shared_data()).string())) << e.path();
        }
}

TEST(SharedData, DracoMilkTruckMatchesOriginal) {
    fs::path plain = shared_data() / "gltf/CesiumMilkTruck/CesiumMilkTruck.gltf";
    fs::path draco = shared_data() / "gltf/CesiumMilkTruck_draco.glb";
    if (!fs::exists(plain) || !fs::exists(draco)) GTEST_SKIP() << "../shared/data is absent";
    cb::Scene a = cb::load_scene(plain.string()), b = cb::load_scene(draco.string());
    EXPECT_EQ(b.report.draco_primitives, 4u);
    ASSERT_EQ(a.meshes.size(), b.meshes.size());
    ASSERT_EQ(a.instances.size(), b.instances.size());
    for (size_t i = 0; i < a.instances.size(); ++i) {
        EXPECT_EQ(a.instances[i].mesh, b.instances[i].mesh);
        EXPECT_EQ(a.instances[i].node_name, b.instances[i].node_name);
        for (int k = 0; k < 16; ++k) EXPECT_DOUBLE_EQ(a.instances[i].world[k], b.instances[i].world[k]);
    }
    for (size_t m = 0; m < a.meshes.size(); ++m) {
        const cb::Mesh &ma = a.meshes[m], &mb = b.meshes[m];
        SCOPED_TRACE("mesh " + std::to_string(m));
        EXPECT_EQ(ma.triangle_count(), mb.triangle_count());
        ASSERT_EQ(ma.primitives.size(), mb.primitives.size());
        for (size_t p = 0; p < ma.primitives.size(); ++p)
            EXPECT_EQ(ma.primitives[p].triangle_count, mb.primitives[p].triangle_count);
        // Draco quantised positions to 11 bits over the mesh's bounds (gltf-pipeline's default): every
        // decoded vertex lies within one quantisation step of an original vertex, per axis, and back.
        float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
        for (size_t i = 0; i < ma.positions.size(); ++i) {
            lo[i % 3] = std::min(lo[i % 3], ma.positions[i]);
            hi[i % 3] = std::max(hi[i % 3], ma.positions[i]);
        }
        float range = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
        float step = range / float((1 << 11) - 1);
        auto nearest_gap = [](const cb::Mesh& from, size_t v, const cb::Mesh& to) {
            float best = 1e30f;
            for (size_t w = 0; w < to.vertex_count(); ++w) {
                float d = 0;
                for (int k = 0; k < 3; ++k)
                    d = std::max(d, std::fabs(from.positions[v * 3 + k] - to.positions[w * 3 + k]));
                best = std::min(best, d);
            }
            return best;
        };
        float worst = 0;
        for (size_t v = 0; v < mb.vertex_count(); ++v) worst = std::max(worst, nearest_gap(mb, v, ma));
        for (size_t v = 0; v < ma.vertex_count(); ++v) worst = std::max(worst, nearest_gap(ma, v, mb));
        EXPECT_LE(worst, step) << "quantisation step " << step;
        EXPECT_GT(worst, 0.0f) << "Draco positions should be quantised, not identical";
    }
}
