// Ray queries against the patch geometry: the only module that sees Embree. One scene of quads
// (triangles repeat their last corner), committed once; primitive id == patch index. Both faces of
// every patch occlude. Optionally, exact spheres (for mirrors and glass, whose facets would show)
// replace the patches of their objects. Embree errors become Error exceptions with context.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "core/math.h"
#include "mesh/patches.h"

namespace penumbra {

// An exact sphere in the ray scene, in metres.
struct RaySphere {
    Vec3 center;
    double radius = 0;
};

struct Hit {
    int patch = -1;   // the patch hit, or -1
    int sphere = -1;  // the exact sphere hit (index into the constructor's list), or -1
    bool found() const { return patch >= 0 || sphere >= 0; }
    double t = 0;
    double u = 0, v = 0;   // Embree's primitive coordinates (quad parametrisation)
    Vec3 geometricNormal;  // unnormalised, as Embree reports it
};

class RayScene {
public:
    explicit RayScene(const PatchSet& patches);
    // Patches with skipPatch[i] != 0 are left out (they never hit); `spheres` are added.
    RayScene(const PatchSet& patches, const std::vector<RaySphere>& spheres, const std::vector<char>& skipPatch);
    ~RayScene();
    RayScene(const RayScene&) = delete;
    RayScene& operator=(const RayScene&) = delete;

    // True if anything blocks the open segment from `from` to `to`, trimmed at both ends by
    // `trim` (a fraction of its length) so the endpoints' own patches do not count.
    bool occluded(const Vec3& from, const Vec3& to, double trim = 1e-5) const;
    // Nearest hit along origin + t * dir, t in (tMin, tMax).
    Hit intersect(const Vec3& origin, const Vec3& dir, double tMin = 0, double tMax = 1e30) const;
    // The committed Embree scene (an RTCScene), for the bench that measures Embree alone on the very
    // scene the solver traces; opaque here so that Embree's headers stay in this module.
    void* embreeScene() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

// Sets the flush-to-zero and denormals-are-zero flags Embree wants in every tracing thread.
void prepareTracingThread();

// Rays cast through any RayScene of this process so far (occlusion and nearest-hit queries alike):
// the bench's "rays cast" counter. Counted per thread, without contention between threads.
uint64_t raysCast();

}  // namespace penumbra
