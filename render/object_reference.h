// Each object's mean radiosity by path tracing: the independent reference a solve is measured
// against (issue 13's "within 1% of a converged reference"). Points are drawn uniformly over each
// diffuse object; at each, the radiosity B = E + rho * integral of L_i cos over the hemisphere is
// pi times the path tracer's radiance leaving the point (its next-event estimation and
// cosine-sampled bounce, weighted by MIS). The mean over the points is unbiased for the object's area mean, whatever
// the mesh, and its noise is measured: each object is sampled until its standard error (of the sum over the channels)
// falls below a target share of its mean, or a sample cap.
#pragma once

#include <cstdint>
#include <vector>

#include "render/path_tracer.h"

namespace penumbra {

struct ObjectReferenceSettings {
    double targetError = 0.002;      // relative standard error to stop at, per object
    int64_t minSamples = 16384;      // points on each object at least
    int64_t maxSamples = 1ll << 24;  // and at most
    double minArea = 0;              // m^2: smaller objects are left out (a large scene's rooms, not its props)
    uint64_t seed = 1;
    PathSettings path;
};

struct ObjectEstimate {
    Rgb radiosity = Rgb::Zero();  // mean radiosity (W/m^2, per channel)
    Rgb stdError = Rgb::Zero();   // its standard error, per channel
    double relativeError = 0;     // standard error of the channel sum over that sum
    int64_t samples = 0;          // 0: not estimated (mirror, glass, or no area)
    double area = 0;              // m^2, of the object's patches
};

// One estimate of the radiosity leaving the front of diffuse `patch` of the tracer's patches, at a
// uniform point on it.
Rgb pathRadiosityAt(const SceneTracer& tracer, int patch, Rng& rng, const PathSettings& path = {});

// One estimate per scene object, in scene order. Deterministic for a seed whatever the threads.
std::vector<ObjectEstimate> pathObjectRadiosity(const SceneTracer& tracer, const ObjectReferenceSettings& settings);

}  // namespace penumbra
