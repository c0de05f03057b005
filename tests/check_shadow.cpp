// A long correctness run, outside ctest: shadow queries on the given scenes, answered by the runtime's
// two-level trees and by its reference walk, both compared with the brute-force CGAL oracle, in two-sided
// and one-sided mode, with lights outside the bounds, grazing them, inside them and exactly on a vertex.
// Exit code 1 on any disagreement.
//
//   check_shadow [--queries N] FILE...      (N per file, default 250000)
#include <cb_cpsv.h>

#include <cstdio>
#include <random>

#include "shadow_oracle.h"

int main(int argc, char** argv) {
    size_t per_file = 250000;
    std::vector<std::string> files;
    for (int i = 1; i < argc; ++i) {
        std::string a = argv[i];
        if (a == "--queries" && i + 1 < argc) per_file = std::stoul(argv[++i]);
        else files.push_back(a);
    }
    size_t total = 0, bad_tree = 0, bad_reference = 0, touching = 0, shadowed = 0;
    for (const std::string& file : files) {
        cb::test::Baked b = cb::test::bake(file);
        const cb::AssetView& v = b.view;
        cb::test::WorldSample w = cb::test::sample_world(v, 1);
        double size = w.size();
        const auto& on = w.surface[w.surface.size() / 2];
        double lights[4][3] = {{w.lo[0] - size, w.hi[1] + 2 * size, w.lo[2] - 0.5 * size},
                               {0.5 * (w.lo[0] + w.hi[0]), w.hi[1] + 1e-3 * size, 0.5 * (w.lo[2] + w.hi[2])},
                               {w.lo[0] + 0.45 * (w.hi[0] - w.lo[0]), w.lo[1] + 0.55 * (w.hi[1] - w.lo[1]), w.lo[2] + 0.5 * (w.hi[2] - w.lo[2])},
                               {on[0], on[1], on[2]}};
        std::mt19937 rng(101);
        std::uniform_real_distribution<double> u(0, 1);
        size_t file_bad = 0, per_variant = per_file / 8;
        for (int variant = 0; variant < 8; ++variant) {
            const double* light = lights[variant % 4];
            bool one_sided = variant >= 4;
            std::vector<cb::ClusterShadowTree> trees(v.instance_count);
            size_t stack = 0;
            for (uint32_t i = 0; i < v.instance_count; ++i) {
                trees[i].build(v, i, light, one_sided);
                stack = std::max(stack, trees[i].stack_size());
            }
            std::vector<uint32_t> scratch(stack);
            for (size_t k = 0; k < per_variant; ++k) {
                double p[3];
                if (k % 2 == 0) {  // on the surfaces
                    const auto& s = w.surface[(k * 7919 + variant) % w.surface.size()];
                    p[0] = s[0], p[1] = s[1], p[2] = s[2];
                } else {
                    for (int j = 0; j < 3; ++j) p[j] = w.lo[j] + (w.hi[j] - w.lo[j]) * (1.2 * u(rng) - 0.1);
                }
                uint8_t tree = 0;
                cb::occluded_batch(trees.data(), trees.size(), p, 1, &tree, scratch.data());
                bool reference = cb::occluded_reference(v, p, light, nullptr, one_sided);
                bool t = false;
                bool exact = cb::test::oracle_occluded(v, p, light, t, one_sided);
                bad_tree += bool(tree) != exact;
                bad_reference += reference != exact;
                file_bad += (bool(tree) != exact) + (reference != exact);
                touching += t;
                shadowed += exact;
                ++total;
            }
        }
        std::printf("%s: %zu queries, %zu disagreements\n", file.c_str(), per_variant * 8, file_bad);
        std::fflush(stdout);
    }
    std::printf("%zu queries in all (two- and one-sided), %zu in shadow, %zu touching per the oracle; disagreements "
                "with the CGAL oracle: trees %zu, reference %zu\n", total, shadowed, touching, bad_tree, bad_reference);
    return bad_tree || bad_reference ? 1 : 0;
}
