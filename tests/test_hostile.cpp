// Untrusted scenes (docs/SECURITY.md): the hostile corpus of fuzz/hostile_corpus.h, written here, each file
// run through the command-line tool in a child process whose time and peak memory are measured; then a batch
// over them beside good files.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>

#include "../fuzz/hostile_corpus.h"

namespace fs = std::filesystem;

namespace {

struct Child {
    int code = -1;  // exit code, -1 when killed by a signal
    std::string err;
    double seconds = 0;       // the child's CPU time, user and system: other tests share the cores
    uint64_t peak_bytes = 0;  // the child's own peak resident size
};

// Runs clusterbake with `args`, its standard error to a file, and measures it alone: wait4 gives this
// child's figures, not the sum over every child so far. fork, not posix_spawn's vfork: a child that shares
// this process's memory until exec would inherit its high-water mark.
Child run_tool(const std::vector<std::string>& args, const fs::path& scratch) {
    std::vector<std::string> words = {CB_CLI};
    words.insert(words.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& w : words) argv.push_back(w.data());
    argv.push_back(nullptr);
    const std::string err_path = (scratch / "stderr.txt").string();
    Child c;
    const pid_t pid = fork();
    if (pid < 0) return c;
    if (pid == 0) {
        const int out = open("/dev/null", O_WRONLY), err = open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        dup2(out, 1), dup2(err, 2);
        execv(argv[0], argv.data());
        _exit(127);
    }
    int status = 0;
    struct rusage usage {};
    wait4(pid, &status, 0, &usage);
    c.seconds = double(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
        1e-6 * double(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
    c.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    c.peak_bytes = uint64_t(usage.ru_maxrss) * 1024;
    std::ifstream in(err_path);
    c.err.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    return c;
}

// Writes the corpus from a child process, so that the documents it builds never swell this one (whose
// resident size the tool's children start from); the child lists the files in outside/listing.txt.
std::vector<cb::hostile::File> write_corpus(const fs::path& dir, const fs::path& outside) {
    const pid_t pid = fork();
    if (pid == 0) {
        std::vector<cb::hostile::File> files = cb::hostile::write_corpus(dir, outside);
        std::ofstream listing(outside / "listing.txt");
        for (const cb::hostile::File& f : files) listing << f.name << '\t' << f.expect << '\n';
        listing.close();  // _exit runs no destructor
        _exit(listing ? 0 : 1);
    }
    int status = 0;
    waitpid(pid, &status, 0);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    std::vector<cb::hostile::File> files;
    std::ifstream listing(outside / "listing.txt");
    for (std::string line; std::getline(listing, line);) {
        const size_t tab = line.find('\t');
        files.push_back({line.substr(0, tab), line.substr(tab + 1)});
    }
    return files;
}

// A fresh folder for this test: the corpus in base/corpus, its targets in base/outside.
fs::path fresh(const std::string& name) {
    fs::path base = fs::temp_directory_path() / ("cb_hostile_" + name + "_" + std::to_string(getpid()));
    fs::remove_all(base);
    fs::create_directories(base);
    return base;
}

}  // namespace

TEST(Hostile, EveryFileIsRefusedInOneLineQuicklyAndInLittleMemory) {
    const fs::path base = fresh("each");
    const std::vector<cb::hostile::File> files = write_corpus(base / "corpus", base / "outside");
    ASSERT_GE(files.size(), 20u);
    for (const cb::hostile::File& f : files) {
        SCOPED_TRACE(f.name);
        const std::string path = (base / "corpus" / f.name).string();
        Child c = run_tool({"info", path}, base);
        std::printf("%-36s exit %d  %.3f s CPU  %5.1f MB\n", f.name.c_str(), c.code, c.seconds, c.peak_bytes / 1e6);
        EXPECT_LT(c.seconds, 1.0);
        EXPECT_LT(c.peak_bytes, uint64_t(100) << 20);
        if (f.expect.empty()) {
            EXPECT_EQ(c.code, 0) << c.err;
            continue;
        }
        EXPECT_EQ(c.code, 2) << c.err;
        ASSERT_FALSE(c.err.empty());
        EXPECT_EQ(c.err.find('\n'), c.err.size() - 1) << "one line: " << c.err;
        EXPECT_EQ(c.err.rfind(path + ": ", 0), 0u) << "names the file: " << c.err;
        EXPECT_NE(c.err.find(f.expect), std::string::npos) << c.err;
    }
    fs::remove_all(base);
}

TEST(Hostile, OutsideFilesAreReadOnlyWhenAllowed) {
    const fs::path base = fresh("allow");
    write_corpus(base / "corpus", base / "outside");
    for (const char* name : {"escape_dotdot", "escape_percent", "escape_absolute"}) {
        SCOPED_TRACE(name);
        const std::string path = (base / "corpus/gltf" / (std::string(name) + ".gltf")).string();
        EXPECT_EQ(run_tool({"info", path}, base).code, 2);
        Child allowed = run_tool({"info", "--allow-outside-files", path}, base);
        EXPECT_EQ(allowed.code, 0) << allowed.err;
    }
    // Every command that loads scenes takes the same flag, and refuses the same escape without it.
    const std::string escape = (base / "corpus/gltf/escape_dotdot.gltf").string();
    const std::vector<std::vector<std::string>> commands = {
        {"stats", escape},
        {"heatmap", escape, "-o", (base / "heat.png").string(), "--size", "32", "-q"},
        {"report", escape, "-o", (base / "report").string(), "--method", "kmeans", "--fine", "8", "--obb", "pca",
         "--runs", "1", "--query-runs", "1", "-q"}};
    for (std::vector<std::string> command : commands) {
        SCOPED_TRACE(command[0]);
        Child refused = run_tool(command, base);
        EXPECT_EQ(refused.code, 2);
        EXPECT_NE(refused.err.find("leads out of the scene's folder"), std::string::npos) << refused.err;
        command.insert(command.begin() + 1, "--allow-outside-files");
        Child allowed = run_tool(command, base);
        EXPECT_EQ(allowed.code, 0) << allowed.err;
    }
    // Inside its own folder a buffer is read as always, also through a folder of its own.
    const std::string inside = (base / "corpus/gltf/inside.gltf").string();
    fs::create_directories(base / "corpus/gltf/buffers");
    fs::copy_file(base / "outside/secret.bin", base / "corpus/gltf/buffers/tri.bin");
    std::ofstream(inside) << cb::hostile::detail::triangle_gltf("buffers/tri.bin").dump();
    Child c = run_tool({"info", inside}, base);
    EXPECT_EQ(c.code, 0) << c.err;
    fs::remove_all(base);
}

TEST(Hostile, AMemoryBudgetTurnsABigSceneIntoACleanFailure) {
    const fs::path base = fresh("budget");
    write_corpus(base / "corpus", base / "outside");
    // The 20,000-deep chain's 20,000 instances fit the default; a cube does not fit a kilobyte.
    const std::string path = (base / "corpus/gltf/deep_chain.gltf").string();
    EXPECT_EQ(run_tool({"bake", path, "-o", (base / "chain.cbk").string(), "-q"}, base).code, 0);
    const std::string cube = std::string(CB_SOURCE_DIR) + "/data/small/cube.obj";
    Child c = run_tool({"bake", cube, "-o", (base / "cube.cbk").string(), "--memory-budget", "1kb", "-q"}, base);
    EXPECT_EQ(c.code, 2);
    EXPECT_NE(c.err.find("over the memory budget of 1 KiB (--memory-budget)"), std::string::npos) << c.err;
    EXPECT_FALSE(fs::exists(base / "cube.cbk"));
    fs::remove_all(base);
}

TEST(Hostile, ABatchOverThemBakesTheGoodFilesBesideThem) {
    const fs::path base = fresh("batch");
    const std::vector<cb::hostile::File> files = write_corpus(base / "in", base / "outside");
    const std::vector<std::string> good = {"cube.obj", "cube_binary.ply", "primitive_modes.gltf", "cube_ascii.stl"};
    for (const std::string& g : good)
        fs::copy_file(std::string(CB_SOURCE_DIR) + "/data/small/" + g, base / "in" / ("good_" + g));
    // A scene below the input root that is a symbolic link to one outside it.
    std::ofstream(base / "outside/scene.gltf")
        << cb::hostile::detail::triangle_gltf(cb::hostile::detail::data_uri(cb::hostile::detail::triangle_bytes()))
               .dump();
    std::error_code ec;
    fs::create_symlink(base / "outside/scene.gltf", base / "in/linked.gltf", ec);
    Child c = run_tool({"batch", (base / "in").string(), "-o", (base / "out").string(), "-j", "2", "-q"}, base);
    EXPECT_EQ(c.code, 2) << c.err;  // some failed; the process itself did not die
    std::ifstream in(base / "out/summary.json");
    ASSERT_TRUE(in) << c.err;
    nlohmann::json summary = nlohmann::json::parse(in);
    std::map<std::string, std::string> status, error;
    for (const auto& f : summary["files"]) {
        status[f["name"]] = f["status"];
        error[f["name"]] = f["error"];
    }
    for (const std::string& g : good) {
        EXPECT_EQ(status["good_" + g], "baked") << g << ": " << error["good_" + g];
        EXPECT_TRUE(fs::exists(base / "out" / ("good_" + fs::path(g).stem().string() + ".cbk"))) << g;
    }
    if (!ec) {
        EXPECT_NE(error["linked.gltf"].find("refused: a symbolic link leads out of the input root"), std::string::npos)
            << error["linked.gltf"];
    }
    for (const cb::hostile::File& f : files) {
        SCOPED_TRACE(f.name);
        EXPECT_EQ(status[f.name], f.expect.empty() ? "baked" : "failed");
        if (!f.expect.empty()) {
            EXPECT_NE(error[f.name].find(f.expect), std::string::npos) << error[f.name];
        }
    }
    fs::remove_all(base);
}
