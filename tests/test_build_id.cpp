// The build id: written into every source section and shown by --version; an output another build wrote (an
// asset the library's own writer makes with another build id in its source section, or with none) is baked
// again by bake_file, `bake --if-changed` and `batch`, and one this build wrote is kept.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include "asset_decode.h"
#include "asset_file.h"
#include "asset_writer.h"
#include "bake_file.h"

namespace fs = std::filesystem;

namespace {

struct CliResult {
    int code = -1;
    std::string out, err;
};

std::string read(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// `args` to the command line under test, its output captured in files of this process's own.
CliResult run(const std::string& args) {
    static int calls = 0;
    const fs::path base =
        fs::temp_directory_path() / ("cb_build_id_" + std::to_string(getpid()) + "_" + std::to_string(calls++));
    const std::string out = base.string() + ".out", err = base.string() + ".err";
    const int status = std::system((CB_CLI + " " + args + " >" + out + " 2>" + err).c_str());
    CliResult r;
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = read(out);
    r.err = read(err);
    fs::remove(out);
    fs::remove(err);
    return r;
}

fs::path fresh_dir(const std::string& name) {
    fs::path d = fs::temp_directory_path() / ("cb_build_id_" + name + "_" + std::to_string(getpid()));
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

std::string source_of(const fs::path& asset_path) {
    cb::LoadedAsset asset;
    std::string error;
    EXPECT_TRUE(cb::read_asset_file(asset_path.string(), asset, error)) << error;
    return asset.view.source ? std::string(asset.view.source, asset.view.source_size) : std::string();
}

// The asset at `path` written again by the library's writer (checksum and all), its source section's first
// line replaced by `line`: what another build of the tool, or one that records no build, would have left.
void rewrite_first_line(const fs::path& path, const std::string& line) {
    cb::LoadedAsset asset;
    std::string error;
    ASSERT_TRUE(cb::read_asset_file(path.string(), asset, error)) << error;
    const std::string source(asset.view.source, asset.view.source_size);
    const cb::BakedScene scene = cb::baked_scene_from_asset(asset.view);
    // The writer gives back the very bytes it read when the source is kept: only line 1 differs below.
    ASSERT_EQ(cb::encode_asset(scene.meshes, scene.instances, source),
              std::vector<uint8_t>(asset.data(), asset.data() + asset.size));
    const std::string other = line + source.substr(source.find('\n'));
    cb::write_file_atomic(path.string(), cb::encode_asset(scene.meshes, scene.instances, other));
    ASSERT_EQ(source_of(path), other);
}

const std::string cube = std::string(CB_SOURCE_DIR) + "/data/small/cube.obj";

// Line 1 as another build of this version writes it, and as a writer that records no build does.
std::vector<std::string> other_first_lines() {
    const std::string tool = std::string(cb::tool_version()) + ", asset format " + std::to_string(cb::asset_version);
    std::string other = cb::build_id();
    other[0] = other[0] == '0' ? '1' : '0';
    return {tool + ", build " + other, tool};
}

}  // namespace

TEST(BuildId, IsInEverySourceSectionAndInVersion) {
    const std::string id = cb::build_id();
    ASSERT_EQ(id.size(), 16u);
    EXPECT_EQ(id.find_first_not_of("0123456789abcdef"), std::string::npos) << id;
    const fs::path d = fresh_dir("names");
    cb::BakeRequest r;
    r.input = cube;
    r.output = (d / "cube.cbk").string();
    ASSERT_EQ(cb::bake_file(r).status, cb::BakeStatus::baked);
    EXPECT_EQ(source_of(r.output).rfind(std::string(cb::tool_version()) + ", asset format 4, build " + id + "\n", 0),
              0u)
        << source_of(r.output);
    // The command line is built from the same tree: its --version and its assets name the same build.
    const CliResult version = run("--version");
    ASSERT_EQ(version.code, 0);
    EXPECT_NE(version.out.find("(asset format 4, build " + id + ", "), std::string::npos) << version.out;
    ASSERT_EQ(run("bake " + cube + " -o " + (d / "cli.cbk").string() + " -q").code, 0);
    EXPECT_EQ(read(d / "cli.cbk"), read(r.output));
    fs::remove_all(d);
}

TEST(BuildId, BakeFileRebakesAnotherBuildsOutput) {
    const fs::path d = fresh_dir("bake_file");
    cb::BakeRequest r;
    r.input = cube;
    r.output = (d / "cube.cbk").string();
    r.if_changed = true;
    ASSERT_EQ(cb::bake_file(r).status, cb::BakeStatus::baked);
    const std::string ours = read(r.output);
    ASSERT_EQ(cb::bake_file(r).status, cb::BakeStatus::up_to_date);
    for (const std::string& line : other_first_lines()) {
        SCOPED_TRACE(line);
        rewrite_first_line(r.output, line);
        EXPECT_EQ(run("validate " + r.output).code, 0) << "a valid asset, only made by another build";
        EXPECT_EQ(cb::bake_file(r).status, cb::BakeStatus::baked);
        EXPECT_EQ(read(r.output), ours);
        EXPECT_EQ(cb::bake_file(r).status, cb::BakeStatus::up_to_date);
    }
    fs::remove_all(d);
}

TEST(BuildId, CommandLineBakeIfChangedRebakesAnotherBuildsOutput) {
    const fs::path d = fresh_dir("cli");
    const std::string out = (d / "cube.cbk").string(), bake = "bake " + cube + " -o " + out + " --if-changed --json";
    auto status = [&] {
        const CliResult r = run(bake);
        EXPECT_EQ(r.code, 0) << r.err;
        return r.code == 0 ? nlohmann::json::parse(r.out)["status"].get<std::string>() : r.err;
    };
    EXPECT_EQ(status(), "baked");
    const std::string ours = read(out);
    EXPECT_EQ(status(), "up-to-date");
    for (const std::string& line : other_first_lines()) {
        SCOPED_TRACE(line);
        rewrite_first_line(out, line);
        EXPECT_EQ(status(), "baked");
        EXPECT_EQ(read(out), ours);
        EXPECT_EQ(status(), "up-to-date");
    }
    fs::remove_all(d);
}

TEST(BuildId, BatchRebakesOnlyAnotherBuildsOutputs) {
    const fs::path d = fresh_dir("batch");
    fs::create_directories(d / "in");
    for (const char* f : {"cube.obj", "cube_binary.ply", "cube_ascii.stl"})
        fs::copy_file(fs::path(CB_SOURCE_DIR) / "data/small" / f, d / "in" / f);
    const std::string batch = "batch " + (d / "in").string() + " -o " + (d / "out").string() + " -j 2 --json -q";
    auto statuses = [&] {
        const CliResult r = run(batch);
        EXPECT_EQ(r.code, 0) << r.err;
        std::map<std::string, std::string> s;
        if (r.code != 0) return s;
        const nlohmann::json summary = nlohmann::json::parse(r.out);  // kept: the loop reads into it
        for (const nlohmann::json& f : summary["files"]) s[f["name"]] = f["status"];
        return s;
    };
    std::map<std::string, std::string> first = statuses();
    ASSERT_EQ(first.size(), 3u);
    for (const auto& [name, s] : first) EXPECT_EQ(s, "baked") << name;
    const fs::path obj = d / "out" / "cube.cbk";  // cube.obj's output
    ASSERT_TRUE(fs::exists(obj));
    const std::string ours = read(obj);
    for (const std::string& line : other_first_lines()) {
        SCOPED_TRACE(line);
        rewrite_first_line(obj, line);
        for (const auto& [name, s] : statuses()) EXPECT_EQ(s, name == "cube.obj" ? "baked" : "up-to-date") << name;
        EXPECT_EQ(read(obj), ours);
        for (const auto& [name, s] : statuses()) EXPECT_EQ(s, "up-to-date") << name;
    }
    fs::remove_all(d);
}
