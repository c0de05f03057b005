// Builds the runtime headers as an embedding engine would: C++17, -fno-exceptions, -fno-rtti, no other
// library. Opens an asset baked from the default scene and answers two queries whose answers the scene
// fixes: a point on the ground under blob_a is in shadow of a light straight above, a point above the
// blob is not. Usage: runtime_cxx17 ASSET
#include <cb_asset.h>
#include <cb_instance_shadow.h>
#include <cb_cull.h>
#include <detail/cb_exact.h>
#include <cb_level.h>
#include <cb_shadow.h>

#include <cstdio>
#include <cstdlib>

int main(int argc, char** argv) {
    if (argc != 2) return 2;
    FILE* f = std::fopen(argv[1], "rb");
    if (!f) return 2;
    std::fseek(f, 0, SEEK_END);
    long size = std::ftell(f);
    std::fseek(f, 0, SEEK_SET);
    // malloc returns memory aligned for any standard type, as the view's doubles need.
    void* bytes = std::malloc(size_t(size));
    if (!bytes || std::fread(bytes, 1, size_t(size), f) != size_t(size)) return 2;
    std::fclose(f);
    cb::AssetView view;
    cb::AssetError e = cb::open_asset(bytes, size_t(size), &view);
    if (e != cb::AssetError::ok) {
        std::printf("open_asset: %s\n", cb::asset_error_text(e));
        return 1;
    }
    const double light[3] = {-4, 30, 2}, under[3] = {-4, 0.05, 2}, above[3] = {-4, 5, 2};
    bool a = cb::occluded_reference(view, under, light, 0.0), b = cb::occluded_reference(view, above, light, 0.0);
    std::printf("under the blob: %s, above it: %s\n", a ? "shadow" : "lit", b ? "shadow" : "lit");
    // The same two points through a level holding the asset's instances as baked.
    cb::Level level;
    level.add_baked(level.add_asset(view));
    level.commit();
    const double points[6] = {under[0], under[1], under[2], above[0], above[1], above[2]};
    uint8_t through[2] = {2, 2};
    cb::LevelShadow shadow;
    shadow.occluded_batch(level, light, points, 2, through);
    std::printf("through a level: %s, %s\n", through[0] ? "shadow" : "lit", through[1] ? "shadow" : "lit");
    std::free(bytes);
    return a && !b && through[0] == 1 && through[1] == 0 ? 0 : 1;
}
