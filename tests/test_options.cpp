// The rules of the option structs, each with its own error and text, and the table of bake options that
// the command line, the source section and batch all read.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "bake_options.h"
#include "batch.h"
#include "bounds.h"
#include "cluster.h"

namespace {

// Options that break exactly one rule of ClusterOptions, with that rule's error and text.
struct BrokenCluster {
    void (*apply)(cb::ClusterOptions&);
    cb::ClusterOptionsError error;
    const char* text;       // fields by their own names
    const char* flag_text;  // fields by their flags
};

const BrokenCluster broken_cluster[] = {
    {[](cb::ClusterOptions& o) { o.fine_size = 0; }, cb::ClusterOptionsError::fine_size_zero,
     "fine_size must be at least 1", "--fine must be at least 1"},
    {[](cb::ClusterOptions& o) { o.fine_size = 86; }, cb::ClusterOptionsError::fine_size_above_max,
     "fine_size must be at most 85 (a fine cluster's corners must fit the asset's 8-bit local indices)",
     "--fine must be at most 85 (a fine cluster's corners must fit the asset's 8-bit local indices)"},
    {[](cb::ClusterOptions& o) { o.coarse_size = 0; }, cb::ClusterOptionsError::coarse_size_zero,
     "coarse_size must be at least 1", "--coarse must be at least 1"},
    {[](cb::ClusterOptions& o) { o.coarse_size = 15; }, cb::ClusterOptionsError::coarse_size_below_fine_size,
     "coarse_size must be at least fine_size", "--coarse must be at least --fine"},
    {[](cb::ClusterOptions& o) { o.kmeans_branching = 1; }, cb::ClusterOptionsError::kmeans_branching_below_two,
     "kmeans_branching must be at least 2 (children per k-means node)",
     "--k0 must be at least 2 (children per k-means node)"},
    {[](cb::ClusterOptions& o) { o.vco_cache_size = 2; }, cb::ClusterOptionsError::vco_cache_size_below_three,
     "vco_cache_size must be at least 3 (a triangle's corners)", "--cache must be at least 3 (a triangle's corners)"},
};

TEST(Options, TheFineSizeLimitComesFromTheFormat) {
    // 85 triangles have at most 255 distinct corners; 86 can have 258, more than 8-bit indices address.
    EXPECT_EQ(cb::max_fine_size, 85u);
    EXPECT_LE(cb::max_fine_size * 3, cb::max_cluster_vertices);
    EXPECT_GT((cb::max_fine_size + 1) * 3, cb::max_cluster_vertices);
}

TEST(Options, EachClusteringRuleHasItsErrorAndText) {
    EXPECT_EQ(cb::check_options(cb::ClusterOptions{}), cb::ClusterOptionsError::none);
    EXPECT_EQ(cb::describe(cb::ClusterOptionsError::none), "");
    for (const BrokenCluster& b : broken_cluster) {
        SCOPED_TRACE(b.text);
        cb::ClusterOptions o;
        b.apply(o);
        EXPECT_EQ(cb::check_options(o), b.error);
        EXPECT_EQ(cb::describe(b.error), b.text);
        EXPECT_EQ(cb::describe(b.error, cb::flag_of_field), b.flag_text);
        cb::BakeRequest r;
        r.clustering = o;
        EXPECT_EQ(cb::request_options_error(r), b.flag_text);
    }
    // The limits themselves are allowed.
    cb::ClusterOptions edge;
    edge.fine_size = edge.coarse_size = 85;
    edge.kmeans_branching = 2;
    edge.vco_cache_size = 3;
    EXPECT_EQ(cb::check_options(edge), cb::ClusterOptionsError::none);
    edge.fine_size = edge.coarse_size = 1;
    EXPECT_EQ(cb::check_options(edge), cb::ClusterOptionsError::none);
}

TEST(Options, BuildHierarchyRefusesBrokenOptionsBeforeAnyWork) {
    const float positions[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint32_t indices[3] = {0, 1, 2};
    for (const BrokenCluster& b : broken_cluster) {
        cb::ClusterOptions o;
        b.apply(o);
        try {
            cb::build_hierarchy(positions, 3, indices, 1, o);
            ADD_FAILURE() << b.text << ": no error";
        } catch (const std::invalid_argument& e) {
            EXPECT_EQ(std::string(e.what()), b.text);
        }
    }
    EXPECT_EQ(cb::build_hierarchy(positions, 3, indices, 1, cb::ClusterOptions{}).fine_count(), 1u);
}

TEST(Options, BakeFileRefusesBrokenOptionsBeforeReadingTheScene) {
    cb::BakeRequest r;
    r.input = "no/such/scene.obj";  // not read: the options fail first
    r.output = "no/such/folder/out.cbk";
    r.clustering.kmeans_branching = 0;
    const cb::BakeResult result = cb::bake_file(r);
    EXPECT_EQ(result.status, cb::BakeStatus::failed);
    EXPECT_EQ(result.error, "no/such/scene.obj: --k0 must be at least 2 (children per k-means node)");
}

TEST(Options, EachBoundsRuleHasItsErrorAndText) {
    EXPECT_EQ(cb::check_options(cb::BoundsOptions{}), cb::BoundsOptionsError::none);
    EXPECT_EQ(cb::describe(cb::BoundsOptionsError::none), "");
    cb::BoundsOptions mask;
    mask.mask = cb::bounds_all | 32;
    EXPECT_EQ(cb::check_options(mask), cb::BoundsOptionsError::mask_unknown_kind);
    EXPECT_EQ(cb::describe(cb::BoundsOptionsError::mask_unknown_kind),
              "mask holds a bit of no volume kind (obb, sphere, capsule, cone, slab)");
    for (double ratio : {0.5, -1.0, std::nan(""), HUGE_VAL}) {
        cb::BoundsOptions o;
        o.capsule_ratio = ratio;
        EXPECT_EQ(cb::check_options(o), cb::BoundsOptionsError::capsule_ratio_below_one) << ratio;
        cb::BakeRequest r;
        r.bounds = o;
        EXPECT_EQ(cb::request_options_error(r), "--capsule-ratio must be a finite number of at least 1");
    }
    EXPECT_EQ(cb::describe(cb::BoundsOptionsError::capsule_ratio_below_one),
              "capsule_ratio must be a finite number of at least 1");
    cb::BoundsOptions one;
    one.capsule_ratio = 1;
    EXPECT_EQ(cb::check_options(one), cb::BoundsOptionsError::none);
}

TEST(Options, TheTableDefaultsAreTheStructsDefaults) {
    const cb::BakeRequest defaults;
    for (const cb::BakeOption& o : cb::bake_options()) {
        SCOPED_TRACE(o.flag);
        EXPECT_EQ(cb::find_bake_option(o.flag), &o);
        EXPECT_EQ(cb::flag_of_field(o.field), o.flag);
        if (!o.takes_value) {
            EXPECT_EQ(o.text(defaults), "false");  // a switch is off unless given
            continue;
        }
        cb::BakeRequest r;
        EXPECT_EQ(o.set(r, o.default_value), "");
        EXPECT_EQ(o.text(r), o.text(defaults));
    }
    EXPECT_EQ(cb::flag_of_field("no_such_field"), "no_such_field");
    EXPECT_EQ(cb::find_bake_option("--no-such-flag"), nullptr);
}

TEST(Options, ApplyOptionsSetsFieldsAndNamesWhatIsWrong) {
    cb::BakeRequest r;
    std::vector<std::string> given;
    EXPECT_EQ(cb::apply_options({"--method", "vco", "--fine=24", "--cache", "12", "--bounds", "all", "--obb", "pca",
                                 "--capsule-ratio", "2.5", "--threads", "3"},
                                r, &given),
              "");
    EXPECT_EQ(r.clustering.method, cb::ClusterMethod::vco);
    EXPECT_EQ(r.clustering.fine_size, 24u);
    EXPECT_EQ(r.clustering.vco_cache_size, 12u);
    EXPECT_EQ(r.bounds.mask, cb::bounds_all);
    EXPECT_EQ(r.bounds.obb, cb::ObbMethod::pca);
    EXPECT_EQ(r.bounds.capsule_ratio, 2.5);
    EXPECT_EQ(r.threads, 3u);
    EXPECT_EQ(given,
              (std::vector<std::string>{"--method", "--fine", "--cache", "--bounds", "--obb", "--capsule-ratio",
                                        "--threads"}));
    EXPECT_EQ(cb::apply_options({"--coarse-morton"}, r), "");
    EXPECT_FALSE(r.clustering.kmeans_coarse_from_tree);

    cb::BakeRequest s;
    EXPECT_EQ(cb::apply_options({"--nope", "1"}, s), "--nope is not a bake option");
    EXPECT_EQ(cb::apply_options({"--fine", "8", "--fine", "9"}, s), "--fine is given twice");
    EXPECT_EQ(cb::apply_options({"--fine"}, s), "--fine needs a value");
    EXPECT_EQ(cb::apply_options({"--coarse-morton=1"}, s), "--coarse-morton takes no value");
    EXPECT_EQ(cb::apply_options({"--coarse", "x"}, s), "--coarse takes a whole number from 0 to 4294967295 (got 'x')");
    EXPECT_EQ(cb::apply_options({"--coarse", "-1"}, s),
              "--coarse takes a whole number from 0 to 4294967295 (got '-1')");
    EXPECT_EQ(cb::apply_options({"--coarse", "4294967296"}, s),
              "--coarse takes a whole number from 0 to 4294967295 (got '4294967296')");
    EXPECT_EQ(cb::apply_options({"--capsule-ratio", "2x"}, s), "--capsule-ratio takes a number (got '2x')");
    EXPECT_EQ(cb::apply_options({"--method", "best"}, s), "unknown method 'best' (kmeans, vco, morton)");
    EXPECT_EQ(cb::apply_options({"--obb", "best"}, s), "--obb takes refined, pca, pca-area or cgal (got 'best')");
    EXPECT_EQ(cb::apply_options({"--bounds", "box"}, s),
              "--bounds takes auto, all or a list of obb,sphere,capsule,cone,slab (got 'box')");
    EXPECT_EQ(cb::apply_options({"--coarse", "0x800"}, s), "");  // as the command line's parser reads it
    EXPECT_EQ(s.clustering.coarse_size, 2048u);
}

TEST(Options, AnOptionThatWouldChangeNothingIsNamedWithWhy) {
    cb::BakeRequest r;
    EXPECT_EQ(cb::ignored_option_error({"--method", "--fine", "--seed", "--presplit", "--bounds", "--threads"}, r), "");
    EXPECT_EQ(cb::ignored_option_error({"--cache"}, r),
              "--cache does nothing here: an option of vco, and the method is kmeans");
    r.clustering.kmeans_coarse_from_tree = false;
    EXPECT_EQ(cb::ignored_option_error({"--presplit"}, r),
              "--presplit does nothing here: with --coarse-morton no k-means tree grows in presplit chunks");
    r.clustering.method = cb::ClusterMethod::morton;
    for (const char* flag : {"--seed", "--k0", "--iterations", "--presplit", "--coarse-morton"})
        EXPECT_EQ(cb::ignored_option_error({flag}, r),
                  std::string(flag) + " does nothing here: an option of kmeans, and the method is morton");
    r.clustering.method = cb::ClusterMethod::vco;
    EXPECT_EQ(cb::ignored_option_error({"--cache", "--coarse"}, r), "");
    r.fit = false;
    EXPECT_EQ(cb::ignored_option_error({"--obb"}, r),
              "--obb does nothing here: an option of bake, and this run fits no bounds");
}

TEST(Options, TheOptionsTextAndBatchArgvComeFromTheTable) {
    cb::BakeRequest r;
    EXPECT_EQ(cb::options_text(r.clustering, r.bounds, true),
              "bake --method kmeans --coarse 2048 --fine 16 --seed 1 --k0 8 --iterations 16 --presplit 65536 "
              "--bounds obb,cone --obb refined --capsule-ratio 2");
    EXPECT_EQ(cb::options_text(r.clustering, r.bounds, false),
              "cluster --method kmeans --coarse 2048 --fine 16 --seed 1 --k0 8 --iterations 16 --presplit 65536");
    ASSERT_EQ(cb::apply_options({"--method", "vco", "--cache", "9", "--capsule-ratio", "0.1e2", "--threads", "2"}, r),
              "");
    EXPECT_EQ(cb::options_text(r.clustering, r.bounds, true),
              "bake --method vco --coarse 2048 --fine 16 --cache 9 --bounds obb,cone --obb refined --capsule-ratio 10");
    // A batch's command line for a job is the same words, with what the file is trusted with.
    r.input = "in dir/a.obj";
    r.output = "out/a.cbk";
    EXPECT_EQ(cb::bake_argv(r, false),
              (std::vector<std::string>{"bake",         "in dir/a.obj", "-o",     "out/a.cbk", "--method",        "vco",
                                        "--coarse",     "2048",         "--fine", "16",        "--cache",         "9",
                                        "--bounds",     "obb,cone",     "--obb",  "refined",   "--capsule-ratio", "10",
                                        "--if-changed", "--json"}));
    // Read back, those words make the same request.
    std::vector<std::string> words = cb::options_argv(r);
    cb::BakeRequest back;
    ASSERT_EQ(cb::apply_options(words, back), "");
    EXPECT_EQ(cb::options_argv(back), words);
    EXPECT_EQ(back.clustering.vco_cache_size, 9u);
    EXPECT_EQ(back.bounds.capsule_ratio, 10.0);
}

TEST(Options, ABatchJobTakesItsLineOverTheBatchsOptions) {
    cb::BatchOptions batch;
    ASSERT_EQ(cb::apply_options({"--fine", "8", "--seed", "3", "--threads", "4"}, batch.bake, &batch.given), "");
    cb::BatchJob job;
    job.input = "scenes/a.obj";
    job.output = "out/a.cbk";
    job.origin = "list.txt: line 2";
    job.args = {"--fine", "24", "--threads", "1"};
    cb::BakeRequest r;
    ASSERT_EQ(cb::job_request(batch, job, r), "");
    EXPECT_EQ(r.clustering.fine_size, 24u);
    EXPECT_EQ(r.clustering.seed, 3u);
    EXPECT_EQ(r.threads, 1u);  // the line's cap; the batch's --threads is the cores it shares
    EXPECT_TRUE(r.if_changed);
    EXPECT_EQ(r.input, job.input);
    job.args = {};
    ASSERT_EQ(cb::job_request(batch, job, r), "");
    EXPECT_EQ(r.threads, 0u);
    job.args = {"--method", "vco"};
    EXPECT_EQ(cb::job_request(batch, job, r),
              "list.txt: line 2: --seed does nothing here: an option of kmeans, and the method is vco");
    job.args = {"--coarse", "4"};
    EXPECT_EQ(cb::job_request(batch, job, r), "list.txt: line 2: --coarse must be at least --fine");
    job.args = {"--k0"};
    EXPECT_EQ(cb::job_request(batch, job, r), "list.txt: line 2: --k0 needs a value");
}

}  // namespace
