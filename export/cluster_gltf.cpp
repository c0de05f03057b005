#include "cluster_gltf.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>

namespace cb {
namespace {

constexpr double pi = 3.14159265358979323846;
constexpr int gl_array_buffer = 34962, gl_element_array_buffer = 34963;
constexpr int gl_unsigned_short = 5123, gl_unsigned_int = 5125, gl_float = 5126;
constexpr int gl_lines = 1;

// ---- the level's clusters, mesh by mesh

uint32_t level_first(const MeshRecord& m, ExportLevel level) {
    return level == ExportLevel::fine ? m.first_fine : m.first_coarse;
}
uint32_t level_count(const MeshRecord& m, ExportLevel level) {
    return level == ExportLevel::fine ? m.fine_count : m.coarse_count;
}
const LevelBounds& level_bounds(const AssetView& v, ExportLevel level) {
    return level == ExportLevel::fine ? v.fine_bounds : v.coarse_bounds;
}

// The fine clusters (mesh-local, [first, first + count)) that make cluster `c` (mesh-local) of the level.
ClusterRange fine_range(const AssetView& v, const MeshRecord& m, ExportLevel level, uint32_t c) {
    if (level == ExportLevel::fine) return {c, 1};
    return v.coarse[m.first_coarse + c];
}

// Calls f(corners) with the mesh-local vertex indices of each triangle of cluster `c`, in stored order.
template <class F>
void for_each_triangle(const AssetView& v, const MeshRecord& m, ExportLevel level, uint32_t c, F&& f) {
    ClusterRange r = fine_range(v, m, level, c);
    for (uint32_t fc = r.first; fc < r.first + r.count; ++fc) {
        const FineCluster& fine = v.fine[m.first_fine + fc];
        for (uint32_t t = fine.first_triangle; t < fine.first_triangle + fine.triangle_count; ++t) {
            uint32_t corners[3];
            v.triangle(m, fc, t, corners);
            f(corners);
        }
    }
}

// A position as a sortable key; +0.0f folds -0 into 0, so equal coordinates give equal keys.
struct Corner {
    uint32_t key[3];
    uint32_t cluster;
    auto operator<=>(const Corner&) const = default;
};

Corner corner_of(const float* p, uint32_t cluster) {
    Corner c{};
    for (int k = 0; k < 3; ++k) {
        float f = p[k] + 0.0f;
        std::memcpy(&c.key[k], &f, 4);
    }
    c.cluster = cluster;
    return c;
}

// ---- colours

void hsv_to_linear(double hue, double sat, double val, double rgb[3]) {
    double h = std::fmod(hue, 360.0) / 60.0, c = val * sat, x = c * (1 - std::fabs(std::fmod(h, 2.0) - 1));
    double r = 0, g = 0, b = 0;
    switch (int(h)) {
        case 0:
            r = c;
            g = x;
            break;
        case 1:
            r = x;
            g = c;
            break;
        case 2:
            g = c;
            b = x;
            break;
        case 3:
            g = x;
            b = c;
            break;
        case 4:
            r = x;
            b = c;
            break;
        default:
            r = c;
            b = x;
            break;
    }
    double m = val - c, srgb[3] = {r + m, g + m, b + m};
    for (int k = 0; k < 3; ++k)  // glTF colour factors are linear, screens show sRGB
        rgb[k] = srgb[k] <= 0.04045 ? srgb[k] / 12.92 : std::pow((srgb[k] + 0.055) / 1.055, 2.4);
}

// ---- instance transforms as glTF nodes

struct Trs {
    double translation[3], rotation[4], scale[3];  // rotation: unit quaternion x, y, z, w
};

double dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
void cross3(const double* a, const double* b, double* out) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}
void normalize3(double* a) {
    double len = std::sqrt(dot3(a, a));
    for (int k = 0; k < 3; ++k) a[k] /= len;
}

// Some unit vector orthogonal to unit `a`.
void perpendicular(const double* a, double* out) {
    int smallest = std::fabs(a[0]) <= std::fabs(a[1]) && std::fabs(a[0]) <= std::fabs(a[2]) ? 0
        : std::fabs(a[1]) <= std::fabs(a[2])                                                ? 1
                                                                                            : 2;
    double e[3] = {0, 0, 0};
    e[smallest] = 1;
    cross3(a, e, out);
    normalize3(out);
}

// Columns col[i] of which known[i] are unit and orthogonal, the others filled in so the frame is
// right-handed where they leave it free (a zero scale along an axis leaves that axis undefined).
void complete_frame(double col[3][3], const bool known[3]) {
    int n = known[0] + known[1] + known[2];
    if (n == 3) return;
    if (n == 0) {
        for (int i = 0; i < 3; ++i)
            for (int k = 0; k < 3; ++k) col[i][k] = i == k ? 1 : 0;
        return;
    }
    int a = known[0] ? 0 : known[1] ? 1 : 2;
    if (n == 1) perpendicular(col[a], col[(a + 1) % 3]);
    for (int i = 0; i < 3; ++i)  // each missing column the cross product of the next two
        if (!known[i] && !(n == 1 && i == (a + 1) % 3)) cross3(col[(i + 1) % 3], col[(i + 2) % 3], col[i]);
}

double det3(const double col[3][3]) {
    double c[3];
    cross3(col[0], col[1], c);
    return dot3(c, col[2]);
}

// The Hamilton quaternion (x, y, z, w) of the rotation whose matrix has columns col (docs/FORMAT.md's
// convention), normalised. Shepperd's choice of the largest diagonal term keeps it accurate.
void quaternion_of(const double col[3][3], double q[4]) {
    auto m = [&](int row, int c) { return col[c][row]; };
    double trace = m(0, 0) + m(1, 1) + m(2, 2);
    if (trace > 0) {
        double s = std::sqrt(trace + 1) * 2;
        q[3] = s / 4;
        q[0] = (m(2, 1) - m(1, 2)) / s;
        q[1] = (m(0, 2) - m(2, 0)) / s;
        q[2] = (m(1, 0) - m(0, 1)) / s;
    } else if (m(0, 0) > m(1, 1) && m(0, 0) > m(2, 2)) {
        double s = std::sqrt(1 + m(0, 0) - m(1, 1) - m(2, 2)) * 2;
        q[3] = (m(2, 1) - m(1, 2)) / s;
        q[0] = s / 4;
        q[1] = (m(0, 1) + m(1, 0)) / s;
        q[2] = (m(0, 2) + m(2, 0)) / s;
    } else if (m(1, 1) > m(2, 2)) {
        double s = std::sqrt(1 + m(1, 1) - m(0, 0) - m(2, 2)) * 2;
        q[3] = (m(0, 2) - m(2, 0)) / s;
        q[0] = (m(0, 1) + m(1, 0)) / s;
        q[1] = s / 4;
        q[2] = (m(1, 2) + m(2, 1)) / s;
    } else {
        double s = std::sqrt(1 + m(2, 2) - m(0, 0) - m(1, 1)) * 2;
        q[3] = (m(1, 0) - m(0, 1)) / s;
        q[0] = (m(0, 2) + m(2, 0)) / s;
        q[1] = (m(1, 2) + m(2, 1)) / s;
        q[2] = s / 4;
    }
    double len = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int k = 0; k < 4; ++k) q[k] /= len;
}

