// export-gltf's GLB read back with tinygltf: one primitive per cluster holding its triangles, each inside its
// cluster's box, instances placed as the asset places them, neighbouring clusters never of one colour.
#include <gtest/gtest.h>

#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>

#include <cb_asset.h>

#include <array>
#include <cmath>
#include <cstring>
#include <map>
#include <set>
#include <stdexcept>

#include "baked.h"
#include "cluster_gltf.h"

namespace {

using Affine = std::array<double, 12>;  // column-major 3x4, as the asset's instances

tinygltf::Model parse(const std::vector<uint8_t>& glb) {
    tinygltf::TinyGLTF loader;
    tinygltf::Model model;
    std::string err, warn;
    bool ok = loader.LoadBinaryFromMemory(&model, &err, &warn, glb.data(), unsigned(glb.size()));
    EXPECT_TRUE(ok) << err;
    EXPECT_TRUE(err.empty()) << err;
    EXPECT_TRUE(warn.empty()) << warn;
    return model;
}

// The values of a SCALAR index or VEC3 float accessor, read through its view as a viewer would.
std::vector<uint32_t> read_indices(const tinygltf::Model& m, int accessor) {
    const tinygltf::Accessor& a = m.accessors.at(size_t(accessor));
    const tinygltf::BufferView& v = m.bufferViews.at(size_t(a.bufferView));
    const uint8_t* p = m.buffers.at(size_t(v.buffer)).data.data() + v.byteOffset + a.byteOffset;
    std::vector<uint32_t> out(a.count);
    for (size_t i = 0; i < a.count; ++i) {
        if (a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT) {
            uint16_t x;
            std::memcpy(&x, p + 2 * i, 2);
            out[i] = x;
        } else {
            EXPECT_EQ(a.componentType, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
            std::memcpy(&out[i], p + 4 * i, 4);
        }
    }
    return out;
}

std::vector<std::array<float, 3>> read_positions(const tinygltf::Model& m, int accessor) {
    const tinygltf::Accessor& a = m.accessors.at(size_t(accessor));
    EXPECT_EQ(a.componentType, TINYGLTF_COMPONENT_TYPE_FLOAT);
    EXPECT_EQ(a.type, TINYGLTF_TYPE_VEC3);
    const tinygltf::BufferView& v = m.bufferViews.at(size_t(a.bufferView));
    const uint8_t* p = m.buffers.at(size_t(v.buffer)).data.data() + v.byteOffset + a.byteOffset;
    std::vector<std::array<float, 3>> out(a.count);
    std::memcpy(out.data(), p, a.count * 12);
    return out;
}

Affine multiply(const Affine& a, const Affine& b) {
    Affine out{};
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 3; ++r) {
            double x = c == 3 ? a[9 + r] : 0;
            for (int k = 0; k < 3; ++k) x += a[k * 3 + r] * b[c * 3 + k];
            out[c * 3 + r] = x;
        }
    return out;
}

// A node's local transform: its matrix, or T R S (rotation a Hamilton quaternion x, y, z, w).
Affine local(const tinygltf::Node& n) {
    Affine out = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
    if (!n.matrix.empty()) {
        for (int c = 0; c < 4; ++c)
            for (int r = 0; r < 3; ++r) out[c * 3 + r] = n.matrix[size_t(c * 4 + r)];
        return out;
    }
    double x = 0, y = 0, z = 0, w = 1;
    if (!n.rotation.empty()) {
        x = n.rotation[0];
        y = n.rotation[1];
        z = n.rotation[2];
        w = n.rotation[3];
    }
    const double rot[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)},
                              {2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)},
                              {2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)}};
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r) out[c * 3 + r] = rot[c][r] * (n.scale.empty() ? 1.0 : n.scale[size_t(c)]);
    for (int r = 0; r < 3 && !n.translation.empty(); ++r) out[9 + r] = n.translation[size_t(r)];
    return out;
}

// Each root's world transform down to the node holding a mesh, and that mesh.
struct Placed {
    Affine world;
    int mesh = -1;
};
std::vector<Placed> placed_roots(const tinygltf::Model& m) {
    std::vector<Placed> out;
    for (int root : m.scenes.at(0).nodes) {
        Placed p{local(m.nodes.at(size_t(root))), m.nodes[size_t(root)].mesh};
        for (int at = root; p.mesh < 0 && !m.nodes[size_t(at)].children.empty();) {
            EXPECT_EQ(m.nodes[size_t(at)].children.size(), 1u);
            at = m.nodes[size_t(at)].children[0];
            p.world = multiply(p.world, local(m.nodes[size_t(at)]));
            p.mesh = m.nodes[size_t(at)].mesh;
        }
        out.push_back(p);
    }
    return out;
}

