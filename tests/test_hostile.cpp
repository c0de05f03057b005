// Untrusted scenes (docs/SECURITY.md): the hostile corpus of fuzz/hostile_corpus.h, written here, each file
// run through the command-line tool in a child process whose time and peak memory are measured; then a batch
// over them beside good files, and batches in which a file's bake dies or runs over its memory budget.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "../fuzz/hostile_corpus.h"

namespace fs = std::filesystem;

namespace {

struct Child {
    int code = -1;  // exit code, -1 when killed by a signal
    std::string err;
    double seconds = 0;       // the child's CPU time, user and system: other tests share the cores
    uint64_t peak_bytes = 0;  // the child's own peak resident size
};

// Starts clusterbake with `args`, its standard output to /dev/null and its standard error to
// scratch/stderr.txt. fork, not posix_spawn's vfork: a child that shares this process's memory until exec
// would inherit its high-water mark.
pid_t start_tool(const std::vector<std::string>& args, const fs::path& scratch) {
    std::vector<std::string> words = {CB_CLI};
    words.insert(words.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& w : words) argv.push_back(w.data());
    argv.push_back(nullptr);
    const std::string err_path = (scratch / "stderr.txt").string();
    const pid_t pid = fork();
    if (pid == 0) {
        const int out = open("/dev/null", O_WRONLY), err = open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        dup2(out, 1);
        dup2(err, 2);
        execv(argv[0], argv.data());
        _exit(127);
    }
    return pid;
}

// Waits for the tool started in `scratch` and measures it alone: wait4 gives this child's figures, not the
// sum over every child so far.
Child wait_tool(pid_t pid, const fs::path& scratch) {
    Child c;
    if (pid < 0) return c;
    int status = 0;
    struct rusage usage {};
    wait4(pid, &status, 0, &usage);
    c.seconds = double(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
        1e-6 * double(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
    c.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    c.peak_bytes = uint64_t(usage.ru_maxrss) * 1024;
    std::ifstream in(scratch / "stderr.txt");
    c.err.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    return c;
}

// Runs clusterbake with `args` to its end.
Child run_tool(const std::vector<std::string>& args, const fs::path& scratch) {
    return wait_tool(start_tool(args, scratch), scratch);
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

// The process that holds `fifo` open, a child of `parent`; 0 while there is none.
pid_t child_holding(const fs::path& fifo, pid_t parent) {
    std::error_code ec;
    for (fs::directory_iterator proc("/proc", ec), end; !ec && proc != end; proc.increment(ec)) {
        const std::string pid = proc->path().filename().string();
        if (pid.find_first_not_of("0123456789") != std::string::npos) continue;
        std::ifstream stat_file(proc->path() / "stat");
        const std::string stat((std::istreambuf_iterator<char>(stat_file)), std::istreambuf_iterator<char>());
        const size_t command_end = stat.rfind(')');  // "PID (COMMAND) STATE PPID ...": the command may hold ')'
        if (command_end == std::string::npos) continue;
        std::istringstream fields(stat.substr(command_end + 1));
        std::string state;
        long ppid = 0;
        if (!(fields >> state >> ppid) || ppid != parent) continue;
        std::error_code fd_ec;
        for (fs::directory_iterator fd(proc->path() / "fd", fd_ec), fds_end; !fd_ec && fd != fds_end;
             fd.increment(fd_ec)) {
            std::error_code link_ec;
            if (fs::read_symlink(fd->path(), link_ec) == fifo) return pid_t(std::stol(pid));
        }
    }
    return 0;
}

// Opens `fifo` for writing (in `writer`) once a bake of the batch `batch` has opened it to read it, and
// returns that bake's process, which then waits in read() until this end is written to or closed, however
// loaded the machine: nothing here depends on timing. -1 when the batch ended first, or after minutes.
pid_t bake_waiting_on(const fs::path& fifo, pid_t batch, int& writer) {
    for (int tries = 0; tries < 12000; ++tries) {
        if (writer < 0) writer = open(fifo.c_str(), O_WRONLY | O_NONBLOCK);  // ENXIO until a reader opens it
        if (writer >= 0)
            if (const pid_t pid = child_holding(fifo, batch)) return pid;
        siginfo_t ended{};
        if (waitid(P_PID, id_t(batch), &ended, WEXITED | WNOHANG | WNOWAIT) == 0 && ended.si_pid == batch) return -1;
        usleep(10000);
    }
    return -1;
}

std::string read_text(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Each good file's output in `out` holds what a `clusterbake bake` of it alone writes.
void expect_single_bakes(const fs::path& base, const fs::path& in, const std::vector<std::string>& good,
                         const fs::path& out) {
    fs::create_directories(base / "single");
    for (const std::string& g : good) {
        SCOPED_TRACE(g);
        const std::string asset = fs::path(g).replace_extension(".cbk").string();
        Child c = run_tool({"bake", (in / g).string(), "-o", (base / "single" / asset).string(), "-q"}, base);
        ASSERT_EQ(c.code, 0) << c.err;
        EXPECT_EQ(read_text(out / asset), read_text(base / "single" / asset));
    }
}

// summary.json's records by name.
std::map<std::string, nlohmann::json> summary_files(const fs::path& out) {
    std::ifstream in(out / "summary.json");
    std::map<std::string, nlohmann::json> files;
    if (!in) return files;
    const nlohmann::json summary = nlohmann::json::parse(in);
    for (const nlohmann::json& f : summary["files"]) files[f["name"].get<std::string>()] = f;
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

// A bake that dies, whatever kills it, fails its file alone: the batch reports it in one line and bakes the
// others. Two of the scene files are named pipes, so that their bakes wait, the file opened, for this test
// to send each a real signal: SIGSEGV as a loader's crash would, SIGKILL as the out-of-memory killer does.
TEST(Hostile, ABatchOutlivesFilesWhoseBakeDies) {
    const fs::path base = fresh("dies");
    const std::vector<std::string> good = {"cube.obj", "cube_binary.ply", "primitive_modes.gltf", "cube_ascii.stl"};
    fs::create_directories(base / "in");
    fs::create_directories(base / "pipes");
    for (const std::string& g : good) fs::copy_file(std::string(CB_SOURCE_DIR) + "/data/small/" + g, base / "in" / g);
    const fs::path crash = base / "pipes/crash.obj", killed = base / "pipes/killed.obj";
    ASSERT_EQ(mkfifo(crash.c_str(), 0600), 0);
    ASSERT_EQ(mkfifo(killed.c_str(), 0600), 0);
    // What the crashing file's output held before: a bake that dies leaves it as it was.
    fs::create_directories(base / "out");
    std::ofstream(base / "out/crash.cbk") << "what was there";

    const pid_t batch = start_tool(
        {"batch", (base / "in").string(), crash.string(), killed.string(), "-o", (base / "out").string(), "-j", "2"},
        base);
    ASSERT_GT(batch, 0);
    int writer = -1;
    const pid_t crashing = bake_waiting_on(crash, batch, writer);
    if (crashing > 0) kill(crashing, SIGSEGV);
    close(writer);
    writer = -1;
    const pid_t dying = bake_waiting_on(killed, batch, writer);
    // The temporary a bake names in the instant before it renames it over its output, as a kill then leaves it.
    const fs::path left = base / ("out/killed.cbk.tmp" + std::to_string(dying));
    if (dying > 0) {
        std::ofstream(left) << "half an asset";
        kill(dying, SIGKILL);
    }
    close(writer);
    if (crashing <= 0 || dying <= 0) kill(batch, SIGKILL);  // its bakes die with it
    const Child c = wait_tool(batch, base);
    ASSERT_GT(crashing, 0) << "no bake opened " << crash << c.err;
    ASSERT_GT(dying, 0) << "no bake opened " << killed << c.err;

    EXPECT_EQ(c.code, 2) << c.err;  // some files failed; the batch itself did not die
    std::map<std::string, nlohmann::json> files = summary_files(base / "out");
    ASSERT_EQ(files.size(), good.size() + 2) << c.err;
    const std::string crash_line = crash.string() + ": the bake was killed by signal 11 (SIGSEGV)";
    const std::string kill_line = killed.string() + ": the bake was killed by signal 9 (SIGKILL)";
    EXPECT_EQ(files["crash.obj"]["status"], "failed");
    EXPECT_EQ(files["crash.obj"]["error"], crash_line);
    EXPECT_EQ(files["killed.obj"]["status"], "failed");
    EXPECT_EQ(files["killed.obj"]["error"], kill_line);
    EXPECT_NE(c.err.find("failed      " + crash_line + "\n"), std::string::npos) << c.err;
    EXPECT_NE(c.err.find("failed      " + kill_line + "\n"), std::string::npos) << c.err;
    EXPECT_EQ(read_text(base / "out/crash.cbk"), "what was there");
    EXPECT_FALSE(fs::exists(base / "out/killed.cbk"));
    EXPECT_FALSE(fs::exists(left)) << "the dead bake's temporary is left";
    for (const std::string& g : good) EXPECT_EQ(files[g]["status"], "baked") << g << ": " << files[g]["error"];
    expect_single_bakes(base, base / "in", good, base / "out");
    fs::remove_all(base);
}

// The memory budget is also a hard limit on each file's process: a file whose load really takes more than
// it (an OBJ grid of 640,000 quads holds some 50 MB while it is read, over a budget of 1 MiB and the 16 MiB
// margin) fails with one line, and the good files beside it bake. Its manifest line gives it one thread, so
// that no helper thread's stack is added to its limit, whatever the machine's core count.
TEST(Hostile, AFileOverItsMemoryBudgetFailsAloneInABatch) {
    const fs::path base = fresh("limit");
    const std::vector<std::string> good = {"cube.obj", "cube_binary.ply", "primitive_modes.gltf"};
    fs::create_directories(base / "in");
    for (const std::string& g : good) fs::copy_file(std::string(CB_SOURCE_DIR) + "/data/small/" + g, base / "in" / g);
    {
        std::ofstream grid(base / "in/grid.obj");
        const int n = 800;
        for (int j = 0; j <= n; ++j)
            for (int i = 0; i <= n; ++i) grid << "v " << i << ' ' << j << " 0\n";
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const int a = j * (n + 1) + i + 1;
                grid << "f " << a << ' ' << a + 1 << ' ' << a + n + 2 << ' ' << a + n + 1 << '\n';
            }
    }
    std::ofstream(base / "in/list.txt") << "grid.obj --threads 1\ncube.obj\ncube_binary.ply\nprimitive_modes.gltf\n";
    const std::string grid = (base / "in/grid.obj").string();
    const std::string line = grid + ": out of memory while loading: over the memory budget of 1 MiB (--memory-budget)";

    Child c = run_tool({"batch", (base / "in/list.txt").string(), "-o", (base / "out").string(), "--memory-budget",
                        "1MB", "-j", "2", "-q"},
                       base);
    EXPECT_EQ(c.code, 2) << c.err;
    std::map<std::string, nlohmann::json> files = summary_files(base / "out");
    ASSERT_EQ(files.size(), good.size() + 1) << c.err;
    EXPECT_EQ(files["grid.obj"]["status"], "failed");
    EXPECT_EQ(files["grid.obj"]["error"], line);
    EXPECT_FALSE(fs::exists(base / "out/grid.cbk"));
    for (const std::string& g : good) EXPECT_EQ(files[g]["status"], "baked") << g << ": " << files[g]["error"];
    expect_single_bakes(base, base / "in", good, base / "out");

    // `bake` holds a file to the same limit: it fails alone as in a batch.
    c = run_tool({"bake", grid, "-o", (base / "grid.cbk").string(), "--memory-budget", "1MB", "--threads", "1"}, base);
    EXPECT_EQ(c.code, 2);
    EXPECT_EQ(c.err, line + "\n");
    EXPECT_FALSE(fs::exists(base / "grid.cbk"));
    fs::remove_all(base);
}
