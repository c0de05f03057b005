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
    for (const char* traversal : {"trees", "one-tree"})  // the other traversals: the same answers
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
