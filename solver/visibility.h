// Ray queries against the patch geometry: the only module that sees Embree. One scene per mesh,
// committed once and shared by everything that traces it (form factors, specular transport, vertex
// gather, photons, integrators): quads (triangles repeat their last corner), both faces occluding,
// and optionally exact spheres standing in for the patches of mirror and glass balls, whose facets
// would show in reflections and scatter caustics. Each query names the view it wants (RayView); each
// view is its own Embree scene. Embree errors become Error exceptions with context.
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

// What a query sees. Patches: every patch as meshed (the radiosity system's own geometry: form
// factors, the vertex gather, the radiosity view). Exact: the exact spheres in place of the patches
// they stand in for (light paths: specular transport, photons, the integrators).
enum class RayView : unsigned { Patches = 1, Exact = 2 };

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
    // With `spheres`, seen by the Exact view in place of the patches with replaced[i] != 0.
    RayScene(const PatchSet& patches, const std::vector<RaySphere>& spheres, const std::vector<char>& replaced);
    ~RayScene();
    RayScene(const RayScene&) = delete;
    RayScene& operator=(const RayScene&) = delete;

    // True if anything blocks the open segment from `from` to `to`, trimmed at both ends by
    // `trim` (a fraction of its length) so the endpoints' own patches do not count.
    bool occluded(const Vec3& from, const Vec3& to, double trim = 1e-5, RayView view = RayView::Patches) const;
    // The patch nearest `from` that blocks the open segment as `occluded` trims it, or -1 if none
    // does (-2: only an exact sphere): one nearest-hit ray, for callers that cache what blocked them.
    int occluder(const Vec3& from, const Vec3& to, double trim = 1e-5, RayView view = RayView::Patches) const;
    // Nearest hit along origin + t * dir, t in (tMin, tMax).
    Hit intersect(const Vec3& origin, const Vec3& dir, double tMin = 0, double tMax = 1e30,
                  RayView view = RayView::Patches) const;
    size_t patchCount() const;
    size_t sphereCount() const;
    // Whether the patch is a facet of an exact sphere (seen by the Patches view only).
    bool onExactSphere(size_t patch) const;
    // The exact spheres (the Exact view's), as given.
    const std::vector<RaySphere>& spheres() const;
    // The view in which patches a and b see each other: the exact spheres as they are (a ball's
    // shadow on the floor is the sphere's, not its facets', which lie inside it), unless a or b is
    // one of their facets, which the sphere itself would hide.
    RayView viewBetween(size_t a, size_t b) const;
    // The committed Embree scene of a view (an RTCScene), for the bench that measures Embree alone on
    // the very scene the solver traces; opaque here so that Embree's headers stay in this module.
    void* embreeScene(RayView view = RayView::Patches) const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

// Sets the flush-to-zero and denormals-are-zero flags Embree wants in every tracing thread.
void prepareTracingThread();

// Rays cast through any RayScene of this process so far (occlusion and nearest-hit queries alike,
// the counters rays.occlusion and rays.nearest): the bench's "rays cast".
uint64_t raysCast();

}  // namespace penumbra
