// Batch baking: the plan (inputs to jobs and mirrored outputs), the source section that makes bakes
// incremental, bake_file's statuses, and the shared cores.
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <future>
#include <sstream>
#include <thread>

#include "asset_file.h"
#include "bake_file.h"
#include "bake_options.h"
#include "core_budget.h"
#include "load.h"
#include "parallel.h"
#include "plan.h"
#include "run.h"
#include "source_files.h"

namespace fs = std::filesystem;

namespace {

fs::path fresh_dir(const std::string& name) {
    fs::path d = fs::temp_directory_path() / ("cb_batch_" + name + "_" + std::to_string(getpid()));
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

void write(const fs::path& p, const std::string& text) {
    fs::create_directories(p.parent_path());
    std::ofstream(p, std::ios::binary) << text;
}

std::string read(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

fs::path small(const std::string& f) { return fs::path(CB_SOURCE_DIR) / "data" / "small" / f; }

std::vector<std::string> names(const std::vector<cb::BatchJob>& jobs) {
    std::vector<std::string> out;
    for (const cb::BatchJob& j : jobs) out.push_back(j.name);
    return out;
}

// A one-triangle glTF whose positions live in an external buffer, tri.bin.
void write_gltf_with_buffer(const fs::path& dir, float z) {
    write(dir / "tri.gltf",
          R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],)"
          R"("meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],)"
          R"("accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,1]}],)"
          R"("bufferViews":[{"buffer":0,"byteLength":36}],"buffers":[{"byteLength":36,"uri":"tri.bin"}]})");
    float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, z};
    write(dir / "tri.bin", std::string(reinterpret_cast<const char*>(p), sizeof p));
}

}  // namespace

TEST(BatchPlan, ManifestFieldsSplitOnBlanksWithQuotesAndComments) {
    EXPECT_EQ(cb::manifest_fields("  a/b.glb  --fine 8\t--bounds all\r"),
              (std::vector<std::string>{"a/b.glb", "--fine", "8", "--bounds", "all"}));
    EXPECT_EQ(cb::manifest_fields("\"my scene.obj\" --obb 'pca'"),
              (std::vector<std::string>{"my scene.obj", "--obb", "pca"}));
    EXPECT_TRUE(cb::manifest_fields("   # a comment").empty());
    EXPECT_TRUE(cb::manifest_fields("").empty());
    EXPECT_THROW(cb::manifest_fields("\"open.obj"), cb::PlanError);
}

TEST(BatchPlan, FoldersAreWalkedAndMirroredIntoTheOutputTree) {
    fs::path d = fresh_dir("folders");
    fs::create_directories(d / "lib" / "a" / "b");
    fs::copy_file(small("cube.obj"), d / "lib" / "cube.obj");
    fs::copy_file(small("cube.obj"), d / "lib" / "a" / "b" / "x.obj");
    fs::copy_file(small("cube_binary.stl"), d / "lib" / "y.STL");
    write(d / "lib" / "notes.txt", "not a scene");
    std::vector<cb::BatchJob> jobs = cb::plan_batch({(d / "lib").string()}, (d / "out").string());
    EXPECT_EQ(names(jobs), (std::vector<std::string>{"a/b/x.obj", "cube.obj", "y.STL"}));
    EXPECT_EQ(jobs[0].output, (d / "out" / "a" / "b" / "x.cbk").string());
    EXPECT_EQ(jobs[0].input, (d / "lib" / "a" / "b" / "x.obj").string());
    EXPECT_EQ(jobs[2].output, (d / "out" / "y.cbk").string());
    EXPECT_EQ(jobs[0].input_size, fs::file_size(small("cube.obj")));

    // A file named on its own is its own root; named again inside a folder, it is still one job.
    jobs = cb::plan_batch({(d / "lib" / "y.STL").string(), (d / "lib").string()}, (d / "out").string());
    EXPECT_EQ(names(jobs), (std::vector<std::string>{"a/b/x.obj", "cube.obj", "y.STL"}));

    EXPECT_THROW(cb::plan_batch({(d / "missing").string()}, "out"), cb::PlanError);
    fs::create_directories(d / "empty");
    EXPECT_THROW(cb::plan_batch({(d / "empty").string()}, "out"), cb::PlanError);
    fs::remove_all(d);
}