// Eigenvectors (columns of vec) and eigenvalues of symmetric `a`, by cyclic Jacobi rotations.
void symmetric_eigen(double a[3][3], double vec[3][3], double val[3]) {
    for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k) vec[i][k] = i == k ? 1 : 0;
    for (int sweep = 0; sweep < 64; ++sweep) {
        double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        double diag = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
        if (off <= 1e-32 * diag) break;
        for (int p = 0; p < 2; ++p)
            for (int q = p + 1; q < 3; ++q) {
                if (a[p][q] == 0) continue;
                double theta = (a[q][q] - a[p][p]) / (2 * a[p][q]);
                double t = (theta >= 0 ? 1 : -1) / (std::fabs(theta) + std::sqrt(theta * theta + 1));
                double c = 1 / std::sqrt(t * t + 1), s = t * c;
                for (int k = 0; k < 3; ++k) {  // a = J^T a J, rows and columns p and q
                    double akp = a[k][p], akq = a[k][q];
                    a[k][p] = c * akp - s * akq;
                    a[k][q] = s * akp + c * akq;
                }
                for (int k = 0; k < 3; ++k) {
                    double apk = a[p][k], aqk = a[q][k];
                    a[p][k] = c * apk - s * aqk;
                    a[q][k] = s * apk + c * aqk;
                }
                for (int k = 0; k < 3; ++k) {  // vec[i] is column i
                    double vp = vec[p][k], vq = vec[q][k];
                    vec[p][k] = c * vp - s * vq;
                    vec[q][k] = s * vp + c * vq;
                }
            }
    }
    for (int i = 0; i < 3; ++i) val[i] = a[i][i];
}

