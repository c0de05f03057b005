// The clusterbake executable: exit codes, one-line errors, JSON output.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cb_asset.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sys/wait.h>
#include <unistd.h>

#include "gltf_writer.h"

namespace {

struct CliRun {
    int code = -1;
    std::string out, err;
};

// `args` to clusterbake; with `pipe_from`, that shell command's output is its standard input.
CliRun run(const std::string& args, const std::string& pipe_from = "") {
    // ctest runs tests in parallel processes: name the capture files after this one.
    static int calls = 0;
    auto base =
        std::filesystem::temp_directory_path() / ("cb_cli_" + std::to_string(getpid()) + "_" + std::to_string(calls++));
    std::string out = base.string() + ".out", err = base.string() + ".err";
    std::string cmd = (pipe_from.empty() ? "" : pipe_from + " | ") + CB_CLI + " " + args + " >" + out + " 2>" + err;
    int status = std::system(cmd.c_str());
    CliRun r;
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    auto slurp = [](const std::string& p) {
        std::ifstream in(p);
        return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    };
    r.out = slurp(out);
    r.err = slurp(err);
    std::filesystem::remove(out);
    std::filesystem::remove(err);
    return r;
}

std::string data(const std::string& f) { return std::string(CB_SOURCE_DIR) + "/data/" + f; }

}  // namespace

TEST(Cli, InfoOnTheDefaultScene) {
    CliRun r = run("info " + data("default_scene.glb"));
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("instances 12"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("load time"), std::string::npos);
}

TEST(Cli, InfoJson) {
    CliRun r = run("info --json " + data("small/cube.obj") + " " + data("small/cube_binary.stl"));
    ASSERT_EQ(r.code, 0) << r.err;
    auto j = nlohmann::json::parse(r.out);
    ASSERT_EQ(j.size(), 2u);
    EXPECT_EQ(j[0]["unique_triangles"], 12);
    EXPECT_EQ(j[1]["scene_triangles"], 12);
    EXPECT_EQ(j[0]["world_bounds"]["max"][0], 1.0);
    EXPECT_TRUE(j[0].contains("load_ms"));
}

TEST(Cli, BadInputGivesOneLineAndExitCode2) {
    auto bad = std::filesystem::temp_directory_path() / ("cb_cli_bad_" + std::to_string(getpid()) + ".obj");
    std::ofstream(bad) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 70000\n";
    CliRun r = run("info " + bad.string());
    EXPECT_EQ(r.code, 2);
    EXPECT_EQ(r.err, bad.string() + ": line 4: face index 70000 out of range (3 vertices)\n");
    EXPECT_TRUE(r.out.empty());

    CliRun missing = run("info /nonexistent/scene.gltf");
    EXPECT_EQ(missing.code, 2);
    EXPECT_EQ(missing.err.rfind("/nonexistent/scene.gltf: cannot open", 0), 0u) << missing.err;

    CliRun unknown = run("info " + std::string(CB_SOURCE_DIR) + "/README.md");
    EXPECT_EQ(unknown.code, 2);
    EXPECT_NE(unknown.err.find("unknown file type"), std::string::npos);
    std::filesystem::remove(bad);
}

TEST(Cli, GoodAndBadFilesTogether) {
    // Every good file is still reported; the exit code says something failed.
    CliRun r = run("info " + data("small/cube.off") + " /nonexistent.obj");
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.out.find("cube.off"), std::string::npos);
}

TEST(Cli, Help) {
    EXPECT_EQ(run("--help").code, 0);
    CliRun r = run("info --help");
    EXPECT_EQ(r.code, 0);
    EXPECT_NE(r.out.find("--json"), std::string::npos);
    EXPECT_NE(run("").code, 0);  // a subcommand is required
}

TEST(Cli, ClusterWritesAValidAssetAndJson) {
    auto out = std::filesystem::temp_directory_path() / ("cb_cli_" + std::to_string(getpid()) + ".cbk");
    CliRun r = run("cluster " + data("default_scene.glb") + " --method vco --fine 24 -o " + out.string() + " --json");
    ASSERT_EQ(r.code, 0) << r.err;
    auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["method"], "vco");
    EXPECT_EQ(j["triangles"], 33952);  // each mesh once, however often it is instanced
    EXPECT_LE(j["fine_max"].get<int>(), 24);
    EXPECT_LT(j["acmr_after"].get<double>(), j["acmr_before"].get<double>());
    CliRun v = run("validate " + out.string());
    EXPECT_EQ(v.code, 0) << v.err;
    EXPECT_NE(v.out.find("instances 12"), std::string::npos) << v.out;
    std::filesystem::remove(out);
}

TEST(Cli, FailedClusterLeavesTheOutputUntouched) {
    auto dir = std::filesystem::temp_directory_path();
    auto out = dir / ("cb_cli_keep_" + std::to_string(getpid()) + ".cbk");
    auto bad = dir / ("cb_cli_bad_" + std::to_string(getpid()) + ".off");
    std::ofstream(out) << "previous contents";
    std::ofstream(bad) << "OFF\n3 1 0\n0 0 0\n1 0 0\n";
    CliRun r = run("cluster " + bad.string() + " -o " + out.string());
    EXPECT_EQ(r.code, 2);
    EXPECT_EQ(r.err, bad.string() + ": truncated: 2 of 3 vertices\n");
    std::ifstream in(out);
    EXPECT_EQ(std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>()), "previous contents");
    CliRun v = run("validate " + out.string());
    EXPECT_EQ(v.code, 2);
    EXPECT_NE(v.err.find("too small"), std::string::npos) << v.err;
    EXPECT_EQ(run("cluster " + data("small/cube.obj") + " --method nonsense -o " + out.string()).code, 2);
    std::filesystem::remove(out);
    std::filesystem::remove(bad);
}

TEST(Cli, AssetIsByteIdenticalForAnyThreadCount) {
    auto dir = std::filesystem::temp_directory_path();
    std::string a = (dir / ("cb_cli_t1_" + std::to_string(getpid()) + ".cbk")).string();
    std::string b = (dir / ("cb_cli_t4_" + std::to_string(getpid()) + ".cbk")).string();
    for (const char* method : {"kmeans", "vco", "morton"}) {
        ASSERT_EQ(run("bake " + data("default_scene.glb") + " --bounds all --coarse 512 --threads 1 --method " +
                      method + " -o " + a)
                      .code,
                  0);
        ASSERT_EQ(run("bake " + data("default_scene.glb") + " --bounds all --coarse 512 --threads 4 --method " +
                      method + " -o " + b)
                      .code,
                  0);
        std::ifstream fa(a, std::ios::binary), fb(b, std::ios::binary);
        std::string sa((std::istreambuf_iterator<char>(fa)), std::istreambuf_iterator<char>());
        std::string sb((std::istreambuf_iterator<char>(fb)), std::istreambuf_iterator<char>());
        EXPECT_FALSE(sa.empty());
        EXPECT_TRUE(sa == sb) << method;
    }
    std::filesystem::remove(a);
    std::filesystem::remove(b);
}

