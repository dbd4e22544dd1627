#include "solver/visibility.h"

#include <embree3/rtcore.h>
#include <pmmintrin.h>
#include <xmmintrin.h>

#include <string>
#include <vector>

#include "core/counters.h"
#include "core/error.h"

namespace penumbra {

namespace {
// Embree calls this from C code, so it must not throw: it records, and `check` throws afterwards.
void embreeError(void* user, RTCError code, const char* message) {
    auto* last = static_cast<std::string*>(user);
    if (last->empty()) *last = cat("Embree error ", int(code), ": ", message ? message : "(no message)");
}

const Counter g_occlusionRays("rays.occlusion", "occlusion (shadow) rays traced, all stages");
const Counter g_nearestRays("rays.nearest", "nearest-hit rays traced, all stages");
const Counter g_scenesBuilt("rays.scenes_built", "ray-tracing scenes (Embree BVHs) built");

// Geometry ids in the views' scenes.
constexpr unsigned kPatchGeometry = 0;   // the patches (in the Exact view's, all but the spheres' facets)
constexpr unsigned kSphereGeometry = 1;  // the exact spheres (the Exact view's only)
}  // namespace

uint64_t raysCast() { return g_occlusionRays.value() + g_nearestRays.value(); }

void prepareTracingThread() {
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
}

struct RayScene::Impl {
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;  // the Patches view: every patch, primitive id = patch index
    // The Exact view, where there are exact spheres: the other patches (exactPatch: primitive ->
    // patch) and the spheres. Its own scene, not the same one told apart by ray masks: a ball's
    // facets lie just inside its sphere, where every light path through the ball starts or ends,
    // and masked primitives still cost their traversal (cornell-glass's paths: 852 facets).
    RTCScene exact = nullptr;
    std::vector<unsigned> exactPatch;
    std::string error;
    size_t patchTotal = 0, sphereTotal = 0;
    std::vector<RaySphere> spheres;
    std::vector<char> replaced;  // per patch: a facet of an exact sphere
    void check(const char* during) {
        if (!error.empty()) throw Error(cat(error, " (while ", during, ")"));
    }
    RTCScene newScene() {
        RTCScene s = rtcNewScene(device);
        rtcSetSceneBuildQuality(s, RTC_BUILD_QUALITY_HIGH);
        // Watertight edges: a ray through the seam of two touching patches must not slip between
        // them (the classic light leak along wall-floor and wall-ceiling joints).
        rtcSetSceneFlags(s, RTC_SCENE_FLAG_ROBUST);
        return s;
    }
    // The quads of patches ids[k] (primitive k) into a new geometry of `into`.
    void addQuads(RTCScene into, const PatchSet& patches, const std::vector<unsigned>& ids, unsigned id) {
        RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_QUAD);
        const size_t n = ids.size();
        auto* vb = static_cast<float*>(
            rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 4 * n));
        auto* ib = static_cast<unsigned*>(
            rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT4, 4 * sizeof(unsigned), n));
        for (size_t q = 0; q < n; ++q) {
            for (size_t k = 0; k < 4; ++k) {
                const Vec3& p = patches.corners[ids[q]][k];
                vb[3 * (4 * q + k) + 0] = float(p.x());
                vb[3 * (4 * q + k) + 1] = float(p.y());
                vb[3 * (4 * q + k) + 2] = float(p.z());
                ib[4 * q + k] = unsigned(4 * q + k);
            }
        }
        rtcCommitGeometry(geom);
        rtcAttachGeometryByID(into, geom, id);
        rtcReleaseGeometry(geom);
    }
    RTCScene sceneOf(RayView view) const { return view == RayView::Exact && exact ? exact : scene; }
};

RayScene::RayScene(const PatchSet& patches) : RayScene(patches, {}, {}) {}