// An instance's transform as a root node's TRS and, when it shears, a child's rotation (see the header).
struct InstanceNodes {
    Trs root;
    bool sheared = false;
    double child_rotation[4] = {0, 0, 0, 1};
};

InstanceNodes instance_nodes(const double* transform) {
    InstanceNodes out;
    double col[3][3];
    for (int i = 0; i < 3; ++i) {
        out.root.translation[i] = transform[9 + i];
        for (int k = 0; k < 3; ++k) col[i][k] = transform[i * 3 + k];
    }
    double norm[3];
    for (int i = 0; i < 3; ++i) norm[i] = std::sqrt(dot3(col[i], col[i]));
    double largest = std::max({norm[0], norm[1], norm[2]});
    // Columns orthogonal to about double precision: a plain rotation and scale.
    bool orthogonal = true;
    for (int i = 0; i < 3; ++i)
        for (int k = i + 1; k < 3; ++k)
            if (std::fabs(dot3(col[i], col[k])) > 1e-12 * largest * largest) orthogonal = false;
    double rotation[3][3];
    bool known[3];
    if (orthogonal) {
        for (int i = 0; i < 3; ++i) {
            out.root.scale[i] = norm[i];
            known[i] = norm[i] > 0;
            for (int k = 0; k < 3; ++k) rotation[i][k] = known[i] ? col[i][k] / norm[i] : 0;
        }
    } else {
        // M = U S V^T: V and S^2 from the eigen-decomposition of M^T M, U = M V / S.
        out.sheared = true;
        double gram[3][3], v[3][3], lambda[3];
        for (int i = 0; i < 3; ++i)
            for (int k = 0; k < 3; ++k) gram[i][k] = dot3(col[i], col[k]);
        symmetric_eigen(gram, v, lambda);
        for (int i = 0; i < 3; ++i) normalize3(v[i]);
        if (det3(v) < 0)
            for (int k = 0; k < 3; ++k) v[2][k] = -v[2][k];
        double sigma_max = std::sqrt(std::max({lambda[0], lambda[1], lambda[2], 0.0}));
        for (int i = 0; i < 3; ++i) {
            double sigma = std::sqrt(std::max(lambda[i], 0.0));
            out.root.scale[i] = sigma;
            known[i] = sigma > 1e-12 * sigma_max;
            for (int k = 0; k < 3; ++k)
                rotation[i][k] =
                    known[i] ? (col[0][k] * v[i][0] + col[1][k] * v[i][1] + col[2][k] * v[i][2]) / sigma : 0;
        }
        double vt[3][3];  // V^T's columns
        for (int i = 0; i < 3; ++i)
            for (int k = 0; k < 3; ++k) vt[i][k] = v[k][i];
        quaternion_of(vt, out.child_rotation);
    }
    complete_frame(rotation, known);
    if (det3(rotation) < 0) {  // a mirror: one negative scale, as glTF allows
        out.root.scale[0] = -out.root.scale[0];
        for (int k = 0; k < 3; ++k) rotation[0][k] = -rotation[0][k];
    }
    quaternion_of(rotation, out.root.rotation);
    return out;
}

// ---- overlays: line segments in the mesh's frame

using Lines = std::vector<float>;  // x, y, z per end, two ends per segment

