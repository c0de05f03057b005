// Debian's assimp-testmodels: real files, many of them broken on purpose. Each either loads into a valid
// scene or fails with a one-line LoadError; nothing crashes, hangs or throws anything else.
#include <gtest/gtest.h>

#include <filesystem>

#include "load.h"
#include "scene_info.h"

namespace fs = std::filesystem;

namespace {

fs::path models() { return fs::path(CB_ASSIMP_MODELS); }

struct Outcome {
    size_t loaded = 0, refused = 0;
};

Outcome sweep(const fs::path& root) {
    Outcome o;
    std::vector<fs::path> files;
    for (const auto& e : fs::recursive_directory_iterator(root))
        if (e.is_regular_file() && cb::format_from_path(e.path().string()) != cb::FileFormat::unknown)
            files.push_back(e.path());
    std::sort(files.begin(), files.end());
    for (const fs::path& f : files) {
        SCOPED_TRACE(f.string());
        try {
            cb::Scene s = cb::load_scene(f.string());
            cb::validate_scene(s, f.string());  // indices in range, positions finite
            ++o.loaded;
        } catch (const cb::LoadError& e) {
            std::string what = e.what();
            EXPECT_EQ(what.rfind(f.string() + ": ", 0), 0u) << what;
            EXPECT_EQ(what.find('\n'), std::string::npos) << what;
            ++o.refused;
        } catch (const std::exception& e) {
            ADD_FAILURE() << "unexpected exception: " << e.what();
        }
    }
    return o;
}

}  // namespace

TEST(AssimpModels, EveryGltfLoadsOrFailsCleanly) {
    if (!fs::exists(models() / "glTF2")) GTEST_SKIP() << "assimp-testmodels is not installed";
    Outcome o = sweep(models() / "glTF2");
    std::printf("glTF2: %zu loaded, %zu refused\n", o.loaded, o.refused);
    EXPECT_GE(o.loaded, 30u);
    // The deliberately broken ones must be refused, not loaded as garbage.
    for (const char* bad :
         {"glTF2/IndexOutOfRange/IndexOutOfRange.gltf", "glTF2/IndexOutOfRange/AllIndicesOutOfRange.gltf",
          "glTF2/BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb", "glTF2/RecursiveNodes/RecursiveNodes.gltf",
          "glTF2/MissingBin/BoxTextured.gltf"})
        EXPECT_THROW(cb::load_scene((models() / bad).string()), cb::LoadError) << bad;
}

TEST(AssimpModels, EveryMeshFileLoadsOrFailsCleanly) {
    if (!fs::exists(models())) GTEST_SKIP() << "assimp-testmodels is not installed";
    for (const char* dir : {"OBJ", "PLY", "STL", "OFF", "invalid"}) {
        if (!fs::exists(models() / dir)) continue;
        Outcome o = sweep(models() / dir);
        std::printf("%s: %zu loaded, %zu refused\n", dir, o.loaded, o.refused);
    }
}

TEST(AssimpModels, WusonAgreesAcrossFormats) {
    if (!fs::exists(models() / "OFF/Wuson.off")) GTEST_SKIP() << "assimp-testmodels is not installed";
    cb::SceneInfo off = cb::describe(cb::load_scene((models() / "OFF/Wuson.off").string()));
    for (const char* f : {"PLY/Wuson.ply", "STL/Wuson.stl", "OBJ/WusonOBJ.obj"}) {
        cb::SceneInfo other = cb::describe(cb::load_scene((models() / f).string()));
        EXPECT_EQ(other.unique_triangles, off.unique_triangles) << f;
        for (int k = 0; k < 3; ++k) {
            EXPECT_NEAR(other.world_min[k], off.world_min[k], 1e-4) << f;
            EXPECT_NEAR(other.world_max[k], off.world_max[k], 1e-4) << f;
        }
    }
}

// The Khronos 2CylinderEngine, once with every primitive Draco-compressed and once plain. Draco's encoder
// drops degenerate triangles, so the Draco mesh holds exactly the plain mesh's non-degenerate ones.
TEST(AssimpModels, DracoEngineMatchesItsPlainTwin) {
    fs::path draco = models() / "glTF2/draco/2CylinderEngine.gltf";
    fs::path plain = models() / "glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb";
    if (!fs::exists(draco) || !fs::exists(plain)) GTEST_SKIP() << "assimp-testmodels is not installed";
    cb::Scene d = cb::load_scene(draco.string()), p = cb::load_scene(plain.string());
    EXPECT_EQ(d.report.draco_primitives, 34u);
    ASSERT_EQ(d.meshes.size(), p.meshes.size());
    ASSERT_EQ(d.instances.size(), p.instances.size());
    uint64_t unique_nondegenerate = 0;
    for (size_t m = 0; m < p.meshes.size(); ++m) {
        uint64_t kept = p.meshes[m].triangle_count() - cb::count_degenerate(p.meshes[m]);
        unique_nondegenerate += kept;
        EXPECT_EQ(d.meshes[m].triangle_count(), kept) << "mesh " << m;
    }
    EXPECT_EQ(cb::describe(d).unique_triangles, unique_nondegenerate);
    EXPECT_EQ(unique_nondegenerate, 65311u);  // the assimp-testmodels README's count for the Draco file
    cb::SceneInfo di = cb::describe(d), pi = cb::describe(p);
    double extent = 0;
    for (int k = 0; k < 3; ++k) extent = std::max(extent, pi.world_max[k] - pi.world_min[k]);
    // The same node transforms; the translations also carry each mesh's origin (mesh_frame.h), which
    // follows the quantised positions.
    for (size_t i = 0; i < d.instances.size(); ++i) {
        EXPECT_EQ(d.instances[i].mesh, p.instances[i].mesh);
        for (int k = 0; k < 16; ++k)
            EXPECT_NEAR(d.instances[i].world[k], p.instances[i].world[k], k >= 12 ? extent * 1e-3 : 1e-9);
    }
    for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(di.world_min[k], pi.world_min[k], extent * 1e-3);
        EXPECT_NEAR(di.world_max[k], pi.world_max[k], extent * 1e-3);
    }
}
