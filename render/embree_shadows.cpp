#include "embree_shadows.h"

#include <embree3/rtcore.h>

#include <cb_segment.h>

#include <chrono>
#include <stdexcept>
#include <string>

#include "parallel.h"
#include "timing.h"

namespace cb {

struct EmbreeShadows::Scene {
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;
    std::vector<float> vertices;        // world xyz, float
    std::vector<uint32_t> triangles;    // corners, wound as in their mesh's frame
    std::vector<uint8_t> double_sided;  // per triangle
    bool one_sided = false;
    ~Scene() {
        if (scene) rtcReleaseScene(scene);
        if (device) rtcReleaseDevice(device);
    }
};

namespace {

// The context a query hands to the occlusion filter: the light (or the direction toward the sun), in double.
struct ShadowContext {
    RTCIntersectContext embree;  // first, so that Embree's pointer to it is a pointer to this
    const double* light;
    bool sun;
};

// One-sided occluders: a hit counts only on a triangle the light is behind (or a double-sided one).
void one_sided_filter(const RTCFilterFunctionNArguments* args) {
    const auto* scene = static_cast<const EmbreeShadows::Scene*>(args->geometryUserPtr);
    const auto* context = reinterpret_cast<const ShadowContext*>(args->context);
    for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] != -1) continue;
        const uint32_t t = RTCHitN_primID(args->hit, args->N, i);
        if (scene->double_sided[t]) continue;
        const float *a = &scene->vertices[size_t(scene->triangles[t * 3]) * 3],
                    *b = &scene->vertices[size_t(scene->triangles[t * 3 + 1]) * 3],
                    *c = &scene->vertices[size_t(scene->triangles[t * 3 + 2]) * 3];
        double e1[3], e2[3], to_light[3];
        for (int k = 0; k < 3; ++k) {
            e1[k] = double(b[k]) - a[k];
            e2[k] = double(c[k]) - a[k];
            to_light[k] = context->sun ? context->light[k] : context->light[k] - a[k];
        }
        const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                             e1[0] * e2[1] - e1[1] * e2[0]};
        if (n[0] * to_light[0] + n[1] * to_light[1] + n[2] * to_light[2] >= 0) args->valid[i] = 0;  // lit side
    }
}

}  // namespace

EmbreeShadows::EmbreeShadows(const LevelInput& level, bool one_sided, unsigned threads)
    : scene_(std::make_unique<Scene>()), threads_(threads) {
    auto start = std::chrono::steady_clock::now();
    Scene& s = *scene_;
    s.one_sided = one_sided;
    for (const LevelInstance& placed : level.instances) {
        const AssetView& view = *level.assets[placed.asset];
        const MeshRecord& mesh = view.meshes[placed.mesh];
        const double* m = placed.transform;
        const double det = m[0] * (m[4] * m[8] - m[7] * m[5]) - m[3] * (m[1] * m[8] - m[7] * m[2]) +
            m[6] * (m[1] * m[5] - m[4] * m[2]);
        const uint32_t base = uint32_t(s.vertices.size() / 3);
        for (uint32_t v = 0; v < mesh.vertex_count; ++v) {
            const float* p = view.position(mesh, v);
            const double local[3] = {p[0], p[1], p[2]};
            double w[3];
            apply_instance(m, local, w);
            for (int k = 0; k < 3; ++k) s.vertices.push_back(float(w[k]));
        }
        for (uint32_t k = 0; k < mesh.fine_count; ++k) {
            const FineCluster& f = view.fine[mesh.first_fine + k];
            for (uint32_t t = f.first_triangle; t < f.first_triangle + f.triangle_count; ++t) {
                uint32_t corner[3];
                view.triangle(mesh, k, t, corner);
                if (det < 0) std::swap(corner[1], corner[2]);  // a mirroring instance turns the winding over
                for (uint32_t c : corner) s.triangles.push_back(base + c);
                s.double_sided.push_back(view.double_sided(size_t(mesh.first_triangle) + t));
            }
        }
    }
    const std::string config = threads ? "threads=" + std::to_string(threads) : "";
    s.device = rtcNewDevice(config.c_str());
    if (!s.device) throw std::runtime_error("Embree: cannot create a device");
    s.scene = rtcNewScene(s.device);
    rtcSetSceneFlags(s.scene, RTC_SCENE_FLAG_ROBUST);
    if (!s.triangles.empty()) {
        RTCGeometry g = rtcNewGeometry(s.device, RTC_GEOMETRY_TYPE_TRIANGLE);
        // Embree reads the buffers in place (shared); its vertex buffer needs 4 bytes of room past the end.
        s.vertices.reserve(s.vertices.size() + 1);
        rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, s.vertices.data(), 0,
                                   3 * sizeof(float), s.vertices.size() / 3);
        rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, s.triangles.data(), 0,
                                   3 * sizeof(uint32_t), s.triangles.size() / 3);
        if (one_sided) {
            rtcSetGeometryUserData(g, &s);
            rtcSetGeometryOccludedFilterFunction(g, one_sided_filter);
        }
        rtcCommitGeometry(g);
        rtcAttachGeometry(s.scene, g);
        rtcReleaseGeometry(g);
    }
    rtcCommitScene(s.scene);
    if (rtcGetDeviceError(s.device) != RTC_ERROR_NONE) throw std::runtime_error("Embree: the scene did not build");
    build_seconds_ = seconds_since(start);
}

EmbreeShadows::~EmbreeShadows() = default;

std::vector<uint8_t> EmbreeShadows::occluded(const double* light, double bias, const double* points, size_t count,
                                             bool sun) const {
    std::vector<uint8_t> out(count, 0);
    const size_t chunk = 4096;
    parallel_for((count + chunk - 1) / chunk, threads_, [&](size_t c) {
        ShadowContext context;
        rtcInitIntersectContext(&context.embree);
        context.light = light;
        context.sun = sun;
        for (size_t i = c * chunk; i < std::min(count, c * chunk + chunk); ++i) {
            const double* p = &points[i * 3];
            RTCRay r;
            r.org_x = float(p[0]);
            r.org_y = float(p[1]);
            r.org_z = float(p[2]);
            if (sun) {
                r.dir_x = float(light[0]);
                r.dir_y = float(light[1]);
                r.dir_z = float(light[2]);
                r.tnear = float(sun_from(light, bias));
                r.tfar = INFINITY;
            } else {
                r.dir_x = float(light[0] - p[0]);
                r.dir_y = float(light[1] - p[1]);
                r.dir_z = float(light[2] - p[2]);
                r.tnear = float(shadow_from(p, light, bias));
                r.tfar = 1.0f;  // the runtime's self-shadowing rule
            }
            r.time = 0;
            r.mask = 0xffffffff;
            r.id = 0;
            r.flags = 0;
            rtcOccluded1(scene_->scene, &context.embree, &r);
            out[i] = r.tfar < 0;
        }
    });
    return out;
}

}  // namespace cb