void segment(Lines& out, const double* a, const double* b) {
    for (int k = 0; k < 3; ++k) out.push_back(float(a[k]));
    for (int k = 0; k < 3; ++k) out.push_back(float(b[k]));
}

// Points c + r (cos t u + sin t v) for t from t0 to t1, joined by `steps` segments.
void arc(Lines& out, const double* c, double r, const double* u, const double* v, double t0, double t1, int steps) {
    double prev[3];
    for (int s = 0; s <= steps; ++s) {
        double t = t0 + (t1 - t0) * s / steps, p[3];
        for (int k = 0; k < 3; ++k) p[k] = c[k] + r * (std::cos(t) * u[k] + std::sin(t) * v[k]);
        if (s > 0) segment(out, prev, p);
        std::memcpy(prev, p, sizeof p);
    }
}

constexpr int circle_steps = 16;

void box_lines(Lines& out, const Obb& box) {
    double half[3], corner[8][3];
    padded_halves(box, half);  // the corners of a box that holds the stored one
    for (int i = 0; i < 8; ++i)
        for (int k = 0; k < 3; ++k) {
            corner[i][k] = box.center[k];
            for (int a = 0; a < 3; ++a) corner[i][k] += (i >> a & 1 ? half[a] : -half[a]) * double(box.axis[a][k]);
        }
    for (int i = 0; i < 8; ++i)
        for (int bit = 1; bit < 8; bit <<= 1)
            if (!(i & bit)) segment(out, corner[i], corner[i | bit]);
}