void expect_same_transform(const Affine& got, const double* want, uint32_t instance) {
    double scale = 1;
    for (int i = 0; i < 12; ++i) scale = std::max(scale, std::fabs(want[i]));
    for (int i = 0; i < 12; ++i)
        EXPECT_NEAR(got[size_t(i)], want[i], 1e-9 * scale) << "instance " << instance << " element " << i;
}

bool is_lines(const tinygltf::Primitive& p) { return p.mode == TINYGLTF_MODE_LINE; }

std::array<double, 3> colour_of(const tinygltf::Model& m, const tinygltf::Primitive& p) {
    const std::vector<double>& c = m.materials.at(size_t(p.material)).pbrMetallicRoughness.baseColorFactor;
    return {c[0], c[1], c[2]};
}

// No two triangle primitives of one mesh that have a vertex position in common have one colour, found from
// the GLB alone. Returns how many such neighbouring pairs there are.
size_t check_neighbour_colours(const tinygltf::Model& m) {
    size_t pairs = 0;
    for (size_t mi = 0; mi < m.meshes.size(); ++mi) {
        const std::vector<tinygltf::Primitive>& prims = m.meshes[mi].primitives;
        std::map<std::array<float, 3>, std::set<size_t>> at;  // position -> primitives with a corner there
        for (size_t pi = 0; pi < prims.size(); ++pi) {
            if (is_lines(prims[pi])) continue;
            std::vector<std::array<float, 3>> pos = read_positions(m, prims[pi].attributes.at("POSITION"));
            for (uint32_t i : read_indices(m, prims[pi].indices)) {
                std::array<float, 3> p = pos.at(i);
                for (float& x : p) x += 0.0f;  // -0 and 0 are one position
                at[p].insert(pi);
            }
        }
        std::set<std::pair<size_t, size_t>> seen;
        for (const auto& [p, users] : at)
            for (size_t a : users)
                for (size_t b : users)
                    if (a < b && seen.insert({a, b}).second) {
                        ++pairs;
                        EXPECT_NE(colour_of(m, prims[a]), colour_of(m, prims[b]))
                            << "mesh " << mi << ": neighbouring primitives " << a << " and " << b << " share a colour";
                    }
    }
    return pairs;
}

std::string data(const std::string& f) { return std::string(CB_SOURCE_DIR) + "/data/" + f; }

}  // namespace

