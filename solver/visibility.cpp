#include "solver/visibility.h"

#include <embree3/rtcore.h>
#include <pmmintrin.h>
#include <xmmintrin.h>

#include <atomic>
#include <deque>
#include <mutex>
#include <string>

#include "core/error.h"

namespace penumbra {

namespace {
// Embree calls this from C code, so it must not throw: it records, and `check` throws afterwards.
void embreeError(void* user, RTCError code, const char* message) {
    auto* last = static_cast<std::string*>(user);
    if (last->empty()) *last = cat("Embree error ", int(code), ": ", message ? message : "(no message)");
}
// One counter per thread, each on its own cache line: an increment never waits for another core.
struct alignas(64) RayCounter {
    std::atomic<uint64_t> rays{0};
};
std::mutex g_countersMutex;
std::deque<RayCounter> g_counters;  // a deque keeps addresses stable as threads register

RayCounter& threadCounter() {
    thread_local RayCounter* mine = [] {
        std::lock_guard<std::mutex> lock(g_countersMutex);
        return &g_counters.emplace_back();
    }();
    return *mine;
}

inline void countRay() {
    std::atomic<uint64_t>& c = threadCounter().rays;
    c.store(c.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
}
}  // namespace

uint64_t raysCast() {
    std::lock_guard<std::mutex> lock(g_countersMutex);
    uint64_t sum = 0;
    for (const RayCounter& c : g_counters) sum += c.rays.load(std::memory_order_relaxed);
    return sum;
}

void prepareTracingThread() {
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
}

struct RayScene::Impl {
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;
    std::string error;
    void check(const char* during) {
        if (!error.empty()) throw Error(cat(error, " (while ", during, ")"));
    }
};

RayScene::RayScene(const PatchSet& patches) : RayScene(patches, {}, {}) {}

RayScene::RayScene(const PatchSet& patches, const std::vector<RaySphere>& spheres, const std::vector<char>& skipPatch)
    : impl_(std::make_unique<Impl>()) {
    prepareTracingThread();
    impl_->device = rtcNewDevice("verbose=0");
    if (!impl_->device)
        throw Error(cat("Embree: cannot create a device (error ", int(rtcGetDeviceError(nullptr)), ")"));
    rtcSetDeviceErrorFunction(impl_->device, embreeError, &impl_->error);
    impl_->scene = rtcNewScene(impl_->device);
    rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_HIGH);
    // Watertight edges: a ray through the seam of two touching patches must not slip between them
    // (the classic light leak along wall-floor and wall-ceiling joints).
    rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_ROBUST);
    RTCGeometry geom = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_QUAD);
    const size_t n = patches.size();
    auto* vb = static_cast<float*>(
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 4 * n));
    auto* ib = static_cast<unsigned*>(
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT4, 4 * sizeof(unsigned), n));
    for (size_t i = 0; i < n; ++i)
        for (size_t k = 0; k < 4; ++k) {
            // A skipped patch collapses to a point, which no ray hits; ids stay patch indices.
            const bool skip = i < skipPatch.size() && skipPatch[i];
            const Vec3& p = patches.corners[i][skip ? 0 : k];
            vb[3 * (4 * i + k) + 0] = float(p.x());
            vb[3 * (4 * i + k) + 1] = float(p.y());
            vb[3 * (4 * i + k) + 2] = float(p.z());
            ib[4 * i + k] = unsigned(4 * i + k);
        }
    rtcCommitGeometry(geom);
    rtcAttachGeometryByID(impl_->scene, geom, 0);
    rtcReleaseGeometry(geom);
    if (!spheres.empty()) {
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
        rtcAttachGeometryByID(impl_->scene, points, 1);
        rtcReleaseGeometry(points);
    }
    rtcCommitScene(impl_->scene);
    impl_->check("building the ray-tracing scene");
}

void* RayScene::embreeScene() const { return impl_->scene; }

RayScene::~RayScene() {
    if (impl_->scene) rtcReleaseScene(impl_->scene);
    if (impl_->device) rtcReleaseDevice(impl_->device);
}

bool RayScene::occluded(const Vec3& from, const Vec3& to, double trim) const {
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
    ray.mask = 0xFFFFFFFF;
    ray.id = 0;
    ray.flags = 0;
    rtcOccluded1(impl_->scene, &context, &ray);
    countRay();
    return ray.tfar < 0;
}

Hit RayScene::intersect(const Vec3& origin, const Vec3& dir, double tMin, double tMax) const {
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
    rh.ray.mask = 0xFFFFFFFF;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(impl_->scene, &context, &rh);
    countRay();
    Hit hit;
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
    if (rh.hit.geomID == 0)
        hit.patch = int(rh.hit.primID);
    else
        hit.sphere = int(rh.hit.primID);
    hit.t = rh.ray.tfar;
    hit.u = rh.hit.u;
    hit.v = rh.hit.v;
    hit.geometricNormal = Vec3(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z);
    return hit;
}

}  // namespace penumbra