void sphere_lines(Lines& out, const float* centre, double radius) {
    const double c[3] = {centre[0], centre[1], centre[2]};
    const double axes[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    for (int i = 0; i < 3; ++i) arc(out, c, radius, axes[i], axes[(i + 1) % 3], 0, 2 * pi, circle_steps);
}

void capsule_lines(Lines& out, const Capsule& cap) {
    double a[3] = {cap.a[0], cap.a[1], cap.a[2]}, b[3] = {cap.b[0], cap.b[1], cap.b[2]}, w[3], r = cap.radius;
    for (int k = 0; k < 3; ++k) w[k] = b[k] - a[k];
    if (dot3(w, w) == 0) return sphere_lines(out, cap.a, r);  // a capsule that is a sphere
    normalize3(w);
    double u[3], v[3], minus_w[3] = {-w[0], -w[1], -w[2]};
    perpendicular(w, u);
    cross3(w, u, v);
    arc(out, a, r, u, v, 0, 2 * pi, circle_steps);  // the end circles
    arc(out, b, r, u, v, 0, 2 * pi, circle_steps);
    for (const double* side : {u, v})  // the caps' outlines, bulging away from the segment
        for (double sign : {1.0, -1.0}) {
            double pa[3], pb[3];
            for (int k = 0; k < 3; ++k) {
                pa[k] = a[k] + sign * r * side[k];
                pb[k] = b[k] + sign * r * side[k];
            }
            segment(out, pa, pb);
        }
    for (const double* side : {u, v}) {
        arc(out, b, r, side, w, 0, pi, circle_steps / 2);
        arc(out, a, r, side, minus_w, 0, pi, circle_steps / 2);
    }
}

// The cone's axis from its front apex, as long as the cluster's box's largest half-extent.
void cone_lines(Lines& out, const Cone& cone, const Obb& box) {
    double length = std::max({double(box.half[0]), double(box.half[1]), double(box.half[2])});
    double from[3], to[3];
    for (int k = 0; k < 3; ++k) {
        from[k] = cone.front_apex[k];
        to[k] = from[k] + length * double(cone.axis[k]);
    }
    segment(out, from, to);
}

const char* overlay_name(int kind) {
    static const char* names[4] = {"obb", "sphere", "capsule", "cone"};
    return names[kind];
}

// ---- the GLB: one binary buffer, JSON built beside it

class Glb {
public:
    nlohmann::json accessors = nlohmann::json::array(), views = nlohmann::json::array();

    // A buffer view of `bytes`, 4-byte aligned in the buffer; its index.
    size_t add_view(const void* data, size_t bytes, int target) {
        bin_.resize((bin_.size() + 3) & ~size_t(3), 0);
        size_t offset = bin_.size();
        bin_.insert(bin_.end(), static_cast<const uint8_t*>(data), static_cast<const uint8_t*>(data) + bytes);
        views.push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}, {"target", target}});
        return views.size() - 1;
    }

    // xyz floats as a POSITION accessor with its bounds, which glTF requires; its index.
    size_t add_positions(const std::vector<float>& xyz) {
        size_t view = add_view(xyz.data(), xyz.size() * sizeof(float), gl_array_buffer);
        std::array<float, 3> lo = {xyz[0], xyz[1], xyz[2]}, hi = lo;
        for (size_t i = 0; i < xyz.size(); i += 3)
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], xyz[i + k]);
                hi[k] = std::max(hi[k], xyz[i + k]);
            }
        accessors.push_back({{"bufferView", view},
                             {"componentType", gl_float},
                             {"count", xyz.size() / 3},
                             {"type", "VEC3"},
                             {"min", {lo[0], lo[1], lo[2]}},
                             {"max", {hi[0], hi[1], hi[2]}}});
        return accessors.size() - 1;
    }

    size_t add_indices(size_t view, size_t byte_offset, size_t count, int component) {
        accessors.push_back({{"bufferView", view},
                             {"byteOffset", byte_offset},
                             {"componentType", component},
                             {"count", count},
                             {"type", "SCALAR"}});
        return accessors.size() - 1;
    }

    // The file: header, JSON chunk padded with spaces, binary chunk padded with zeros.
    std::vector<uint8_t> bytes(nlohmann::json& doc) {
        bin_.resize((bin_.size() + 3) & ~size_t(3), 0);
        if (!bin_.empty()) doc["buffers"] = {{{"byteLength", bin_.size()}}};
        if (!views.empty()) doc["bufferViews"] = views;
        if (!accessors.empty()) doc["accessors"] = accessors;
        std::string text = doc.dump();
        text.resize((text.size() + 3) & ~size_t(3), ' ');
        std::vector<uint8_t> out;
        size_t total = 12 + 8 + text.size() + (bin_.empty() ? 0 : 8 + bin_.size());
        auto u32 = [&](uint32_t x) {
            for (int k = 0; k < 4; ++k) out.push_back(uint8_t(x >> (8 * k)));
        };
        if (total > UINT32_MAX) throw std::invalid_argument("the glTF would exceed the 4 GiB a GLB can hold");
        out.reserve(total);
        u32(0x46546C67);  // "glTF"
        u32(2);
        u32(uint32_t(total));
        u32(uint32_t(text.size()));
        u32(0x4E4F534A);  // "JSON"
        out.insert(out.end(), text.begin(), text.end());
        if (!bin_.empty()) {
            u32(uint32_t(bin_.size()));
            u32(0x004E4942);  // "BIN\0"
            out.insert(out.end(), bin_.begin(), bin_.end());
        }
        return out;
    }

private:
    std::vector<uint8_t> bin_;
};

nlohmann::json array3(const double* v) { return {v[0], v[1], v[2]}; }

}  // namespace

bool parse_volume_overlays(const std::string& text, uint32_t& out) {
    out = 0;
    std::stringstream in(text);
    std::string name;
    while (std::getline(in, name, ',')) {
        if (name == "obb")
            out |= overlay_obb;
        else if (name == "sphere")
            out |= overlay_sphere;
        else if (name == "capsule")
            out |= overlay_capsule;
        else
            return false;
    }
    return out != 0 && text.back() != ',';
}

std::string export_options_error(const AssetView& view, const ExportOptions& options) {
    const LevelBounds& b = level_bounds(view, options.level);
    const std::string level = options.level == ExportLevel::fine ? "fine" : "coarse";
    struct Need {
        uint32_t bit;
        const void* section;
        const char* what;
        const char* bounds;
    };
    for (const Need& n :
         {Need{overlay_obb, b.obbs, "boxes", "obb"}, Need{overlay_sphere, b.spheres, "spheres", "sphere"},
          Need{overlay_capsule, b.capsules, "capsules", "capsule"},
          Need{overlay_cone, b.cones, "normal cones", "cone"}})
        if ((options.overlays & n.bit) && !n.section)
            return "the asset has no " + level + " " + n.what + " (bake it with --bounds naming " + n.bounds + ")";
    return {};
}