TEST(Export, FineClustersRoundTripThroughTinygltf) {
    cb::test::Baked baked = cb::test::bake_scene(cb::load_scene(data("default_scene.glb")), {}, cb::bounds_all);
    const cb::AssetView& v = baked.view;
    ASSERT_GT(v.mesh_count, 0u);
    cb::ExportOptions options;
    options.overlays = cb::overlay_obb | cb::overlay_sphere | cb::overlay_capsule | cb::overlay_cone;
    options.generator = "clusterbake test";
    cb::ExportSummary summary;
    std::vector<uint8_t> glb = cb::export_clusters_glb(v, options, &summary);
    EXPECT_EQ(summary.bytes, glb.size());
    tinygltf::Model m = parse(glb);
    ASSERT_EQ(m.meshes.size(), v.mesh_count);
    EXPECT_EQ(m.asset.generator, "clusterbake test");

    size_t triangle_primitives = 0, triangles = 0, box_ends = 0;
    for (uint32_t mi = 0; mi < v.mesh_count; ++mi) {
        const cb::MeshRecord& rec = v.meshes[mi];
        uint32_t c = 0;
        for (const tinygltf::Primitive& p : m.meshes[mi].primitives) {
            if (is_lines(p)) {
                EXPECT_TRUE(m.materials.at(size_t(p.material)).extensions.count("KHR_materials_unlit"));
                std::string kind = p.extras.Get("overlay").Get<std::string>();
                size_t ends = m.accessors.at(size_t(p.attributes.at("POSITION"))).count;
                EXPECT_EQ(ends % 2, 0u);
                if (kind == "obb") box_ends += ends;
                continue;
            }
            ASSERT_EQ(p.mode, TINYGLTF_MODE_TRIANGLES);
            ASSERT_LT(c, rec.fine_count) << "more triangle primitives than clusters in mesh " << mi;
            const uint32_t cluster = rec.first_fine + c++;
            EXPECT_EQ(p.extras.Get("cluster").GetNumberAsInt(), int(cluster));
            std::vector<uint32_t> idx = read_indices(m, p.indices);
            std::vector<std::array<float, 3>> pos = read_positions(m, p.attributes.at("POSITION"));
            EXPECT_EQ(idx.size(), 3u * v.fine[cluster].triangle_count);
            triangles += idx.size() / 3;
            ++triangle_primitives;
            // The cluster's triangles, in stored order and winding, every vertex inside its box.
            cb::Obb box = v.fine_bounds.obb(cluster);
            for (size_t t = 0; t < idx.size() / 3; ++t) {
                uint32_t want[3];
                v.triangle(rec, c - 1, v.fine[cluster].first_triangle + uint32_t(t), want);
                for (int k = 0; k < 3; ++k) {
                    const std::array<float, 3>& q = pos.at(idx[t * 3 + k]);
                    const float* expected = v.position(rec, want[k]);
                    ASSERT_EQ(std::memcmp(q.data(), expected, 12), 0) << "cluster " << cluster << " triangle " << t;
                    for (int a = 0; a < 3; ++a) {
                        double d = 0;
                        for (int j = 0; j < 3; ++j) d += (double(q[j]) - box.center[j]) * box.axis[a][j];
                        EXPECT_LE(std::fabs(d), box.half[a] * (1 + 1e-6) + 1e-6) << "cluster " << cluster;
                    }
                }
            }
        }
        EXPECT_EQ(c, rec.fine_count) << "mesh " << mi;
    }
    EXPECT_EQ(triangle_primitives, v.fine_count);
    EXPECT_EQ(triangles, v.triangle_count);
    EXPECT_EQ(box_ends, 24u * v.fine_count);  // 12 edges per cluster

    std::vector<Placed> roots = placed_roots(m);
    ASSERT_EQ(roots.size(), v.instance_count);
    for (uint32_t i = 0; i < v.instance_count; ++i) {
        EXPECT_EQ(roots[i].mesh, int(v.instances[i].mesh));
        expect_same_transform(roots[i].world, v.instances[i].transform, i);
    }
    EXPECT_GT(check_neighbour_colours(m), v.fine_count);  // clusters of a surface have several neighbours each
    std::set<std::array<double, 3>> colours;
    for (const tinygltf::Mesh& mesh : m.meshes)
        for (const tinygltf::Primitive& p : mesh.primitives)
            if (!is_lines(p)) colours.insert(colour_of(m, p));
    EXPECT_EQ(colours.size(), summary.colours);  // one colour per class, no two classes alike
}

TEST(Export, CoarseLevelIsOnePrimitivePerCoarseCluster) {
    cb::ClusterOptions clustering;
    clustering.coarse_size = 256;  // many coarse clusters, so that they have neighbours
    cb::test::Baked baked = cb::test::bake_scene(cb::load_scene(data("default_scene.glb")), clustering);
    const cb::AssetView& v = baked.view;
    cb::ExportOptions options;
    options.level = cb::ExportLevel::coarse;
    options.overlays = cb::overlay_obb;
    tinygltf::Model m = parse(cb::export_clusters_glb(v, options));
    size_t primitives = 0, triangles = 0;
    for (uint32_t mi = 0; mi < v.mesh_count; ++mi)
        for (const tinygltf::Primitive& p : m.meshes.at(mi).primitives)
            if (!is_lines(p)) {
                ++primitives;
                triangles += m.accessors.at(size_t(p.indices)).count / 3;
            }
    EXPECT_EQ(primitives, v.coarse_count);
    EXPECT_EQ(triangles, v.triangle_count);
    EXPECT_GT(check_neighbour_colours(m), 0u);
}

