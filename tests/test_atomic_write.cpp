// cb::write_file_atomic: an output is either the old file or the whole new one, whenever the writer dies,
// and nothing else is left beside it.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include "asset_writer.h"
#include "bake.h"
#include "load.h"

namespace fs = std::filesystem;

namespace {

fs::path fresh_dir(const std::string& name) {
    fs::path d = fs::temp_directory_path() / ("cb_atomic_" + name + "_" + std::to_string(getpid()));
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

std::vector<uint8_t> read_all(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

size_t entries(const fs::path& d) { return size_t(std::distance(fs::directory_iterator(d), fs::directory_iterator())); }

// The default scene (several meshes), and a scene of its first mesh alone: assets of many meshes and of one.
std::vector<cb::Scene> default_scene_and_its_first_mesh() {
    std::vector<cb::Scene> scenes(2);
    scenes[0] = cb::load_scene(std::string(CB_SOURCE_DIR) + "/data/default_scene.glb");
    scenes[1].meshes.push_back(scenes[0].meshes.at(0));
    scenes[1].instances.push_back({0, cb::identity_transform(), "one"});
    return scenes;
}

}  // namespace

TEST(AtomicWrite, KilledWritersLeaveTheOldFileAndNoTemporary) {
    const fs::path d = fresh_dir("kill");
    const fs::path out = d / "scene.cbk";
    const std::vector<uint8_t> old_bytes(1000, 7), new_bytes(size_t(256) << 20, 9);  // 256 MB: seconds to write
    cb::write_file_atomic(out.string(), old_bytes);
    int old_seen = 0, new_seen = 0;
    for (int delay_ms : {5, 20, 60, 150}) {
        const pid_t child = fork();
        ASSERT_GE(child, 0);
        if (child == 0) {
            try {
                cb::write_file_atomic(out.string(), new_bytes);
            } catch (...) {
                _exit(3);
            }
            _exit(0);
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
        kill(child, SIGKILL);
        int status = 0;
        waitpid(child, &status, 0);
        const std::vector<uint8_t> now = read_all(out);
        EXPECT_TRUE(now == old_bytes || now == new_bytes) << "a partial output of " << now.size() << " bytes";
        old_seen += now == old_bytes;
        new_seen += now == new_bytes;
        // Nothing beside the output, or at most the one temporary of a writer killed between naming its
        // file and the rename, which the next write removes.
        EXPECT_LE(entries(d), 2u);
        if (now == new_bytes) cb::write_file_atomic(out.string(), old_bytes);
    }
    EXPECT_GT(old_seen, 0) << "no writer was killed before it finished: the test proves nothing";
    cb::write_file_atomic(out.string(), old_bytes);
    EXPECT_EQ(entries(d), 1u);
    fs::remove_all(d);
}

TEST(AtomicWrite, StaleTemporariesOfDeadWritersAreRemoved) {
    const fs::path d = fresh_dir("stale");
    const fs::path out = d / "scene.cbk";
    // pid_max is at most 2^22: no process has the first id; the second is this process, which is alive.
    const fs::path dead = d / "scene.cbk.tmp4194305", alive = d / ("scene.cbk.tmp" + std::to_string(getpid() + 0));
    const fs::path other = d / "other.cbk.tmp4194305";
    for (const fs::path& p : {dead, other}) std::ofstream(p) << "left over";
    cb::write_file_atomic(out.string(), std::vector<uint8_t>(10, 1));
    EXPECT_FALSE(fs::exists(dead));
    EXPECT_TRUE(fs::exists(other));   // another output's: not ours to remove
    EXPECT_FALSE(fs::exists(alive));  // our own temporary never outlives the call
    EXPECT_EQ(read_all(out), std::vector<uint8_t>(10, 1));
    fs::remove_all(d);
}

// A writer killed in the instant its temporary has a name, and not yet reaped (its parent died with it), is
// dead: its temporary goes.
TEST(AtomicWrite, StaleTemporariesOfUnreapedWritersAreRemoved) {
    const fs::path d = fresh_dir("zombie");
    const fs::path out = d / "scene.cbk";
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) _exit(0);
    // Until it is waited for, the child stays a zombie: kill(pid, 0) still finds it.
    for (int i = 0; i < 1000; ++i) {
        std::ifstream stat("/proc/" + std::to_string(child) + "/stat");
        std::string line;
        std::getline(stat, line);
        if (line.find(") Z") != std::string::npos) break;
        usleep(1000);
    }
    const fs::path left = d / ("scene.cbk.tmp" + std::to_string(child));
    std::ofstream(left) << "half an asset";
    cb::write_file_atomic(out.string(), std::vector<uint8_t>(10, 1));
    EXPECT_FALSE(fs::exists(left));
    EXPECT_EQ(read_all(out), std::vector<uint8_t>(10, 1));
    int status = 0;
    EXPECT_EQ(waitpid(child, &status, 0), child);
    fs::remove_all(d);
}

TEST(AtomicWrite, RefusesToReplaceWhatIsNotARegularFile) {
    const fs::path d = fresh_dir("special");
    const fs::path fifo = d / "pipe", folder = d / "folder";
    ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
    fs::create_directories(folder);
    for (const fs::path& p : {fifo, folder, fs::path("/dev/null")}) {
        try {
            cb::write_file_atomic(p.string(), std::vector<uint8_t>(4, 0));
            ADD_FAILURE() << p << " was replaced";
        } catch (const std::runtime_error& e) {
            EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos) << e.what();
        }
    }
    struct stat st;
    ASSERT_EQ(stat("/dev/null", &st), 0);
    EXPECT_TRUE(S_ISCHR(st.st_mode));
    EXPECT_TRUE(fs::is_fifo(fifo));
    EXPECT_TRUE(fs::is_directory(folder));
    fs::remove_all(d);
}

// write_asset streams the asset to its file (a second thread writing while the checksum is summed): the
// file must hold encode_asset's bytes exactly, for one mesh and many, with and without a source section,
// and the meshes' geometry is freed once encoded.
TEST(AtomicWrite, StreamedAssetEqualsTheEncodedOne) {
    const fs::path d = fresh_dir("stream");
    const std::vector<cb::Scene> scenes = default_scene_and_its_first_mesh();
    ASSERT_GT(scenes[0].meshes.size(), 1u);
    for (const cb::Scene& s : scenes) {
        cb::BakeStats stats;
        std::vector<cb::AssetMesh> meshes = cb::cluster_scene(s, {}, stats);
        cb::BoundsOptions bounds;
        bounds.mask = cb::bounds_auto;
        cb::fit_scene_bounds(meshes, bounds, 2, stats);
        for (const std::string source : {"", "made by a test\n"}) {
            const std::vector<uint8_t> encoded = cb::encode_asset(meshes, s.instances, source);
            for (unsigned threads : {1u, 2u}) {
                std::vector<cb::AssetMesh> copy = meshes;
                const fs::path out = d / ("asset" + std::to_string(threads) + ".cbk");
                EXPECT_EQ(cb::write_asset(out.string(), copy, cb::encode_geometry(copy), s.instances, source, threads),
                          encoded.size());
                EXPECT_EQ(read_all(out), encoded) << s.meshes.size() << " meshes, " << threads << " threads";
                for (const cb::AssetMesh& m : copy) EXPECT_EQ(m.positions.capacity() + m.triangles.capacity(), 0u);
            }
        }
    }
    EXPECT_EQ(entries(d), 2u);  // the two outputs, no temporary
    fs::remove_all(d);
}

// An asset of 8 MB or more goes to its file by direct writes from an aligned buffer (where the filesystem
// takes them): a rolling grid whose asset is about 11 MB, so that the buffer fills and is written more than
// once, the volumes follow the geometry's last bytes in it, and the last block is cut to the file's size. The file
// holds encode_asset's bytes exactly, with its checksum, on one thread and two, and an output it replaces
// stays as it was until the writer finishes.
TEST(AtomicWrite, LargeAssetWrittenDirectlyEqualsTheEncodedOne) {
    const fs::path d = fresh_dir("direct");
    cb::Scene s;
    cb::Mesh grid;
    grid.name = "rolling grid";
    const uint32_t side = 601;  // vertices a side: 720,000 triangles
    for (uint32_t j = 0; j < side; ++j)
        for (uint32_t i = 0; i < side; ++i)
            for (float c : {float(i), float(j), 3.0f * std::sin(0.05f * float(i)) * std::cos(0.07f * float(j))})
                grid.positions.push_back(c);
    for (uint32_t j = 0; j + 1 < side; ++j)
        for (uint32_t i = 0; i + 1 < side; ++i) {
            const uint32_t v = j * side + i;
            for (uint32_t c : {v, v + 1, v + side, v + 1, v + side + 1, v + side}) grid.indices.push_back(c);
        }
    s.meshes.push_back(grid);
    s.instances.push_back({0, cb::identity_transform(), "grid"});
    cb::BakeStats stats;
    const std::vector<cb::AssetMesh> clustered = cb::cluster_scene(s, {}, stats);
    cb::BoundsOptions bounds;
    bounds.mask = cb::bounds_auto;
    std::vector<cb::AssetMesh> fitted = clustered;
    cb::fit_scene_bounds(fitted, bounds, 2, stats);
    const std::string source = "made by a test\n";
    const std::vector<uint8_t> encoded = cb::encode_asset(fitted, s.instances, source);
    ASSERT_GE(encoded.size(), size_t(8) << 20);
    ASSERT_NE(encoded.size() % 4096, 0u);  // a last block to cut
    const fs::path out = d / "grid.cbk";
    const std::vector<uint8_t> old_bytes(5000, 4);
    for (unsigned threads : {1u, 2u}) {
        cb::write_file_atomic(out.string(), old_bytes);
        std::vector<cb::AssetMesh> meshes = clustered;
        cb::size_scene_bounds(meshes, bounds);
        cb::AssetWriter writer(out.string(), meshes, cb::encode_geometry(meshes), s.instances, source);
        cb::fit_scene_bounds(meshes, bounds, threads, stats);
        EXPECT_EQ(read_all(out), old_bytes);
        EXPECT_EQ(writer.finish(meshes, threads), encoded.size());
        const std::vector<uint8_t> written = read_all(out);
        EXPECT_EQ(written.size(), encoded.size());
        EXPECT_TRUE(written == encoded) << threads << " threads";
        EXPECT_EQ(entries(d), 1u);
    }
    fs::remove_all(d);
}

// AssetWriter writes the geometry before the volumes are fitted (their arrays only sized) and the rest once
// they are: the file holds the asset of the filled meshes exactly, for one mesh and many; the old output
// stays as it was until finish(), and a writer dropped before it leaves the old output and nothing else.
TEST(AtomicWrite, GeometryWrittenBeforeTheVolumesAreFitted) {
    const fs::path d = fresh_dir("early");
    const std::vector<cb::Scene> scenes = default_scene_and_its_first_mesh();
    ASSERT_GT(scenes[0].meshes.size(), 1u);
    cb::BoundsOptions bounds;
    bounds.mask = cb::bounds_all;
    const fs::path out = d / "asset.cbk";
    const std::vector<uint8_t> old_bytes(100, 3);
    for (const cb::Scene& s : scenes) {
        cb::BakeStats stats;
        const std::vector<cb::AssetMesh> clustered = cb::cluster_scene(s, {}, stats);
        std::vector<cb::AssetMesh> fitted = clustered;
        cb::fit_scene_bounds(fitted, bounds, 2, stats);
        const std::vector<uint8_t> encoded = cb::encode_asset(fitted, s.instances, "source\n");
        for (bool finished : {false, true}) {
            cb::write_file_atomic(out.string(), old_bytes);
            std::vector<cb::AssetMesh> meshes = clustered;
            cb::size_scene_bounds(meshes, bounds);
            const cb::AssetMesh* where = meshes.data();
            const void* fine_boxes = meshes[0].fine_volumes.obbs.data();
            {
                cb::AssetWriter writer(out.string(), meshes, cb::encode_geometry(meshes), s.instances, "source\n");
                cb::fit_scene_bounds(meshes, bounds, 2, stats);
                EXPECT_EQ(meshes.data(), where);
                EXPECT_EQ(meshes[0].fine_volumes.obbs.data(), fine_boxes);  // sized once, filled in place
                EXPECT_EQ(read_all(out), old_bytes);
                if (finished) {
                    EXPECT_EQ(writer.finish(meshes, 2), encoded.size());
                }
            }
            EXPECT_EQ(read_all(out), finished ? encoded : old_bytes) << s.meshes.size() << " meshes";
            EXPECT_EQ(entries(d), 1u);  // no temporary either way
        }
    }
    fs::remove_all(d);
}
