// A level of two assets through the installed runtime alone: the first asset as baked, every instance of
// the second placed by a matrix, then moved between two frames, with one light's shadows answered for a
// batch of points in each frame.
//
//   embed_level GROUND_ASSET PROP_ASSET X,Y,Z POINTS
//
// Prints one 0/1 line per point for frame 1, then for frame 2: what `clusterbake query` prints for the
// level files frame1.json and frame2.json that tests/check_embed.sh writes with the same matrices.
#include <clusterbake/cb_level.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "files.h"

// The level example of docs/RUNTIME.md, word for word (tests/check_embed.sh compares the two).

// ground, prop: opened assets; first, second: where the prop stands in each frame (column-major 3x4, world =
// matrix x baked). answers: 2 n bytes, frame 1's then frame 2's.
void two_frames(const cb::AssetView& ground, const cb::AssetView& prop, const double* first, const double* second,
                const double* light, const double* points, size_t n, uint8_t* answers) {
    cb::Level level;
    level.add_baked(level.add_asset(ground));
    // The prop's handles, to move its instances later
    std::vector<uint32_t> handles(prop.instance_count);
    level.add_baked(level.add_asset(prop), first, handles.data());
    // The hierarchy over the instances: built once
    level.commit();
    // Kept between frames
    cb::LevelShadow shadow;
    shadow.occluded_batch(level, light, points, n, answers);
    for (uint32_t i = 0; i < prop.instance_count; ++i) {
        double world[12];
        cb::compose_instance(second, prop.instances[i].transform, world);
        level.move(handles[i], world);
    }
    // Refits the moved instances' paths
    level.commit();
    shadow.occluded_batch(level, light, points, n, answers + n);
}

int main(int argc, char** argv) {
    double light[3];
    if (argc != 5 || std::sscanf(argv[3], "%lf,%lf,%lf", &light[0], &light[1], &light[2]) != 3) {
        std::fprintf(stderr, "usage: embed_level GROUND_ASSET PROP_ASSET X,Y,Z POINTS\n");
        return 2;
    }
    void* bytes[2] = {nullptr, nullptr};
    cb::AssetView views[2];
    for (int a = 0; a < 2; ++a) {
        size_t size = 0;
        if (!example::open_asset_file(argv[1 + a], bytes[a], size, views[a])) return 2;
    }
    const std::vector<double> points = example::read_points(argv[4]);
    const size_t n = points.size() / 3;

    // Frame 1: the prop three times its size, raised 6 above the origin and moved to (8, 8); frame 2: its x
    // and z axes swapped (a mirror image), raised 5 and moved to (-10, -6). The same matrices as
    // check_embed.sh's level files.
    const double first[12] = {3, 0, 0, 0, 3, 0, 0, 0, 3, 8, 6, 8};
    const double second[12] = {0, 0, 3, 0, 3, 0, 3, 0, 0, -10, 5, -6};
    std::vector<uint8_t> answers(2 * n);
    two_frames(views[0], views[1], first, second, light, points.data(), n, answers.data());
    for (uint8_t s : answers) std::printf("%d\n", int(s));
    std::free(bytes[0]);
    std::free(bytes[1]);
    return 0;
}