RayScene::RayScene(const PatchSet& patches, const std::vector<RaySphere>& spheres, const std::vector<char>& replaced)
    : impl_(std::make_unique<Impl>()) {
    prepareTracingThread();
    impl_->device = rtcNewDevice("verbose=0");
    if (!impl_->device)
        throw Error(cat("Embree: cannot create a device (error ", int(rtcGetDeviceError(nullptr)), ")"));
    rtcSetDeviceErrorFunction(impl_->device, embreeError, &impl_->error);
    impl_->patchTotal = patches.size();
    std::vector<unsigned> all(patches.size());
    for (size_t i = 0; i < all.size(); ++i) all[i] = unsigned(i);
    impl_->scene = impl_->newScene();
    impl_->addQuads(impl_->scene, patches, all, kPatchGeometry);
    rtcCommitScene(impl_->scene);
    if (!spheres.empty()) {
        impl_->replaced = replaced;
        for (size_t i = 0; i < patches.size(); ++i)
            if (i >= replaced.size() || !replaced[i]) impl_->exactPatch.push_back(unsigned(i));
        impl_->exact = impl_->newScene();
        impl_->addQuads(impl_->exact, patches, impl_->exactPatch, kPatchGeometry);
        RTCGeometry points = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_SPHERE_POINT);
        auto* pb = static_cast<float*>(rtcSetNewGeometryBuffer(points, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4,
                                                               4 * sizeof(float), spheres.size()));
        for (size_t i = 0; i < spheres.size(); ++i) {
            pb[4 * i + 0] = float(spheres[i].center.x());
            pb[4 * i + 1] = float(spheres[i].center.y());
            pb[4 * i + 2] = float(spheres[i].center.z());
            pb[4 * i + 3] = float(spheres[i].radius);
        }
        rtcCommitGeometry(points);
        rtcAttachGeometryByID(impl_->exact, points, kSphereGeometry);
        rtcReleaseGeometry(points);
        impl_->sphereTotal = spheres.size();
        impl_->spheres = spheres;
        rtcCommitScene(impl_->exact);
    }
    impl_->check("building the ray-tracing scene");
    g_scenesBuilt.add();
}

void* RayScene::embreeScene(RayView view) const { return impl_->sceneOf(view); }
size_t RayScene::patchCount() const { return impl_->patchTotal; }
size_t RayScene::sphereCount() const { return impl_->sphereTotal; }
const std::vector<RaySphere>& RayScene::spheres() const { return impl_->spheres; }

bool RayScene::onExactSphere(size_t patch) const {
    return patch < impl_->replaced.size() && impl_->replaced[patch] != 0;
}

RayView RayScene::viewBetween(size_t a, size_t b) const {
    return impl_->sphereTotal > 0 && !onExactSphere(a) && !onExactSphere(b) ? RayView::Exact : RayView::Patches;
}

RayScene::~RayScene() {
    if (impl_->exact) rtcReleaseScene(impl_->exact);
    if (impl_->scene) rtcReleaseScene(impl_->scene);
    if (impl_->device) rtcReleaseDevice(impl_->device);
}

bool RayScene::occluded(const Vec3& from, const Vec3& to, double trim, RayView view) const {
    const Vec3 d = to - from;
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRay ray;
    ray.org_x = float(from.x());
    ray.org_y = float(from.y());
    ray.org_z = float(from.z());
    ray.dir_x = float(d.x());
    ray.dir_y = float(d.y());
    ray.dir_z = float(d.z());
    ray.tnear = float(trim);
    ray.tfar = float(1 - trim);
    ray.time = 0;
    ray.mask = ~0u;
    ray.id = 0;
    ray.flags = 0;
    rtcOccluded1(impl_->sceneOf(view), &context, &ray);
    g_occlusionRays.add();
    return ray.tfar < 0;
}

int RayScene::occluder(const Vec3& from, const Vec3& to, double trim, RayView view) const {
    const Hit h = intersect(from, to - from, trim, 1 - trim, view);
    return h.patch >= 0 ? h.patch : h.sphere >= 0 ? -2 : -1;
}

Hit RayScene::intersect(const Vec3& origin, const Vec3& dir, double tMin, double tMax, RayView view) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh;
    rh.ray.org_x = float(origin.x());
    rh.ray.org_y = float(origin.y());
    rh.ray.org_z = float(origin.z());
    rh.ray.dir_x = float(dir.x());
    rh.ray.dir_y = float(dir.y());
    rh.ray.dir_z = float(dir.z());
    rh.ray.tnear = float(tMin);
    rh.ray.tfar = float(std::min(tMax, 3e38));
    rh.ray.time = 0;
    rh.ray.mask = ~0u;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    const bool exact = view == RayView::Exact && impl_->exact;
    rtcIntersect1(exact ? impl_->exact : impl_->scene, &context, &rh);
    g_nearestRays.add();
    Hit hit;
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
    if (rh.hit.geomID == kPatchGeometry)
        hit.patch = int(exact ? impl_->exactPatch[rh.hit.primID] : rh.hit.primID);
    else
        hit.sphere = int(rh.hit.primID);
    hit.t = rh.ray.tfar;
    hit.u = rh.hit.u;
    hit.v = rh.hit.v;
    hit.geometricNormal = Vec3(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z);
    return hit;
}

}  // namespace penumbra