std::vector<std::vector<uint32_t>> cluster_neighbours(const AssetView& view, ExportLevel level) {
    std::vector<std::vector<uint32_t>> out(level == ExportLevel::fine ? view.fine_count : view.coarse_count);
    std::vector<Corner> corners;
    for (uint32_t mi = 0; mi < view.mesh_count; ++mi) {
        const MeshRecord& m = view.meshes[mi];
        const uint32_t first = level_first(m, level);
        corners.clear();
        for (uint32_t c = 0; c < level_count(m, level); ++c)
            for_each_triangle(view, m, level, c, [&](const uint32_t* t) {
                for (int k = 0; k < 3; ++k) corners.push_back(corner_of(view.position(m, t[k]), first + c));
            });
        std::sort(corners.begin(), corners.end());
        corners.erase(std::unique(corners.begin(), corners.end()), corners.end());
        // Every two clusters with a corner at one position are neighbours.
        for (size_t at = 0; at < corners.size();) {
            size_t end = at + 1;
            while (end < corners.size() && std::equal(corners[at].key, corners[at].key + 3, corners[end].key)) ++end;
            for (size_t i = at; i < end; ++i)
                for (size_t k = at; k < end; ++k)
                    if (i != k) out[corners[i].cluster].push_back(corners[k].cluster);
            at = end;
        }
    }
    for (std::vector<uint32_t>& list : out) {
        std::sort(list.begin(), list.end());
        list.erase(std::unique(list.begin(), list.end()), list.end());
    }
    return out;
}

std::vector<uint32_t> cluster_colours(const AssetView& view, ExportLevel level) {
    const std::vector<std::vector<uint32_t>> neighbours = cluster_neighbours(view, level);
    const uint32_t n = uint32_t(neighbours.size()), none = UINT32_MAX;
    // Smallest-last order: repeatedly take out a cluster of least remaining degree; colour in reverse.
    std::vector<uint32_t> degree(n), order;
    std::set<std::pair<uint32_t, uint32_t>> by_degree;
    for (uint32_t c = 0; c < n; ++c) by_degree.insert({degree[c] = uint32_t(neighbours[c].size()), c});
    std::vector<bool> removed(n, false);
    order.reserve(n);
    while (!by_degree.empty()) {
        uint32_t c = by_degree.begin()->second;
        by_degree.erase(by_degree.begin());
        removed[c] = true;
        order.push_back(c);
        for (uint32_t o : neighbours[c])
            if (!removed[o]) {
                by_degree.erase({degree[o], o});
                by_degree.insert({--degree[o], o});
            }
    }
    std::vector<uint32_t> colour(n, none);
    std::vector<size_t> used(export_palette_size, 0);
    std::vector<bool> taken;
    for (auto it = order.rbegin(); it != order.rend(); ++it) {
        taken.assign(export_palette_size + neighbours[*it].size() + 1, false);
        for (uint32_t o : neighbours[*it])
            if (colour[o] != none && colour[o] < taken.size()) taken[colour[o]] = true;
        uint32_t pick = none;
        for (uint32_t k = 0; k < export_palette_size; ++k)  // the least used free palette colour, balancing them
            if (!taken[k] && (pick == none || used[k] < used[pick])) pick = k;
        if (pick == none)
            for (pick = export_palette_size; taken[pick];) ++pick;
        if (pick < export_palette_size) ++used[pick];
        colour[*it] = pick;
    }
    return colour;
}

void export_colour(uint32_t k, double rgb[3]) {
    if (k < export_palette_size) {
        bool bright = k < export_palette_size / 2;
        static const double hue[6] = {0, 120, 240, 60, 180, 300};
        hsv_to_linear(hue[k % 6] + (bright ? 0 : 30), bright ? 0.85 : 0.9, bright ? 0.95 : 0.6, rgb);
        return;
    }
    hsv_to_linear(std::fmod(k * 137.50776405003785, 360.0), 0.7, k % 2 ? 0.9 : 0.55, rgb);
}

