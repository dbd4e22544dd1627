// The small sources' direct light at a point, as a view needs it at every pixel: each source
// polygon's unoccluded irradiance in closed form (Lambert's contour formula), times the share of a
// few stratified shadow rays to it that arrive. A point that sees all of every source, or none of
// it, gets the exact value without noise; only a penumbra is sampled, and unbiasedly so (jittered
// points, not grid centres). The solve splits its irradiance the same way (indirectCorners,
// vertex_radiosity.h), so the two parts add up to all the light once.
#pragma once

#include <array>
#include <vector>

#include "core/math.h"
#include "core/rng.h"
#include "core/sampler.h"
#include "mesh/patches.h"
#include "mesh/scene.h"
#include "solver/tracer.h"

namespace penumbra {

class DirectLight {
public:
    // The scene's small sources (smallSources, system.h): a quad or triangle object as its one
    // polygon, any other emitting object patch by patch. None when the emitters are not small.
    DirectLight(const Scene& scene, const PatchSet& patches);

    // Proves, patch by patch, which sources no surface hides from any of the patch's points
    // (solver/shafts.h): irradiance then casts no shadow rays to them from points of that patch.
    // The image is the same, ray for ray where the rays would all have arrived. Returns the share
    // of (patch, source) pairs proved clear among those facing each other.
    double proveClearShafts(const SceneTracer& tracer);

    bool empty() const { return sources_.empty(); }
    size_t sources() const { return sources_.size(); }
    // Irradiance at x (unit normal n, x already off its surface) from the sources, W/m^2, with
    // `rays` shadow rays spread over the sources in proportion to their unoccluded light. Past
    // kMostPolygons sources, by emitter sampling instead (tracer.sampleLight: every emitter, which
    // are then all small sources).
    static constexpr size_t kMostPolygons = 64;
    // From an Rng, each ray's point jittered in its stratum; from a PixelSampler, one shift of the
    // whole grid (two dimensions), which the sampler stratifies over the pixel's samples and its
    // neighbours'.
    // `patch`: the patch x lies on (-1: unknown), whose proved-clear sources take no shadow rays.
    template <typename Generator>
    Rgb irradiance(const SceneTracer& tracer, const Vec3& x, const Vec3& n, int rays, Generator& g,
                   int patch = -1) const;

private:
    struct Source {
        std::array<Vec3, 4> corner;
        int count = 4;
        Vec3 normal, centre;
        Rgb exitance;      // E = pi L_e, W/m^2
        double split = 1;  // share of the area in the triangle (0, 1, 2); the rest in (0, 2, 3)
        int object = -1;   // a quad or triangle object taken whole; -1: one patch of an object
    };
    Vec3 pointOn(const Source& s, double u1, double u2) const;
    std::vector<Source> sources_;
    std::vector<uint64_t> clear_;  // per patch: bit k set where source k is proved in full view
};

}  // namespace penumbra