TEST(Export, ShearedAndMirroredInstancesKeepTheirTransforms) {
    cb::Scene scene = cb::load_scene(data("small/cube.obj"));
    ASSERT_EQ(scene.instances.size(), 1u);
    // Column-major 4x4: a plain one, a rotation with non-uniform scale, a mirror, a shear, one far away.
    const double c = std::cos(0.7), s = std::sin(0.7);
    const std::vector<cb::Transform> worlds = {
        cb::identity_transform(),
        {2 * c, 2 * s, 0, 0, -3 * s, 3 * c, 0, 0, 0, 0, 0.5, 0, 1, 2, 3, 1},
        {-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1},
        {1, 0, 0, 0, 0.8, 1, 0.3, 0, 0.1, -0.4, 2, 0, -5, 0, 7, 1},
        {0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1, 0, 4.5e6, -2.25e6, 123.25, 1},
    };
    cb::Instance proto = scene.instances[0];
    scene.instances.clear();
    for (const cb::Transform& w : worlds) {
        proto.world = w;
        scene.instances.push_back(proto);
    }
    cb::test::Baked baked = cb::test::bake_scene(scene);
    const cb::AssetView& v = baked.view;
    ASSERT_EQ(v.instance_count, worlds.size());
    cb::ExportSummary summary;
    tinygltf::Model m = parse(cb::export_clusters_glb(v, {}, &summary));
    EXPECT_EQ(summary.sheared_instances, 1u);  // the shear needs two nodes; the mirror is a negative scale
    std::vector<Placed> roots = placed_roots(m);
    ASSERT_EQ(roots.size(), v.instance_count);
    for (uint32_t i = 0; i < v.instance_count; ++i) {
        EXPECT_EQ(roots[i].mesh, int(v.instances[i].mesh));
        expect_same_transform(roots[i].world, v.instances[i].transform, i);
    }
    for (const tinygltf::Node& n : m.nodes) {
        EXPECT_TRUE(n.matrix.empty());
        if (n.rotation.empty()) continue;
        double len = 0;
        for (double q : n.rotation) len += q * q;
        EXPECT_NEAR(len, 1, 1e-12);
    }
}

TEST(Export, MissingVolumesAreRefused) {
    cb::test::Baked baked = cb::test::bake(data("small/cube.obj"));  // boxes and cones only
    cb::ExportOptions options;
    options.overlays = cb::overlay_obb | cb::overlay_cone;
    EXPECT_EQ(cb::export_options_error(baked.view, options), "");
    options.overlays |= cb::overlay_sphere;
    EXPECT_NE(cb::export_options_error(baked.view, options).find("no fine spheres"), std::string::npos);
    EXPECT_THROW(cb::export_clusters_glb(baked.view, options), std::invalid_argument);
    options.overlays = cb::overlay_capsule;
    options.level = cb::ExportLevel::coarse;
    EXPECT_NE(cb::export_options_error(baked.view, options).find("no coarse capsules"), std::string::npos);
}

TEST(Export, OverlayNames) {
    uint32_t bits = 0;
    EXPECT_TRUE(cb::parse_volume_overlays("obb", bits));
    EXPECT_EQ(bits, cb::overlay_obb);
    EXPECT_TRUE(cb::parse_volume_overlays("capsule,obb,sphere", bits));
    EXPECT_EQ(bits, cb::overlay_obb | cb::overlay_sphere | cb::overlay_capsule);
    for (const char* bad : {"", "cone", "obb,", "box", "obb,,sphere"})
        EXPECT_FALSE(cb::parse_volume_overlays(bad, bits)) << bad;
}

TEST(Export, PaletteColoursAreFarApart) {
    // Any two of the palette, and the first colours past it, differ clearly as the screen shows them (sRGB).
    auto srgb = [](uint32_t k, double out[3]) {
        cb::export_colour(k, out);
        for (int c = 0; c < 3; ++c) {
            EXPECT_GE(out[c], 0.0);
            EXPECT_LE(out[c], 1.0);
            out[c] = out[c] <= 0.0031308 ? out[c] * 12.92 : 1.055 * std::pow(out[c], 1 / 2.4) - 0.055;
        }
    };
    for (uint32_t a = 0; a < 20; ++a)
        for (uint32_t b = a + 1; b < 20; ++b) {
            double ca[3], cb_[3], d = 0;
            srgb(a, ca);
            srgb(b, cb_);
            for (int k = 0; k < 3; ++k) d = std::max(d, std::fabs(ca[k] - cb_[k]));
            EXPECT_GT(d, b < cb::export_palette_size ? 0.25 : 0.04) << "colours " << a << " and " << b;
        }
}

TEST(Export, GreedyColouringUsesFewColours) {
    cb::test::Baked baked = cb::test::bake(data("default_scene.glb"));
    std::vector<uint32_t> colour = cb::cluster_colours(baked.view, cb::ExportLevel::fine);
    std::vector<std::vector<uint32_t>> neighbours = cb::cluster_neighbours(baked.view, cb::ExportLevel::fine);
    ASSERT_EQ(colour.size(), baked.view.fine_count);
    uint32_t most = 0;
    for (uint32_t c = 0; c < colour.size(); ++c) {
        most = std::max(most, colour[c]);
        for (uint32_t o : neighbours[c]) EXPECT_NE(colour[c], colour[o]) << "clusters " << c << " and " << o;
    }
    EXPECT_LT(most, cb::export_palette_size);  // no cluster of a surface needs a colour past the palette
}