TEST(Cli, BakeWritesTheChosenBounds) {
    auto out = std::filesystem::temp_directory_path() / ("cb_cli_bake_" + std::to_string(getpid()) + ".cbk");
    CliRun r = run("bake " + data("default_scene.glb") + " -o " + out.string() + " --json");
    ASSERT_EQ(r.code, 0) << r.err;
    auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["bounds"], "auto");
    EXPECT_GT(j["valid_cones"].get<int>(), 0);
    CliRun v = run("validate " + out.string());
    EXPECT_NE(v.out.find("fine bounds: obb cone"), std::string::npos) << v.out;
    EXPECT_NE(v.out.find("coarse bounds: obb cone"), std::string::npos) << v.out;

    ASSERT_EQ(run("bake " + data("small/cube.obj") + " --bounds sphere,slab -o " + out.string()).code, 0);
    v = run("validate " + out.string());
    EXPECT_NE(v.out.find("fine bounds: sphere slab"), std::string::npos) << v.out;

    ASSERT_EQ(run("cluster " + data("small/cube.obj") + " -o " + out.string()).code, 0);
    v = run("validate " + out.string());
    EXPECT_NE(v.out.find("fine bounds: none"), std::string::npos) << v.out;

    EXPECT_EQ(run("bake " + data("small/cube.obj") + " --bounds obb,box -o " + out.string()).code, 2);
    EXPECT_EQ(run("bake " + data("small/cube.obj") + " --obb best -o " + out.string()).code, 2);
    // Cones are stored relative to boxes: asking for cones alone stores the boxes too.
    ASSERT_EQ(run("bake " + data("small/cube.obj") + " --bounds cone -o " + out.string()).code, 0);
    v = run("validate " + out.string());
    EXPECT_NE(v.out.find("fine bounds: obb cone"), std::string::npos) << v.out;
    // Fine clusters must fit 8-bit local indices: 85 triangles at most.
    EXPECT_EQ(run("bake " + data("small/cube.obj") + " --fine 86 -o " + out.string()).code, 2);
    EXPECT_EQ(run("bake " + data("small/cube.obj") + " --fine 85 -o " + out.string()).code, 0);
    EXPECT_EQ(run("report " + data("small/cube.obj") + " --fine 16,86 -o " + out.string() + "_report").code, 2);
    EXPECT_EQ(run("heatmap " + data("small/cube.obj") + " --fine 86 -o " + out.string() + ".png").code, 2);
    std::filesystem::remove(out);
}

TEST(Cli, QueryAnswersOneLinePerPoint) {
    auto dir = std::filesystem::temp_directory_path();
    std::string asset = (dir / ("cb_cli_q_" + std::to_string(getpid()) + ".cbk")).string();
    std::string pts = (dir / ("cb_cli_q_" + std::to_string(getpid()) + ".txt")).string();
    ASSERT_EQ(run("bake " + data("default_scene.glb") + " -o " + asset).code, 0);
    // Under blob_a with the light straight above; above the blob; on the open ground far from everything.
    std::ofstream(pts) << "-4 0.05 2\n# a comment\n-4 5 2\n\n15 0.01 15\n";
    CliRun r = run("query " + asset + " --light -4,30,2 --points " + pts + " --stats");
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(r.out, "1\n0\n0\n");
    EXPECT_NE(r.err.find("3 queries, 1 in shadow"), std::string::npos) << r.err;
    CliRun ref = run("query " + asset + " --light -4,30,2 --points " + pts + " --reference");
    EXPECT_EQ(ref.out, r.out);
    EXPECT_EQ(run("query " + asset + " --light 1,2 --points " + pts).code, 2);
    // Many points over the scene: the same answers on 1 and 3 threads, trees or reference.
    {
        std::ofstream grid(pts);
        for (int i = 0; i < 40; ++i)
            for (int j = 0; j < 40; ++j)
                grid << -18 + 0.9 * i << " " << 0.02 + 0.05 * ((i * 7 + j) % 5) << " " << -18 + 0.9 * j << "\n";
    }
    CliRun one = run("query " + asset + " --light -4,30,2 --points " + pts);
    CliRun three = run("query " + asset + " --light -4,30,2 --points " + pts + " --threads 3");
    CliRun three_ref = run("query " + asset + " --light -4,30,2 --points " + pts + " --threads 3 --reference");
    EXPECT_EQ(one.out.size(), 1600u * 2);
    EXPECT_EQ(three.out, one.out);
    EXPECT_EQ(three_ref.out, one.out);
    for (const char* traversal :
         {"top-two", "top-one", "mtsv-one", "mtsv-two", "mtsv-one --mtsv-build reference",
          "mtsv-one --capsule-aspect 1.2", "mtsv-one --capsule-aspect inf", "mtsv-one --capsule-ratio 1.2", "trees",
          "one-tree", "mtsv"})  // the same answers (the last three: the older spellings)
        EXPECT_EQ(run("query " + asset + " --light -4,30,2 --points " + pts + " --traversal " + traversal).out, one.out)
            << traversal;
    EXPECT_EQ(run("query " + asset + " --light -4,30,2 --points " + pts + " --traversal leaves").code, 2);
    EXPECT_NE(one.out.find('1'), std::string::npos);
    EXPECT_NE(one.out.find('0'), std::string::npos);
    std::ofstream(pts) << "1 2\n";
    CliRun bad = run("query " + asset + " --light 1,2,3 --points " + pts);
    EXPECT_EQ(bad.code, 2);
    EXPECT_EQ(bad.err, pts + ": line 1: expected 'x y z'\n");
    EXPECT_EQ(run("query " + pts + " --light 1,2,3 --points " + pts).code, 2);  // not an asset
    std::filesystem::remove(asset);
    std::filesystem::remove(pts);
}