TEST(BatchPlan, ManifestLinesCarryTheirOwnOptions) {
    fs::path d = fresh_dir("manifest");
    fs::create_directories(d / "lib" / "a");
    fs::copy_file(small("cube.obj"), d / "lib" / "a" / "x.obj");
    fs::copy_file(small("cube.off"), d / "lib" / "z.off");
    write(d / "lib" / "list.txt", "# scenes\n\na/x.obj --fine 8 --bounds all\n  z.off\n");
    std::vector<cb::BatchJob> jobs = cb::plan_batch({(d / "lib" / "list.txt").string()}, (d / "out").string());
    ASSERT_EQ(names(jobs), (std::vector<std::string>{"a/x.obj", "z.off"}));
    EXPECT_EQ(jobs[0].args, (std::vector<std::string>{"--fine", "8", "--bounds", "all"}));
    EXPECT_EQ(jobs[0].origin, (d / "lib" / "list.txt").string() + ": line 3");
    EXPECT_TRUE(jobs[1].args.empty());
    EXPECT_EQ(jobs[1].output, (d / "out" / "z.cbk").string());

    // From standard input, relative to the working directory.
    std::istringstream in((d / "lib" / "z.off").string() + "\n");
    fs::path cwd = fs::current_path();
    fs::current_path(d / "lib");
    jobs = cb::plan_batch({"-"}, "out", &in);
    fs::current_path(cwd);
    ASSERT_EQ(names(jobs), (std::vector<std::string>{"z.off"}));

    auto error_of = [&](const std::string& manifest) {
        write(d / "lib" / "bad.txt", manifest);
        try {
            cb::plan_batch({(d / "lib" / "bad.txt").string()}, "out");
        } catch (const cb::PlanError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    std::string bad = (d / "lib" / "bad.txt").string();
    EXPECT_EQ(error_of("z.off\n../x.obj\n"),
              bad + ": line 2: ../x.obj is outside the manifest's folder, so no output path mirrors it");
    EXPECT_EQ(error_of("notes.txt\n"),
              bad + ": line 1: notes.txt is not a scene file (.gltf .glb .obj .ply .off .stl)");
    EXPECT_EQ(error_of("'z.off\n"), bad + ": line 1: unclosed quote");
    fs::remove_all(d);
}

TEST(BatchPlan, TwoInputsThatWouldWriteOneOutputAreRefused) {
    fs::path d = fresh_dir("collide");
    fs::create_directories(d / "lib");
    fs::copy_file(small("cube.obj"), d / "lib" / "s.obj");
    fs::copy_file(small("cube.off"), d / "lib" / "s.off");
    try {
        cb::plan_batch({(d / "lib").string()}, (d / "out").string());
        FAIL() << "no error";
    } catch (const cb::PlanError& e) {
        EXPECT_EQ(std::string(e.what()),
                  (d / "lib" / "s.obj").string() + " and " + (d / "lib" / "s.off").string() + " would both write " +
                      (d / "out" / "s.cbk").string());
    }
    fs::remove_all(d);
}

TEST(BatchSource, OptionsTextNamesWhatShapesTheAssetAndNotTheThreads) {
    cb::BakeRequest one, seven;
    seven.threads = 7;
    EXPECT_EQ(cb::options_argv(one), cb::options_argv(seven));
    cb::ClusterOptions a, b;
    cb::BoundsOptions bounds;
    b.fine_size = 8;
    EXPECT_NE(cb::options_text(a, bounds, true), cb::options_text(b, bounds, true));
    EXPECT_NE(cb::options_text(a, bounds, true), cb::options_text(a, bounds, false));
    cb::BoundsOptions other = bounds;
    other.capsule_ratio = 2.5;
    EXPECT_NE(cb::options_text(a, bounds, true), cb::options_text(a, other, true));
    EXPECT_EQ(cb::options_text(a, bounds, false).find("--bounds"), std::string::npos);
    // Only the method's own options: another method's would be refused on a bake command line.
    EXPECT_EQ(cb::options_text(a, bounds, true).find("--cache"), std::string::npos);
    b = a;
    b.vco_cache_size = 16;
    EXPECT_EQ(cb::options_text(a, bounds, true), cb::options_text(b, bounds, true));
    b.method = cb::ClusterMethod::vco;
    EXPECT_NE(cb::options_text(b, bounds, true).find("--method vco --coarse 2048 --fine 16 --cache 16 --bounds"),
              std::string::npos)
        << cb::options_text(b, bounds, true);
    b.method = cb::ClusterMethod::morton;
    EXPECT_EQ(cb::options_text(b, bounds, true).find("--seed"), std::string::npos);
    a.kmeans_coarse_from_tree = false;
    EXPECT_NE(cb::options_text(a, bounds, true).find("--iterations 16 --coarse-morton --bounds"), std::string::npos);
}

TEST(BatchSource, TheHashCoversExternalBuffersAndMatchesARehash) {
    fs::path d = fresh_dir("source");
    write_gltf_with_buffer(d, 1);
    cb::Scene scene = cb::load_scene((d / "tri.gltf").string());
    const cb::SourceFiles& s = scene.report.source;
    EXPECT_EQ(s.names, (std::vector<std::string>{"tri.gltf", "tri.bin"}));
    EXPECT_EQ(s.bytes, fs::file_size(d / "tri.gltf") + 36);
    EXPECT_EQ(s.hash.size(), 32u);
    cb::SourceFiles again;
    std::string error;
    ASSERT_TRUE(cb::hash_source_files((d / "tri.gltf").string(), s.names, again, error)) << error;
    EXPECT_EQ(again.hash, s.hash);

    write_gltf_with_buffer(d, 2);  // the same JSON, another buffer
    ASSERT_TRUE(cb::hash_source_files((d / "tri.gltf").string(), s.names, again, error)) << error;
    EXPECT_NE(again.hash, s.hash);
    EXPECT_EQ(cb::load_scene((d / "tri.gltf").string()).report.source.hash, again.hash);

    fs::remove(d / "tri.bin");
    EXPECT_FALSE(cb::hash_source_files((d / "tri.gltf").string(), s.names, again, error));
    EXPECT_EQ(error.find((d / "tri.bin").string() + ": cannot open"), 0u) << error;
    fs::remove_all(d);
}

// A large file is mapped (its pages mapped in by one thread or in parts by several), a small one read and a
// pipe read in blocks: the same bytes each way, and one FileBytes read again holds the new file's bytes alone.
TEST(BatchSource, FileBytesAreTheFilesWhetherMappedReadOrPiped) {
    fs::path d = fresh_dir("bytes");
    std::string large((9u << 20) + 12345, '\0'), little = "ply\nformat ascii 1.0\n";
    for (size_t i = 0; i < large.size(); ++i) large[i] = char((i * 2654435761u) >> 13);
    write(d / "large.bin", large);
    write(d / "little.bin", little);
    cb::FileBytes bytes;
    std::string error;
    auto text = [&] { return std::string(reinterpret_cast<const char*>(bytes.data()), bytes.size()); };
    ASSERT_TRUE(bytes.read((d / "large.bin").string(), error)) << error;
    EXPECT_EQ(text(), large);
    for (unsigned threads : {2u, 3u}) {
        ASSERT_TRUE(bytes.read((d / "large.bin").string(), error, threads)) << error;
        EXPECT_EQ(text(), large) << threads << " threads";
    }
    ASSERT_TRUE(bytes.read((d / "little.bin").string(), error)) << error;
    EXPECT_EQ(text(), little);
    ASSERT_TRUE(bytes.read((d / "large.bin").string(), error)) << error;
    EXPECT_EQ(text(), large);

    const fs::path fifo = d / "pipe";
    ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
    std::thread writer([&] { std::ofstream(fifo, std::ios::binary) << large; });
    const bool read_pipe = bytes.read(fifo.string(), error);
    writer.join();
    ASSERT_TRUE(read_pipe) << error;
    EXPECT_EQ(text(), large);

    EXPECT_FALSE(bytes.read((d / "missing.bin").string(), error));
    EXPECT_EQ(error.find((d / "missing.bin").string() + ": cannot open"), 0u) << error;
    fs::remove_all(d);
}

TEST(BatchSource, BakeFileKeepsOnlyOutputsMadeFromTheSameInputsOptionsAndTool) {
    fs::path d = fresh_dir("incremental");
    write_gltf_with_buffer(d, 1);
    cb::BakeRequest r;
    r.input = (d / "tri.gltf").string();
    r.output = (d / "tri.cbk").string();
    r.if_changed = true;
    auto status = [&](const cb::BakeRequest& req) { return cb::bake_file(req).status; };

    cb::BakeResult first = cb::bake_file(r);
    ASSERT_EQ(first.status, cb::BakeStatus::baked) << first.error;
    std::string bytes = read(r.output);
    cb::BakeResult second = cb::bake_file(r);
    EXPECT_EQ(second.status, cb::BakeStatus::up_to_date);
    EXPECT_EQ(second.triangles, first.triangles);
    EXPECT_EQ(second.fine_clusters, first.fine_clusters);
    EXPECT_EQ(second.coarse_clusters, first.coarse_clusters);
    EXPECT_EQ(second.output_bytes, first.output_bytes);
    EXPECT_EQ(second.input_bytes, first.input_bytes);

    // The asset names what it was made from.
    cb::LoadedAsset asset;
    std::string error;
    ASSERT_TRUE(cb::read_asset_file(r.output, asset, error)) << error;
    std::string source(asset.view.source, asset.view.source_size);
    EXPECT_EQ(source.find(std::string(cb::tool_version()) + ", asset format 4, build " + cb::build_id() +
                          "\nbake --method kmeans"),
              0u)
        << source;
    EXPECT_NE(source.find("\nfile tri.gltf\nfile tri.bin\n"), std::string::npos) << source;

    cb::BakeRequest threads = r;
    threads.threads = 1;
    EXPECT_EQ(status(threads), cb::BakeStatus::up_to_date);
    cb::BakeRequest finer = r;
    finer.clustering.fine_size = 8;
    EXPECT_EQ(status(finer), cb::BakeStatus::baked);
    EXPECT_EQ(status(finer), cb::BakeStatus::up_to_date);
    EXPECT_EQ(status(r), cb::BakeStatus::baked);  // back to the first options
    EXPECT_EQ(read(r.output), bytes);

    write_gltf_with_buffer(d, 3);  // only the external buffer changes
    EXPECT_EQ(status(r), cb::BakeStatus::baked);
    EXPECT_NE(read(r.output), bytes);
    EXPECT_EQ(status(r), cb::BakeStatus::up_to_date);

    std::string good = read(r.output);  // a damaged output is baked again
    std::string damaged = good;
    damaged[damaged.size() / 2] ^= 1;
    write(r.output, damaged);
    EXPECT_EQ(status(r), cb::BakeStatus::baked);
    EXPECT_EQ(read(r.output), good);

    cb::BakeRequest always = r;
    always.if_changed = false;
    EXPECT_EQ(status(always), cb::BakeStatus::baked);
    fs::remove_all(d);
}

TEST(BatchSource, FailuresAreOneLineAndLeaveTheOutputAlone) {
    fs::path d = fresh_dir("failures");
    write(d / "old.cbk", "what was there");
    cb::BakeRequest r;
    r.input = (d / "missing.obj").string();
    r.output = (d / "old.cbk").string();
    cb::BakeResult missing = cb::bake_file(r);
    EXPECT_EQ(missing.status, cb::BakeStatus::failed);
    EXPECT_EQ(missing.error.find(r.input + ": cannot open"), 0u) << missing.error;
    EXPECT_EQ(read(r.output), "what was there");

    write(d / "broken.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n");
    r.input = (d / "broken.obj").string();
    cb::BakeResult broken = cb::bake_file(r);
    EXPECT_EQ(broken.status, cb::BakeStatus::failed);
    EXPECT_EQ(broken.error.find(r.input + ": "), 0u) << broken.error;
    EXPECT_EQ(broken.error.find('\n'), std::string::npos);
    EXPECT_EQ(read(r.output), "what was there");

    r.input = small("cube.obj").string();
    r.output = (d / "no-such-folder" / "cube.cbk").string();
    cb::BakeResult unwritable = cb::bake_file(r);
    EXPECT_EQ(unwritable.status, cb::BakeStatus::failed);
    EXPECT_NE(unwritable.error.find(r.output), std::string::npos) << unwritable.error;
    fs::remove_all(d);
}

TEST(BatchRun, SharedCoresGiveTheSameAssetsAsOneFileAtATime) {
    fs::path d = fresh_dir("run");
    std::vector<cb::BakeRequest> requests;
    std::vector<size_t> order;
    for (const char* f : {"cube.obj", "cube.off", "cube_binary.ply", "cube_ascii.stl", "primitive_modes.gltf"}) {
        cb::BakeRequest r;
        r.input = small(f).string();
        order.push_back(requests.size());
        requests.push_back(r);
    }
    cb::BakeRequest scene;
    scene.input = (fs::path(CB_SOURCE_DIR) / "data" / "default_scene.glb").string();
    order.insert(order.begin(), requests.size());
    requests.push_back(scene);

    std::vector<std::string> first;
    for (unsigned jobs : {1u, 2u, 3u}) {
        for (size_t i = 0; i < requests.size(); ++i)
            requests[i].output = (d / (std::to_string(jobs) + "_" + std::to_string(i) + ".cbk")).string();
        std::atomic<int> started{0}, finished{0};
        std::vector<cb::BakeResult> results = cb::run_batch(
            requests, order, cb::BatchRun{jobs, 2}, [&](size_t) { ++started; },
            [&](size_t, const cb::BakeResult&) { ++finished; });
        EXPECT_EQ(started, int(requests.size()));
        EXPECT_EQ(finished, int(requests.size()));
        for (size_t i = 0; i < requests.size(); ++i) {
            ASSERT_EQ(results[i].status, cb::BakeStatus::baked) << results[i].error;
            if (jobs == 1)
                first.push_back(read(requests[i].output));
            else
                EXPECT_EQ(read(requests[i].output), first[i]) << requests[i].input << " with " << jobs << " at once";
        }
    }
    fs::remove_all(d);
}

TEST(BatchRun, ParallelForUnderABudgetUsesOnlyIdleCoresAndGivesThemBack) {
    cb::CoreBudget budget(3);
    std::vector<std::atomic<int>> hits(5000);
    std::thread job([&] {
        cb::thread_core_budget() = &budget;
        budget.take();  // the job's own core
        cb::parallel_for(hits.size(), 0, [&](size_t i) { ++hits[i]; });
        budget.give();
        cb::thread_core_budget() = nullptr;
    });
    job.join();
    for (const std::atomic<int>& h : hits) ASSERT_EQ(h, 1);
    EXPECT_TRUE(budget.try_take());
    EXPECT_TRUE(budget.try_take());
    EXPECT_TRUE(budget.try_take());
    EXPECT_FALSE(budget.try_take());
}

// A batch's files bake in processes of their own, each drawing on the shared budget through a view: what a
// view holds is counted, so that the cores of a process that died holding them come back.
TEST(BatchRun, ACoreBudgetViewCountsWhatItHoldsSoThatItCanBeReclaimed) {
    cb::CoreBudget budget(3);
    std::atomic<int> held{0};
    cb::CoreBudget view(budget, held);
    budget.take();  // the slot's own core, held by the batch
    EXPECT_TRUE(view.try_take());
    EXPECT_TRUE(view.try_take());
    EXPECT_FALSE(view.try_take());
    EXPECT_EQ(held, 2);
    view.give();
    EXPECT_EQ(held, 1);
    budget.reclaim(held);  // its process ended holding one
    EXPECT_EQ(held, 0);
    EXPECT_TRUE(budget.try_take());
    EXPECT_TRUE(budget.try_take());
    EXPECT_FALSE(budget.try_take());
}

// An item that throws (std::bad_alloc under a memory limit) is rethrown once every thread has joined, under
// a budget or not, and the budget gets its cores back. (How many items still run meanwhile depends on the
// machine's load: not asserted.)
TEST(BatchRun, ParallelForRethrowsAnItemsExceptionOnceItsThreadsJoined) {
    for (bool budgeted : {false, true}) {
        cb::CoreBudget budget(4);
        cb::thread_core_budget() = budgeted ? &budget : nullptr;
        EXPECT_THROW(cb::parallel_for(10000, 4,
                                      [&](size_t i) {
                                          if (i == 100) throw std::bad_alloc();
                                      }),
                     std::bad_alloc);
        cb::thread_core_budget() = nullptr;
        for (int k = 0; k < 4; ++k) EXPECT_TRUE(budget.try_take());
        EXPECT_FALSE(budget.try_take());
    }
}

// A child forked from a process that runs other threads copies one of them and whatever locks the others
// held: run_batch refuses to fork there.
TEST(BatchRun, RunBatchRefusesToForkBesideOtherThreads) {
    std::promise<void> release;
    std::thread other([done = release.get_future()] { done.wait(); });
    cb::BakeRequest r;
    r.input = small("cube.obj").string();
    r.output = (fs::temp_directory_path() / ("cb_batch_threads_" + std::to_string(getpid()) + ".cbk")).string();
    EXPECT_THROW(cb::run_batch({r}, {0}, cb::BatchRun{1, 1}, {}, {}), std::logic_error);
    release.set_value();
    other.join();
    EXPECT_FALSE(fs::exists(r.output));
}