std::vector<uint8_t> export_clusters_glb(const AssetView& view, const ExportOptions& options, ExportSummary* summary) {
    std::string error = export_options_error(view, options);
    if (!error.empty()) throw std::invalid_argument(error);
    const ExportLevel level = options.level;
    const LevelBounds& bounds = level_bounds(view, level);
    const std::vector<uint32_t> colour = cluster_colours(view, level);
    ExportSummary s;
    s.meshes = view.mesh_count;
    s.instances = view.instance_count;
    s.clusters = colour.size();

    // Materials: one per colour class in use, and an unlit one per colour the lines use.
    std::set<uint32_t> colours(colour.begin(), colour.end()), line_colours;
    std::map<uint32_t, size_t> lit_material, line_material;
    for (uint32_t k : colours) lit_material.emplace(k, lit_material.size());

    Glb glb;
    nlohmann::json meshes = nlohmann::json::array();
    std::vector<int64_t> gltf_mesh(view.mesh_count, -1);
    struct LineSet {
        size_t accessor;
        int kind;
        uint32_t colour;
    };
    for (uint32_t mi = 0; mi < view.mesh_count; ++mi) {
        const MeshRecord& m = view.meshes[mi];
        const uint32_t first = level_first(m, level), count = level_count(m, level);
        if (count == 0) continue;
        nlohmann::json primitives = nlohmann::json::array();
        // The mesh's vertices once, shared by its clusters' primitives; each cluster a slice of one index view.
        std::vector<float> xyz(view.positions + size_t(m.first_vertex) * 3,
                               view.positions + size_t(m.first_vertex + m.vertex_count) * 3);
        size_t positions = glb.add_positions(xyz);
        // 16-bit indices while no index can be the primitive-restart value 65535.
        const bool wide = m.vertex_count >= 65535;
        const size_t index_size = wide ? 4 : 2;
        std::vector<uint8_t> indices;
        indices.reserve(size_t(m.triangle_count) * 3 * index_size);
        std::vector<std::pair<size_t, size_t>> slices;  // byte offset and index count per cluster
        for (uint32_t c = 0; c < count; ++c) {
            size_t at = indices.size();
            for_each_triangle(view, m, level, c, [&](const uint32_t* t) {
                for (int k = 0; k < 3; ++k)
                    for (size_t b = 0; b < index_size; ++b)
                        indices.push_back(uint8_t(t[k] >> (8 * b)));  // little-endian
            });
            slices.push_back({at, (indices.size() - at) / index_size});
        }
        size_t index_view = glb.add_view(indices.data(), indices.size(), gl_element_array_buffer);
        for (uint32_t c = 0; c < count; ++c) {
            size_t accessor = glb.add_indices(index_view, slices[c].first, slices[c].second,
                                              wide ? gl_unsigned_int : gl_unsigned_short);
            primitives.push_back({{"attributes", {{"POSITION", positions}}},
                                  {"indices", accessor},
                                  {"material", lit_material.at(colour[first + c])},
                                  {"extras", {{"cluster", first + c}}}});
            s.triangles += slices[c].second / 3;
        }

        // Overlays: per kind and colour one LINES primitive holding every such cluster's wireframe.
        std::map<std::pair<int, uint32_t>, Lines> lines;
        for (uint32_t c = 0; c < count && options.overlays; ++c) {
            const uint32_t i = first + c, k = colour[i];
            if (options.overlays & overlay_obb) box_lines(lines[{0, k}], bounds.obb(i));
            if (options.overlays & overlay_sphere)
                sphere_lines(lines[{1, k}], bounds.spheres[i].center, bounds.spheres[i].radius);
            if (options.overlays & overlay_capsule) capsule_lines(lines[{2, k}], bounds.capsules[i]);
            if (options.overlays & overlay_cone) {
                Cone cone = bounds.cone(i);
                if (cone.valid) cone_lines(lines[{3, k}], cone, bounds.obb(i));
                s.cones += cone.valid;
            }
        }
        std::vector<LineSet> sets;
        for (const auto& [key, xyz_lines] : lines)
            if (!xyz_lines.empty()) sets.push_back({glb.add_positions(xyz_lines), key.first, key.second});
        for (const LineSet& set : sets) {
            line_colours.insert(set.colour);
            primitives.push_back({{"attributes", {{"POSITION", set.accessor}}},
                                  {"mode", gl_lines},
                                  {"material", set.colour},  // the colour class for now; a material index below
                                  {"extras", {{"overlay", overlay_name(set.kind)}}}});
            ++s.line_primitives;
        }
        gltf_mesh[mi] = int64_t(meshes.size());
        meshes.push_back({{"name", "mesh " + std::to_string(mi)}, {"primitives", primitives}});
    }
    for (uint32_t k : line_colours) line_material.emplace(k, lit_material.size() + line_material.size());
    for (nlohmann::json& mesh : meshes)
        for (nlohmann::json& p : mesh["primitives"])
            if (p.contains("mode")) p["material"] = line_material.at(p["material"].get<uint32_t>());

    nlohmann::json materials = nlohmann::json::array();
    auto material = [&](uint32_t k, bool lines) {
        double rgb[3];
        export_colour(k, rgb);
        nlohmann::json j = {
            {"name", "colour " + std::to_string(k) + (lines ? " lines" : "")},
            {"pbrMetallicRoughness",
             {{"baseColorFactor", {rgb[0], rgb[1], rgb[2], 1.0}}, {"metallicFactor", 0.0}, {"roughnessFactor", 0.8}}}};
        if (lines)  // lines have no normals to light them by
            j["extensions"] = {{"KHR_materials_unlit", nlohmann::json::object()}};
        else  // clusters of open surfaces are seen from both sides
            j["doubleSided"] = true;
        materials.push_back(j);
    };
    for (const auto& [k, index] : lit_material) material(k, false);
    for (const auto& [k, index] : line_material) material(k, true);

    nlohmann::json nodes = nlohmann::json::array(), roots = nlohmann::json::array();
    for (uint32_t i = 0; i < view.instance_count; ++i) {
        const InstanceRecord& inst = view.instances[i];
        InstanceNodes n = instance_nodes(inst.transform);
        nlohmann::json root = {
            {"name", "instance " + std::to_string(i)},
            {"translation", array3(n.root.translation)},
            {"rotation", {n.root.rotation[0], n.root.rotation[1], n.root.rotation[2], n.root.rotation[3]}},
            {"scale", array3(n.root.scale)}};
        nlohmann::json holder = {
            {"name", "instance " + std::to_string(i) + " shear"},
            {"rotation", {n.child_rotation[0], n.child_rotation[1], n.child_rotation[2], n.child_rotation[3]}}};
        nlohmann::json& with_mesh = n.sheared ? holder : root;
        if (gltf_mesh[inst.mesh] >= 0) with_mesh["mesh"] = gltf_mesh[inst.mesh];
        roots.push_back(nodes.size());
        if (n.sheared) {
            root["children"] = {nodes.size() + 1};
            ++s.sheared_instances;
        }
        nodes.push_back(root);
        if (n.sheared) nodes.push_back(holder);
    }

    nlohmann::json doc = {{"asset", {{"version", "2.0"}}}};
    if (!options.generator.empty()) doc["asset"]["generator"] = options.generator;
    if (!line_material.empty()) doc["extensionsUsed"] = {"KHR_materials_unlit"};
    if (!roots.empty()) {
        doc["scene"] = 0;
        doc["scenes"] = {
            {{"name", level == ExportLevel::fine ? "fine clusters" : "coarse clusters"}, {"nodes", roots}}};
        doc["nodes"] = nodes;
    }
    if (!meshes.empty()) doc["meshes"] = meshes;
    if (!materials.empty()) doc["materials"] = materials;
    std::vector<uint8_t> out = glb.bytes(doc);

    s.nodes = nodes.size();
    s.colours = colours.size();
    s.materials = materials.size();
    s.bytes = out.size();
    if (summary) *summary = s;
    return out;
}

}  // namespace cb