// A level file in place of the asset: paths relative to it, each asset opened once, every traversal giving
// the reference's answers; a glTF translation, rotation and scale meaning what the equal matrix means.
TEST(Cli, QueryBiasIsAWorldDistance) {
    // A square roof 1 above the ground and points 0.01 under it: with --bias 0.001 the roof shadows them
    // however far the light, with --bias 0.02 it does not; a bias that is not a distance is refused.
    const auto dir = std::filesystem::temp_directory_path() / ("cb_cli_bias_" + std::to_string(getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    const std::string obj = (dir / "roof.obj").string(), asset = (dir / "roof.cbk").string(),
                      pts = (dir / "points.txt").string();
    std::ofstream(obj) << "v -1 1 -1\nv 1 1 -1\nv 1 1 1\nv -1 1 1\nf 1 2 3\nf 1 3 4\n";
    std::ofstream(pts) << "0.1 0.99 0.2\n-0.3 0.99 -0.4\n0.5 0.99 0.5\n";
    ASSERT_EQ(run("bake " + obj + " -o " + asset).code, 0);
    for (const char* light : {"0,10,0", "0,1e7,0", "3,1e9,2"}) {
        SCOPED_TRACE(light);
        const std::string q = "query " + asset + " --points " + pts + " --light " + light;
        EXPECT_EQ(run(q + " --bias 0.001").out, "1\n1\n1\n");
        EXPECT_EQ(run(q + " --bias 0.02").out, "0\n0\n0\n");
        EXPECT_EQ(run(q + " --bias 0.001 --reference").out, "1\n1\n1\n");
        EXPECT_EQ(run(q).out, "1\n1\n1\n");  // the default: 2 / 65536 for this 2-wide roof
    }
    CliRun json = run("query " + asset + " --points " + pts + " --light 0,10,0 --json");
    const size_t at = json.out.find("\"bias\":");
    ASSERT_NE(at, std::string::npos) << json.out;
    EXPECT_NEAR(std::stod(json.out.substr(at + 7)), 2.0 / 65536, 1e-12);  // the hierarchy's boxes are padded
    for (const char* bad : {"-1", "nan", "inf"}) {
        CliRun r = run("query " + asset + " --points " + pts + " --light 0,10,0 --bias " + bad);
        EXPECT_EQ(r.code, 2) << bad;
        EXPECT_NE(r.err.find("--bias"), std::string::npos) << r.err;
    }
    std::filesystem::remove_all(dir);
}

TEST(Cli, QuerySunAnswersAsItsReference) {
    // --sun: a light at infinity by its direction. Under blob_a with the sun straight up, and a low sun from
    // either side; the grid of points answered as --reference answers it, on 1 and 3 threads, both modes; bad
    // suns and light pairs refused.
    const auto dir = std::filesystem::temp_directory_path() / ("cb_cli_sun_" + std::to_string(getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    const std::string asset = (dir / "scene.cbk").string(), pts = (dir / "points.txt").string();
    ASSERT_EQ(run("bake " + data("default_scene.glb") + " -o " + asset).code, 0);
    std::ofstream(pts) << "-4 0.05 2\n-4 5 2\n15 0.01 15\n";
    CliRun up = run("query " + asset + " --sun 0,1,0 --points " + pts + " --stats");
    EXPECT_EQ(up.code, 0) << up.err;
    EXPECT_EQ(up.out, "1\n0\n0\n");
    EXPECT_EQ(run("query " + asset + " --sun 0,3e-9,0 --points " + pts).out, up.out);  // any length
    {
        std::ofstream grid(pts);
        for (int i = 0; i < 40; ++i)
            for (int j = 0; j < 40; ++j)
                grid << -18 + 0.9 * i << " " << 0.02 + 0.05 * ((i * 7 + j) % 5) << " " << -18 + 0.9 * j << "\n";
    }
    size_t dark = 0;
    for (const char* sun : {"0.3,1,0.2", "-1,0.15,0.3", "1,0.05,-0.2"})
        for (const char* mode : {"", " --one-sided"}) {
            SCOPED_TRACE(std::string(sun) + mode);
            const std::string q = "query " + asset + " --points " + pts + " --sun " + sun + mode;
            const CliRun one = run(q), three = run(q + " --threads 3"), ref = run(q + " --reference");
            EXPECT_EQ(one.code, 0) << one.err;
            EXPECT_EQ(one.out.size(), 1600u * 2);
            EXPECT_EQ(three.out, one.out);
            EXPECT_EQ(ref.out, one.out);
            for (const char* traversal : {"top-two", "top-one", "mtsv-one", "mtsv-two"})
                EXPECT_EQ(run(q + " --traversal " + traversal).out, one.out) << traversal;
            dark += size_t(std::count(one.out.begin(), one.out.end(), '1'));
        }
    EXPECT_GT(dark, 6u * 1600 / 50);  // shadows to get wrong
    CliRun json = run("query " + asset + " --points " + pts + " --sun 0,1,0 --json");
    EXPECT_NE(json.out.find("\"sun\":[0.0,1.0,0.0]"), std::string::npos) << json.out;
    EXPECT_NE(json.out.find("\"traversal\":\"scan\""), std::string::npos) << json.out;
    for (const char* bad : {" --sun 0,0,0", " --sun 1,2", " --sun nan,1,0", " --sun 0,1,0 --light 0,5,0", "",
                            " --sun 0,1,0 --traversal tree"}) {
        CliRun r = run("query " + asset + " --points " + pts + bad);
        EXPECT_EQ(r.code, 2) << bad;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    }
    std::filesystem::remove_all(dir);
}

TEST(Cli, QueryTakesALevelFile) {
    const auto dir = std::filesystem::temp_directory_path() / ("cb_cli_level_" + std::to_string(getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir / "assets");
    const std::string asset = (dir / "assets" / "scene.cbk").string(), pts = (dir / "points.txt").string();
    ASSERT_EQ(run("bake " + data("default_scene.glb") + " -o " + asset).code, 0);
    {
        std::ofstream grid(pts);  // over the three copies below
        for (int i = 0; i < 60; ++i)
            for (int j = 0; j < 40; ++j)
                grid << -18 + 0.97 * i << " " << 0.02 + 0.05 * ((i * 7 + j) % 5) << " " << -18 + 0.9 * j << "\n";
    }
    auto level = [&](const std::string& name, const std::string& entries) {
        std::ofstream((dir / name).string()) << "{\"instances\": [" << entries << "]}";
        return (dir / name).string();
    };
    const std::string base = R"({"asset": "assets/scene.cbk"})";
    // A half turn about y, then a scale mirroring x: the columns (-2, 0, 0), (0, 1, 0), (0, 0, 1).
    const std::string trs = level("trs.json", base + R"(, {"asset": "./assets/../assets/scene.cbk",
        "translation": [30, 0, 0], "rotation": [0, 1, 0, 0], "scale": [2, 1, -1]})");
    const std::string matrix = level("matrix.json", base + R"(, {"asset": "assets/scene.cbk",
        "matrix": [-2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 30, 0, 0, 1]})");
    const std::string alone = level("alone.json", base);
    const std::string light = " --light 6,30,2 --points " + pts;

    CliRun ref = run("query " + trs + light + " --reference");
    ASSERT_EQ(ref.code, 0) << ref.err;
    EXPECT_EQ(ref.out.size(), 2400u * 2);
    for (const char* traversal : {"scan", "top-two", "top-one", "mtsv-one", "mtsv-two"})
        EXPECT_EQ(run("query " + trs + light + " --traversal " + traversal + " --threads 2").out, ref.out) << traversal;
    EXPECT_EQ(run("query " + matrix + light).out, ref.out);
    const std::string asset_only = run("query " + asset + light).out;
    EXPECT_EQ(run("query " + alone + light).out, asset_only);
    EXPECT_NE(asset_only, ref.out) << "the second copy casts shadows of its own";
    CliRun json = run("query " + trs + light + " --json --stats");
    ASSERT_EQ(json.code, 0) << json.err;
    EXPECT_NE(json.out.find("\"shadowed\":"), std::string::npos);

    // Bad level files: exit code 2 and one line naming the file and the entry.
    const std::string q = " --light 0,10,0 --points " + pts;
    const std::pair<std::string, std::string> bad[] = {
        {"{\"instances\": []}", "instances: no entry"},
        {"{\"instance\": []}", "a level file is an object with an \"instances\" array"},
        {"{\"instances\": [", "not JSON text (parse error at byte 16)"},
        {"{\"instances\": [" + base + ", {\"asset\": \"missing.cbk\"}]}",
         "instances[1]: " + (dir / "missing.cbk").string() + ": cannot open (No such file or directory)"},
        {"{\"instances\": [{\"asset\": \"assets/scene.cbk\", \"matirx\": []}]}",
         "instances[0]: unknown key 'matirx' (asset, matrix, translation, rotation, scale)"},
        {"{\"instances\": [{\"asset\": \"assets/scene.cbk\", \"matrix\": [1, 0, 0]}]}",
         "instances[0]: matrix needs 16 numbers"},
        {"{\"instances\": [{\"asset\": \"assets/scene.cbk\", \"matrix\": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,2]}]}",
         "instances[0]: matrix is not affine (its last row, elements 3, 7, 11 and 15, must be 0 0 0 1)"},
        {"{\"instances\": [{\"asset\": \"assets/scene.cbk\", \"rotation\": [0, 0, 0, 0]}]}",
         "instances[0]: rotation quaternion has zero length"},
        {"{\"instances\": [{\"asset\": \"assets/scene.cbk\", \"scale\": [1, \"2\", 1]}]}",
         "instances[0]: scale[1] is not a number"},
        {"{\"instances\": [{\"asset\": \"assets/scene.cbk\", \"scale\": [1, 1, 1], \"matrix\": []}]}",
         "instances[0]: a matrix and a translation, rotation or scale: give one or the other"},
        {"{\"instances\": [{\"matrix\": []}]}", "instances[0]: needs \"asset\": the path of a baked asset"},
        {"{\"instances\": [{\"asset\": \"points.txt\"}]}",
         "instances[0]: " + (dir / "points.txt").string() + ": not a clusterbake asset (bad magic)"},
    };
    for (const auto& [text, line] : bad) {
        const std::string file = (dir / "bad.json").string();
        std::ofstream(file) << text;
        for (const char* command : {"query ", "render "}) {
            CliRun r = run(command + file + (command[0] == 'q' ? q : " -o " + (dir / "bad.png").string()));
            EXPECT_EQ(r.code, 2) << text;
            EXPECT_EQ(r.err, file + ": " + line + "\n") << text;
        }
        EXPECT_FALSE(std::filesystem::exists(dir / "bad.png"));
    }
    std::filesystem::remove_all(dir);
}

TEST(Cli, OptionsNoAlgorithmTakesAreRefusedInOneLineBeforeAnyWork) {
    const std::filesystem::path out = std::filesystem::temp_directory_path() / "cb_cli_refused.cbk";
    std::filesystem::remove(out);
    for (const char* options : {"--coarse 0", "--coarse 8 --fine 16", "--k0 0", "--k0 1", "--capsule-ratio -1",
                                "--capsule-ratio nan", "--cache 0", "--fine 0", "--threads x", "--no-such-flag"}) {
        CliRun r = run("bake " + data("small/cube.obj") + " " + options + " -o " + out.string());
        EXPECT_EQ(r.code, 2) << options;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << options << ": " << r.err;
        EXPECT_EQ(r.err.rfind("clusterbake: ", 0), 0u) << options << ": " << r.err;
        EXPECT_FALSE(std::filesystem::exists(out)) << options;
    }
    EXPECT_EQ(run("stats " + data("small/cube.obj") + " --coarse 8 --fine 16").code, 2);
}

TEST(Cli, VersionNamesTheToolAndTheAssetFormat) {
    CliRun r = run("--version");
    EXPECT_EQ(r.code, 0);
    EXPECT_EQ(r.out.rfind("clusterbake ", 0), 0u) << r.out;
    EXPECT_NE(r.out.find("asset format " + std::to_string(cb::asset_version)), std::string::npos) << r.out;
}

TEST(Cli, BakeChecksItsOutputPathBeforeAnyWork) {
    namespace fs = std::filesystem;
    fs::path dir = fs::temp_directory_path() / ("cb_cli_out_" + std::to_string(getpid()));
    fs::create_directories(dir);
    std::string cube = data("small/cube.obj");
    auto refused = [&](const std::string& out, const std::string& why, const std::string& extra = "") {
        CliRun r = run("bake " + cube + " -o " + out + extra);
        EXPECT_EQ(r.code, 2) << out;
        EXPECT_EQ(r.err, "clusterbake: " + out + ": " + why + "\n");
    };
    refused((dir / "scene.glb").string(), "named like a scene file; an asset is not one (name it .cbk, or --force)");
    refused((dir / "scene.GLTF").string(), "named like a scene file; an asset is not one (name it .cbk, or --force)");
    refused((dir / "no" / "x.cbk").string(), "folder " + (dir / "no").string() + " does not exist");
    refused(dir.string(), "exists and is not a regular file");
    EXPECT_FALSE(fs::exists(dir / "scene.glb"));
    EXPECT_EQ(run("bake " + cube + " -o " + (dir / "scene.glb").string() + " --force -q").code, 0);
    EXPECT_EQ(run("bake " + cube + " -o " + (dir / "x.cbk").string() + " --force --if-changed").code, 2);
    fs::remove_all(dir);
}

TEST(Cli, ASceneWithoutTrianglesBakesWithAWarning) {
    namespace fs = std::filesystem;
    fs::path dir = fs::temp_directory_path() / ("cb_cli_empty_" + std::to_string(getpid()));
    fs::create_directories(dir);
    std::ofstream(dir / "points.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    CliRun r = run("bake " + (dir / "points.obj").string() + " -o " + (dir / "points.cbk").string());
    EXPECT_EQ(r.code, 0);
    EXPECT_NE(r.err.find("clusterbake: warning: " + (dir / "points.obj").string() + ": no triangles"),
              std::string::npos)
        << r.err;
    CliRun v = run("validate " + (dir / "points.cbk").string());
    EXPECT_EQ(v.code, 0) << v.err;
    fs::remove_all(dir);
}

namespace {

std::filesystem::path scratch(const std::string& name) {
    return std::filesystem::temp_directory_path() / ("cb_cli_" + std::to_string(getpid()) + "_" + name);
}

// A bad input: exit code 2 and exactly this one line on stderr.
void expect_bad_input(const CliRun& r, const std::string& line, const std::string& context) {
    EXPECT_EQ(r.code, 2) << context;
    EXPECT_EQ(r.err, line + "\n") << context;
}

}  // namespace

TEST(Cli, InfoListsGltfExtensionsAndBakeWarnsOfOnesItCannotRead) {
    namespace fs = std::filesystem;
    fs::path dir = fs::temp_directory_path() / ("cb_cli_extensions_" + std::to_string(getpid()));
    fs::create_directories(dir);
    cb::data::GltfWriter w;
    w.mesh("m", {{0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2}}, -1);
    w.node({{"mesh", 0}, {"extensions", {{"MSFT_lod", {{"ids", {0}}}}}}});
    w.doc["extensionsUsed"] = {"MSFT_lod", "KHR_texture_transform"};
    const fs::path scene = dir / "lod.gltf";
    std::ofstream(scene) << w.gltf_embedded();
    const std::string warning = scene.string() +
        ": optional extension MSFT_lod (on nodes) is not supported and could change the geometry: loaded without it";
    CliRun info = run("info " + scene.string());
    EXPECT_EQ(info.code, 0) << info.err;
    EXPECT_NE(info.out.find("  extensions: MSFT_lod (unsupported), KHR_texture_transform (no geometry)\n"),
              std::string::npos)
        << info.out;
    EXPECT_NE(info.out.find("  warning: " + warning + "\n"), std::string::npos) << info.out;
    CliRun bake = run("bake " + scene.string() + " -o " + (dir / "lod.cbk").string());
    EXPECT_EQ(bake.code, 0) << bake.err;
    EXPECT_NE(bake.err.find("clusterbake: warning: " + warning + "\n"), std::string::npos) << bake.err;
    // Required, it is refused.
    w.doc["extensionsRequired"] = {"MSFT_lod"};
    std::ofstream(scene) << w.gltf_embedded();
    expect_bad_input(run("info " + scene.string()),
                     scene.string() + ": unsupported required extension MSFT_lod (on nodes)", "required");
    fs::remove_all(dir);
}

TEST(Cli, FilesThatAreNotWhatTheirNameSaysGiveOneLineNamingThem) {
    std::string text = scratch("text.glb").string(), gltf = scratch("text.gltf").string();
    std::ofstream(text) << "hello world\n";
    std::ofstream(gltf) << "hello world\n";
    for (const std::string& command :
         {std::string("info "), "bake -o " + scratch("text.cbk").string() + " ", std::string("stats ")}) {
        expect_bad_input(run(command + text),
                         text +
                             ": not a glTF file: neither binary glTF (magic 'glTF') nor JSON text (parse error "
                             "at byte 1)",
                         command);
        expect_bad_input(run(command + gltf),
                         gltf +
                             ": not a glTF file: neither binary glTF (magic 'glTF') nor JSON text (parse error "
                             "at byte 1)",
                         command);
    }
    // A GLB whose JSON chunk is broken, and one whose buffer file is missing.
    auto glb = [](const std::string& path, std::string json) {
        while (json.size() % 4) json += ' ';
        auto u32 = [](uint32_t v) { return std::string{char(v), char(v >> 8), char(v >> 16), char(v >> 24)}; };
        std::ofstream(path, std::ios::binary)
            << "glTF" + u32(2) + u32(uint32_t(20 + json.size())) + u32(uint32_t(json.size())) + "JSON" + json;
    };
    std::string broken = scratch("broken.glb").string(), missing = scratch("missing.glb").string();
    glb(broken, "{\"asset\": {\"version\": \"2.0\"}, broken");
    glb(missing, "{\"asset\": {\"version\": \"2.0\"}, \"buffers\": [{\"uri\": \"nowhere.bin\", \"byteLength\": 12}]}");
    expect_bad_input(run("info " + broken),
                     broken + ": GLB JSON chunk is not JSON text (parse error at byte 31 of the chunk)", "broken GLB");
    CliRun r = run("info " + missing);
    EXPECT_EQ(r.code, 2);
    EXPECT_EQ(r.err.rfind(missing + ": buffer 0: 'nowhere.bin': no such file (looked for ", 0), 0u) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    // Text named .stl is neither kind of STL, not an empty mesh.
    std::string stl = scratch("text.stl").string();
    std::ofstream(stl) << "hello world\n";
    expect_bad_input(run("info " + stl),
                     stl +
                         ": not an STL file: neither binary STL (at least 84 bytes) nor ASCII STL (starts with "
                         "'solid')",
                     "text .stl");
    for (const std::string& f : {text, gltf, broken, missing, stl}) std::filesystem::remove(f);
}

TEST(Cli, QueryReadsPointsFromStandardInput) {
    std::string asset = scratch("stdin.cbk").string(), pts = scratch("stdin.txt").string(),
                bin = scratch("stdin.bin").string();
    ASSERT_EQ(run("bake " + data("default_scene.glb") + " -o " + asset).code, 0);
    const float points[] = {-4, 0.05f, 2, -4, 5, 2, 15, 0.01f, 15};
    std::ofstream(pts) << "-4 0.05 2\n-4 5 2\n15 0.01 15\n";
    std::ofstream(bin, std::ios::binary).write(reinterpret_cast<const char*>(points), sizeof points);
    std::string query = "query " + asset + " --light -4,30,2 --points ";
    EXPECT_EQ(run(query + pts).out, "1\n0\n0\n");
    EXPECT_EQ(run(query + "- < " + pts).out, "1\n0\n0\n");
    EXPECT_EQ(run(query + "- --binary < " + bin).out, "1\n0\n0\n");
    EXPECT_EQ(run(query + "- --binary", "cat " + bin).out, "1\n0\n0\n");  // a pipe, not a file
    EXPECT_EQ(run(query + "-", "cat " + pts).out, "1\n0\n0\n");
    std::ofstream(pts) << "1 2\n";
    expect_bad_input(run(query + "- < " + pts), "standard input: line 1: expected 'x y z'", "stdin");
    expect_bad_input(run(query + "- --binary < " + pts),
                     "standard input: 4 bytes is not a whole number of float32 triples", "stdin, binary");
    for (const std::string& f : {asset, pts, bin}) std::filesystem::remove(f);
}

namespace {

// A usage error: exit code 2 and one line on stderr, "clusterbake: ...", that names `what`.
void expect_usage_error(const CliRun& r, const std::string& what, const std::string& context) {
    EXPECT_EQ(r.code, 2) << context << ": " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << context << ": " << r.err;
    EXPECT_EQ(r.err.rfind("clusterbake: ", 0), 0u) << context << ": " << r.err;
    EXPECT_NE(r.err.find(what), std::string::npos) << context << ": " << r.err;
}

// The line of `help` that describes `flag` (CLI11 prints one line per option).
std::string help_line(const std::string& help, const std::string& flag) {
    for (size_t at = help.find(flag); at != std::string::npos; at = help.find(flag, at + 1)) {
        size_t begin = help.rfind('\n', at) + 1, end = help.find('\n', at);
        std::string line = help.substr(begin, end - begin);
        // The option's own line: the flag is the line's first word (after a short alias).
        std::string first = line.substr(line.find_first_not_of(' '));
        if (first.rfind(flag + " ", 0) == 0 || first.rfind(flag + ",", 0) == 0 || first.find(", " + flag) < 4)
            return line;
    }
    return {};
}

// "clusterbake 0.1.2", as --version starts.
std::string tool_version() {
    std::string v = run("--version").out;
    return v.substr(0, v.find(" ("));
}

// The quickest report of the 12-triangle cube, and its smallest sweep: one configuration.
const std::string quick_report = " --fine 8 --runs 1 --query-runs 1 --view 16 --lights 1";
const std::string one_config = " --method kmeans --obb pca";

}  // namespace

TEST(Cli, OneFlagNameHasOneMeaning) {
    std::string asset = scratch("names.cbk").string(), pts = scratch("names.txt").string();
    ASSERT_EQ(run("bake " + data("small/cube.obj") + " -o " + asset).code, 0);
    std::ofstream(pts) << "0 2 0\n";
    // --fine is a fine cluster size: a query cannot change it, and says what picks the traversal.
    CliRun fine = run("query " + asset + " --light 0,5,0 --points " + pts + " --fine trees");
    expect_usage_error(fine, "--fine", "query --fine");
    EXPECT_NE(fine.err.find("--traversal"), std::string::npos) << fine.err;
    EXPECT_EQ(run("query " + asset + " --light 0,5,0 --points " + pts + " --traversal top-two").out, "0\n");
    EXPECT_EQ(help_line(run("query --help").out, "--fine"), "");
    // Every command's --fine is the fine cluster size; report's takes a list of them.
    for (const char* command : {"cluster", "bake", "batch", "stats", "report", "heatmap"}) {
        std::string line = help_line(run(std::string(command) + " --help").out, "--fine");
        EXPECT_NE(line.find("triangles per fine cluster, 1 to 85"), std::string::npos) << command << ": " << line;
    }
    // report's sweep takes bake's flag names, each with a comma list.
    expect_usage_error(
        run("report " + data("small/cube.obj") + " -o " + scratch("names_report").string() + " --methods kmeans"),
        "--methods", "report --methods");
    CliRun report = run("report " + data("small/cube.obj") + " -o " + scratch("names_report").string() + quick_report +
                        " --method kmeans,vco --obb refined,pca --traversal scan,top-two,mtsv-two --json -q");
    ASSERT_EQ(report.code, 0) << report.err;
    nlohmann::json j = nlohmann::json::parse(report.out);
    EXPECT_EQ(j["options"]["methods"], nlohmann::json::array({"kmeans", "vco"}));
    EXPECT_EQ(j["options"]["obbs"], nlohmann::json::array({"refined", "pca"}));
    EXPECT_EQ(j["options"]["traversals"], nlohmann::json::array({"scan", "top-two", "mtsv-two"}));
    EXPECT_EQ(j["scenes"][0]["configs"].size(), 12u);
    // --traversal is query's name for the same choice; an unknown one is a usage error.
    expect_usage_error(run("report " + data("small/cube.obj") + " -o " + scratch("names_report").string() +
                           " --traversal scan,leaves"),
                       "--traversal takes a list of scan, top-two, top-one, mtsv-one, mtsv-two", "report --traversal");
    // The shadow-volume sampling lights are --sample-lights in stats as in report; --lights is report's own.
    expect_usage_error(run("stats " + data("small/cube.obj") + " --lights 2"), "--lights", "stats --lights");
    EXPECT_EQ(run("stats " + data("small/cube.obj") + " --sample-lights 2 --samples 4").code, 0);
    std::filesystem::remove_all(scratch("names_report"));
    std::filesystem::remove(asset);
    std::filesystem::remove(pts);
}

TEST(Cli, EveryCommandTakesJsonAndQuietAndNamesTheTool) {
    const std::string tool = tool_version(), cube = data("small/cube.obj");
    EXPECT_EQ(tool.rfind("clusterbake 0.", 0), 0u) << tool;
    std::string asset = scratch("json.cbk").string(), pts = scratch("json.txt").string();
    std::ofstream(pts) << "0 2 0\n0 0.5 0\n";
    const std::vector<std::string> commands = {
        "bake " + cube + " -o " + asset,
        "cluster " + cube + " -o " + scratch("json_cluster.cbk").string(),
        "info " + cube,
        "validate " + asset,
        "query " + asset + " --light 0,5,0 --points " + pts + " --stats",
        "stats " + cube,
        "stats " + asset,
        "heatmap " + cube + " -o " + scratch("json.png").string() + " --size 16",
        "report " + cube + " -o " + scratch("json_report").string() + quick_report + one_config,
        "batch " + cube + " -o " + scratch("json_batch").string()};
    for (const std::string& command : commands) {
        CliRun r = run(command + " --json -q");
        ASSERT_EQ(r.code, 0) << command << ": " << r.err;
        EXPECT_EQ(r.err, "") << command;
        nlohmann::json j = nlohmann::json::parse(r.out);
        for (const nlohmann::json& record : j.is_array() ? j : nlohmann::json::array({j}))
            EXPECT_EQ(record["tool"], tool) << command;
    }
    nlohmann::json q = nlohmann::json::parse(run(commands[4] + " --json").out);
    EXPECT_EQ(q["answers"], nlohmann::json::array({0, 1}));
    EXPECT_EQ(q["shadowed"], 1);
    EXPECT_TRUE(q["stats"].contains("build_seconds"));
    nlohmann::json v = nlohmann::json::parse(run(commands[3] + " --json").out);
    EXPECT_EQ(v["valid"], true);
    EXPECT_EQ(v["triangles"], 12);
    EXPECT_EQ(v["fine_bounds"], nlohmann::json::array({"obb", "cone"}));
    // An invalid asset is still one JSON object, and one line on stderr.
    CliRun invalid = run("validate " + pts + " --json");
    EXPECT_EQ(invalid.code, 2);
    EXPECT_EQ(nlohmann::json::parse(invalid.out)["valid"], false);
    EXPECT_EQ(std::count(invalid.err.begin(), invalid.err.end(), '\n'), 1) << invalid.err;
    for (const char* f : {"json.cbk", "json_cluster.cbk", "json.png", "json.txt"}) std::filesystem::remove(scratch(f));
    for (const char* d : {"json_report", "json_batch"}) std::filesystem::remove_all(scratch(d));
}

TEST(Cli, ThreadsMeanAllHardwareThreadsByDefaultEverywhere) {
    for (const char* command : {"cluster", "bake", "batch", "stats", "report", "heatmap", "query"}) {
        std::string line = help_line(run(std::string(command) + " --help").out, "--threads");
        EXPECT_NE(line.find("0 = all hardware threads; "), std::string::npos) << command << ": " << line;
        EXPECT_NE(line.find("(default 0)"), std::string::npos) << command << ": " << line;
    }
    std::string asset = scratch("threads.cbk").string(), pts = scratch("threads.txt").string();
    ASSERT_EQ(run("bake " + data("default_scene.glb") + " -o " + asset).code, 0);
    {
        std::ofstream grid(pts);
        for (int i = 0; i < 30; ++i)
            for (int j = 0; j < 30; ++j) grid << -18 + 1.2 * i << " 0.05 " << -18 + 1.2 * j << "\n";
    }
    std::string query = "query " + asset + " --light -4,30,2 --points " + pts;
    CliRun all = run(query), one = run(query + " --threads 1"), zero = run(query + " --threads 0");
    ASSERT_EQ(all.code, 0) << all.err;
    EXPECT_EQ(all.out, one.out);
    EXPECT_EQ(all.out, zero.out);
    // The heat map uses every thread for every stage, and draws the same picture.
    std::string png_all = scratch("threads_all.png").string(), png_one = scratch("threads_one.png").string();
    ASSERT_EQ(run("heatmap " + data("default_scene.glb") + " --size 32 -o " + png_all).code, 0);
    ASSERT_EQ(run("heatmap " + data("default_scene.glb") + " --size 32 --threads 1 -o " + png_one).code, 0);
    auto bytes = [](const std::string& path) {
        std::ifstream in(path, std::ios::binary);
        return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    };
    EXPECT_FALSE(bytes(png_all).empty());
    EXPECT_TRUE(bytes(png_all) == bytes(png_one));
    for (const std::string& f : {asset, pts, png_all, png_one}) std::filesystem::remove(f);
}

TEST(Cli, OptionsACommandWouldIgnoreAreRefused) {
    const std::string cube = data("small/cube.obj");
    std::string asset = scratch("ignored.cbk").string(), all = scratch("ignored_all.cbk").string();
    ASSERT_EQ(run("bake " + cube + " -o " + asset).code, 0);
    ASSERT_EQ(run("bake " + cube + " --bounds all -o " + all).code, 0);
    // An asset's clusters are made: every option that shapes clusters does nothing to it.
    for (const char* option : {"--method vco", "--coarse 512", "--fine 8", "--seed 2", "--k0 4", "--iterations 3",
                               "--method vco --cache 16", "--presplit 1000", "--coarse-morton"}) {
        std::string name = std::string(option).substr(0, std::string(option).find(' '));
        expect_usage_error(run("stats " + asset + " " + option), name + " does nothing here", option);
        EXPECT_EQ(run("stats " + cube + " " + option + " -q").code, 0) << option;  // a scene is clustered
    }
    // A method's own options do nothing to another method.
    for (const char* option : {"--cache 16", "--method morton --cache 16", "--method vco --seed 2",
                               "--method vco --k0 4", "--method morton --iterations 3", "--method vco --presplit 100",
                               "--method morton --coarse-morton", "--coarse-morton --presplit 100"}) {
        std::string last = std::string(option).substr(std::string(option).rfind("--"));
        std::string name = last.substr(0, last.find(' '));
        expect_usage_error(run("stats " + cube + " " + option), name + " does nothing here", option);
        // The same before any work in the commands that write: nothing is made.
        const std::string out = scratch("ignored_method.cbk").string(), outdir = scratch("ignored_batch").string();
        for (const char* command : {"bake ", "cluster "})
            expect_usage_error(run(command + cube + " -o " + out + " " + option), name + " does nothing here",
                               command + std::string(option));
        expect_usage_error(run("batch " + cube + " -o " + outdir + " " + option), name + " does nothing here",
                           std::string("batch ") + option);
        EXPECT_FALSE(std::filesystem::exists(out)) << option;
        EXPECT_FALSE(std::filesystem::exists(outdir)) << option;
    }
    // A manifest line's method against the batch's own options, and a line's own options.
    const std::filesystem::path folder = scratch("ignored_manifest");
    std::filesystem::create_directories(folder);
    std::filesystem::copy_file(cube, folder / "cube.obj", std::filesystem::copy_options::overwrite_existing);
    const std::string manifest = (folder / "manifest.txt").string(), outdir = scratch("ignored_batch").string();
    std::ofstream(manifest) << "cube.obj --method vco\n";
    expect_usage_error(run("batch " + manifest + " -o " + outdir + " --seed 3"), "--seed does nothing here",
                       "manifest --method vco, batch --seed");
    std::ofstream(manifest) << "cube.obj --method morton --cache 8\n";
    expect_usage_error(run("batch " + manifest + " -o " + outdir), "--cache does nothing here",
                       "manifest --method morton --cache");
    EXPECT_FALSE(std::filesystem::exists(outdir));
    std::ofstream(manifest) << "cube.obj --method vco --cache 8\n";
    EXPECT_EQ(run("batch " + manifest + " -o " + outdir + " -q").code, 0);
    std::filesystem::remove_all(outdir);
    std::filesystem::remove_all(folder);
    // The box fitter and the capsule ratio shape only the volumes the asset does not store.
    EXPECT_EQ(run("stats " + asset + " --obb pca --capsule-ratio 3").code, 0);
    expect_usage_error(run("stats " + all + " --obb pca"), "--obb does nothing here", "all kinds stored");
    expect_usage_error(run("stats " + all + " --capsule-ratio 3"), "--capsule-ratio does nothing here",
                       "capsules stored");
    EXPECT_EQ(run("stats " + all + " --threads 1").code, 0);
    // heatmap and report cluster a scene themselves: an asset is refused before any work.
    std::string png = scratch("ignored.png").string(), dir = scratch("ignored_report").string();
    expect_usage_error(run("heatmap " + asset + " -o " + png), "is a clusterbake asset", "heatmap ASSET");
    expect_usage_error(run("heatmap " + cube + " -o " + png + " --sun 0,1,0 --light 0,9,0"), "name two lights",
                       "heatmap --sun --light");
    expect_usage_error(run("heatmap " + cube + " -o " + png + " --sun 0,0,0"), "--sun takes X,Y,Z", "heatmap --sun 0");
    expect_usage_error(run("report " + cube + " " + asset + " -o " + dir), "is a clusterbake asset", "report ASSET");
    expect_usage_error(run("report " + cube + " -o " + dir + " --heatmap-size 64"), "--heatmap-size does nothing here",
                       "--heatmap-size alone");
    EXPECT_FALSE(std::filesystem::exists(png));
    EXPECT_FALSE(std::filesystem::exists(dir));
    // The reference walk takes no traversal.
    std::string pts = scratch("ignored.txt").string();
    std::ofstream(pts) << "0 2 0\n";
    expect_usage_error(run("query " + asset + " --light 0,5,0 --points " + pts + " --reference --traversal top-two"),
                       "--traversal does nothing here", "--reference --traversal");
    EXPECT_EQ(run("query " + asset + " --light 0,5,0 --points " + pts + " --reference --one-sided").out, "0\n");
    for (const std::string& f : {asset, all, pts}) std::filesystem::remove(f);
}

TEST(Cli, OutputsAreCheckedBeforeAnyWork) {
    const std::string scene = data("default_scene.glb");
    std::string file = scratch("output_file").string();
    std::ofstream(file) << "not a folder";
    // Without -q the sweep would print progress: one line on stderr means it never started.
    expect_usage_error(run("report " + scene + " -o /dev/null"), "/dev/null: exists and is not a folder", "/dev/null");
    expect_usage_error(run("report " + scene + " -o " + file), "exists and is not a folder", "a file");
    expect_usage_error(run("report " + scene + " -o " + file + "/sub"), "cannot make the folder", "under a file");
    expect_usage_error(run("heatmap " + scene + " -o /dev/null"), "exists and is not a regular file", "heatmap");
    expect_usage_error(run("heatmap " + scene + " -o " + scratch("no_folder").string() + "/h.png"),
                       "folder " + scratch("no_folder").string() + " does not exist", "heatmap, no folder");
    expect_usage_error(run("heatmap " + scene + " -o " + std::filesystem::temp_directory_path().string()),
                       "exists and is not a regular file", "heatmap, a folder");
    std::filesystem::remove(file);
}

TEST(Cli, UsageErrorsAreOneLineWithExitCode2) {
    const std::string cube = data("small/cube.obj"), scene = data("default_scene.glb");
    std::string asset = scratch("usage.cbk").string(), pts = scratch("usage.txt").string(),
                dir = scratch("usage_dir").string(), png = scratch("usage.png").string();
    ASSERT_EQ(run("bake " + cube + " -o " + asset).code, 0);
    std::ofstream(pts) << "0 2 0\n";
    const std::string query = "query " + asset + " --points " + pts + " --light 0,5,0";
    for (const std::string& args : std::vector<std::string>{
             "no-such-command",
             "info",
             "info --no-such-flag " + cube,
             "validate",
             "validate " + asset + " extra",
             "query " + asset + " --points " + pts,
             query + " --traversal leaves",
             query + " --threads many",
             query + " --fine 8",
             query + " --reference --traversal scan",
             query + " --capsule-ratio 3",
             query + " --traversal top-two --mtsv-build reference",
             query + " --traversal mtsv-one --mtsv-build best",
             query + " --traversal mtsv-one --capsule-ratio 0.5",
             query + " --traversal mtsv-one --capsule-ratio nan",
             query + " --capsule-aspect 3",
             query + " --traversal mtsv-one --capsule-aspect 0.5",
             "query " + asset + " --points " + pts + " --light 0,5",
             "stats",
             "stats " + cube + " --fine 86",
             "stats " + cube + " --coarse 8 --fine 16",
             "stats " + asset + " --method kmeans",
             "stats " + cube + " --lights 3",
             "heatmap " + cube,
             "heatmap " + cube + " -o " + png + " --size 2",
             "heatmap " + cube + " -o " + png + " --obb best",
             "heatmap " + cube + " -o " + png + " --coarse 8 --fine 16",
             "heatmap " + asset + " -o " + png,
             "heatmap " + scene + " -o /dev/null",
             "report " + cube,
             "report " + cube + " -o " + dir + " --method kmeans,nope",
             "report " + cube + " -o " + dir + " --methods kmeans",
             "report " + cube + " -o " + dir + " --fine 16,86",
             "report " + cube + " -o " + dir + " --runs 0",
             "report " + cube + " -o " + dir + " --coarse 0",
             "report " + cube + " -o " + dir + " --coarse 12 --fine 8,16",
             "report " + cube + " -o " + dir + " --heatmap --heatmap-size 2",
             "report " + cube + " -o " + dir + " --heatmap-size 64",
             "report " + asset + " -o " + dir,
             "report " + scene + " -o /dev/null",
         }) {
        CliRun r = run(args);
        EXPECT_EQ(r.code, 2) << args << ": " << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << args << ": " << r.err;
        EXPECT_EQ(r.err.rfind("clusterbake: ", 0), 0u) << args << ": " << r.err;
        EXPECT_EQ(r.out, "") << args;
    }
    EXPECT_FALSE(std::filesystem::exists(dir));
    EXPECT_FALSE(std::filesystem::exists(png));
    std::filesystem::remove(asset);
    std::filesystem::remove(pts);
}

namespace {

// What `args` prints on stderr when stderr is a terminal: run under script(1), stdout thrown away.
std::string terminal_stderr(const std::string& args) {
    std::string cmd = "script -qec '" + std::string(CB_CLI) + " " + args + " 2>&1 >/dev/null' /dev/null";
    std::string out;
    FILE* pipe = popen(cmd.c_str(), "r");
    char buffer[4096];
    for (size_t n; pipe && (n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0;) out.append(buffer, n);
    if (pipe) pclose(pipe);
    return out;
}

}  // namespace

TEST(Cli, QuietSilencesProgressOnATerminal) {
    if (!std::filesystem::exists("/usr/bin/script"))
        GTEST_SKIP() << "script(1) is not installed: no terminal to show progress on";
    const std::string scene = data("default_scene.glb"), png = scratch("quiet.png").string();
    EXPECT_NE(terminal_stderr("stats " + scene).find("clustering and fitting"), std::string::npos);
    EXPECT_EQ(terminal_stderr("stats -q " + scene), "");
    EXPECT_NE(terminal_stderr("heatmap --size 32 -o " + png + " " + scene).find("heat map: kmeans panel"),
              std::string::npos);
    EXPECT_EQ(terminal_stderr("heatmap --size 32 -q -o " + png + " " + scene), "");
    std::filesystem::remove(png);
}

namespace {

std::string slurp_binary(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

}  // namespace

TEST(Cli, ExportGltfWritesAGlbAndItsSummary) {
    const std::string asset = scratch("export.cbk").string(), glb = scratch("export.glb").string();
    ASSERT_EQ(run("bake " + data("default_scene.glb") + " -o " + asset).code, 0);
    auto counts = nlohmann::json::parse(run("validate --json " + asset).out);

    CliRun r = run("export-gltf " + asset + " -o " + glb + " --boxes --cones --json");
    ASSERT_EQ(r.code, 0) << r.err;
    auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["tool"].get<std::string>().rfind("clusterbake ", 0), 0u);
    EXPECT_EQ(j["level"], "fine");
    EXPECT_EQ(j["clusters"], counts["fine_clusters"]);
    EXPECT_EQ(j["triangles"], counts["triangles"]);
    EXPECT_EQ(j["instances"], counts["instances"]);
    EXPECT_EQ(j["primitives"].get<size_t>(), j["clusters"].get<size_t>() + j["line_primitives"].get<size_t>());
    EXPECT_GT(j["line_primitives"].get<size_t>(), 0u);
    EXPECT_GT(j["cones"].get<size_t>(), 0u);
    EXPECT_GE(j["colours"].get<size_t>(), 3u);
    EXPECT_LE(j["colours"].get<size_t>(), 12u);
    std::string bytes = slurp_binary(glb);
    EXPECT_EQ(j["bytes"].get<size_t>(), bytes.size());
    EXPECT_EQ(bytes.substr(0, 4), "glTF");

    CliRun coarse = run("export-gltf " + asset + " -o " + glb + " --level coarse -q --json");
    ASSERT_EQ(coarse.code, 0) << coarse.err;
    EXPECT_EQ(coarse.err, "");
    EXPECT_EQ(nlohmann::json::parse(coarse.out)["clusters"], counts["coarse_clusters"]);
    CliRun plain = run("export-gltf " + asset + " -o " + glb);
    EXPECT_EQ(plain.code, 0);
    EXPECT_NE(plain.out.find(" -> " + glb + ": "), std::string::npos) << plain.out;
    std::filesystem::remove(asset);
    std::filesystem::remove(glb);
}

TEST(Cli, ExportGltfUsageErrorsWriteNothing) {
    const std::string asset = scratch("export_usage.cbk").string(), glb = scratch("export_usage.glb").string();
    ASSERT_EQ(run("bake " + data("small/cube.obj") + " -o " + asset).code, 0);  // boxes and cones only
    auto refused = [&](const std::string& args, const std::string& out, const std::string& says) {
        CliRun r = run("export-gltf " + args);
        EXPECT_EQ(r.code, 2) << args;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << args << ": " << r.err;
        EXPECT_NE(r.err.find(says), std::string::npos) << args << ": " << r.err;
        EXPECT_EQ(r.out, "") << args;
        EXPECT_FALSE(std::filesystem::exists(out)) << args;
    };
    refused(asset + " -o " + glb + " --level medium", glb, "--level takes fine or coarse");
    refused(asset + " -o " + glb + " --boxes=cube", glb, "--boxes takes");
    refused(asset + " -o " + glb + " --boxes=obb,sphere", glb, "no fine spheres");
    refused(asset + " -o " + glb + " --level coarse --boxes=capsule", glb, "no coarse capsules");
    refused(asset + " -o /nonexistent-folder/out.glb", "/nonexistent-folder/out.glb", "does not exist");
    const std::string gltf = scratch("export_usage.gltf").string();
    refused(asset + " -o " + gltf, gltf, "name it .glb");
    refused(scratch("missing.cbk").string() + " -o " + glb, glb, "cannot open");

    // A folder as the output: refused, and nothing is written into it.
    auto folder = scratch("export_folder");
    std::filesystem::create_directories(folder);
    CliRun dir = run("export-gltf " + asset + " -o " + folder.string());
    EXPECT_EQ(dir.code, 2);
    EXPECT_NE(dir.err.find("not a regular file"), std::string::npos) << dir.err;
    EXPECT_TRUE(std::filesystem::is_directory(folder));
    EXPECT_TRUE(std::filesystem::is_empty(folder));
    std::filesystem::remove_all(folder);

    // An asset at the output path is kept, unless --force.
    const std::string other = scratch("export_other.cbk").string();
    std::filesystem::copy_file(asset, other, std::filesystem::copy_options::overwrite_existing);
    const std::string before = slurp_binary(other);
    CliRun kept = run("export-gltf " + asset + " -o " + other);
    EXPECT_EQ(kept.code, 2);
    EXPECT_NE(kept.err.find("is a clusterbake asset"), std::string::npos) << kept.err;
    EXPECT_EQ(slurp_binary(other), before);
    EXPECT_EQ(run("export-gltf " + asset + " -o " + other + " --force").code, 0);
    EXPECT_EQ(slurp_binary(other).substr(0, 4), "glTF");
    std::filesystem::remove(other);
    std::filesystem::remove(asset);
}

TEST(Cli, EveryCommandGivesTheLibrariesTextForABrokenRule) {
    const std::string cube = data("small/cube.obj"), out = scratch("rules.cbk").string();
    const std::string png = scratch("rules.png").string(), dir = scratch("rules_batch").string();
    const std::string fine_text =
        "clusterbake: --fine must be at most 85 (a fine cluster's corners must fit the asset's 8-bit local indices)\n";
    for (const std::string& command : {"bake " + cube + " -o " + out, "cluster " + cube + " -o " + out, "stats " + cube,
                                       "batch " + cube + " -o " + dir, "heatmap " + cube + " -o " + png}) {
        CliRun fine = run(command + " --fine 86");
        EXPECT_EQ(fine.code, 2) << command;
        EXPECT_EQ(fine.err, fine_text) << command;
        CliRun coarse = run(command + " --coarse 8 --fine 16");
        EXPECT_EQ(coarse.code, 2) << command;
        EXPECT_EQ(coarse.err, "clusterbake: --coarse must be at least --fine\n") << command;
    }
    CliRun k0 = run("bake " + cube + " -o " + out + " --k0 1");
    EXPECT_EQ(k0.err, "clusterbake: --k0 must be at least 2 (children per k-means node)\n");
    CliRun cache = run("cluster " + cube + " -o " + out + " --method vco --cache 2");
    EXPECT_EQ(cache.err, "clusterbake: --cache must be at least 3 (a triangle's corners)\n");
    CliRun ratio = run("bake " + cube + " -o " + out + " --capsule-ratio 0.5");
    EXPECT_EQ(ratio.err, "clusterbake: --capsule-ratio must be a finite number of at least 1\n");
    CliRun number = run("bake " + cube + " -o " + out + " --coarse many");
    EXPECT_EQ(number.err, "clusterbake: --coarse takes a whole number from 0 to 4294967295 (got 'many')\n");
    CliRun sweep = run("report " + cube + " -o " + scratch("rules_report").string() + " --coarse 12 --fine 8,16");
    EXPECT_EQ(sweep.err, "clusterbake: the sweep's --coarse 12 --fine 16: --coarse must be at least --fine\n");
    // A manifest line's options keep the same rules, named with the line.
    const std::filesystem::path folder = scratch("rules_manifest");
    std::filesystem::create_directories(folder);
    std::filesystem::copy_file(cube, folder / "cube.obj", std::filesystem::copy_options::overwrite_existing);
    const std::string manifest = (folder / "list.txt").string();
    std::ofstream(manifest) << "cube.obj --fine 0\n";
    EXPECT_EQ(run("batch " + manifest + " -o " + dir).err,
              "clusterbake: " + manifest + ": line 1: --fine must be at least 1\n");
    std::ofstream(manifest) << "cube.obj --fine 8 --fine 9\n";
    EXPECT_EQ(run("batch " + manifest + " -o " + dir).err,
              "clusterbake: " + manifest + ": line 1: --fine is given twice\n");
    std::ofstream(manifest) << "cube.obj --jobs 3\n";
    EXPECT_EQ(run("batch " + manifest + " -o " + dir).err,
              "clusterbake: " + manifest + ": line 1: --jobs is not a bake option\n");
    EXPECT_FALSE(std::filesystem::exists(out));
    EXPECT_FALSE(std::filesystem::exists(png));
    EXPECT_FALSE(std::filesystem::exists(dir));
    std::filesystem::remove_all(folder);
}
