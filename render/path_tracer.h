// The unbiased reference: a path tracer over the same geometry, materials and camera as the
// final-gather view. Next-event estimation with multiple importance sampling (power heuristic)
// against cosine sampling on diffuse surfaces, exact specular bounces, Russian roulette.
#pragma once

#include "core/rng.h"
#include "render/film.h"
#include "solver/tracer.h"

namespace penumbra {

struct PathSettings {
    int rouletteDepth = 3;  // Russian roulette from this many bounces on
    int maxDepth = 1000;    // a guard against endless paths only; roulette ends paths long before
};

Rgb pathRadiance(const SceneTracer& tracer, const Vec3& origin, const Vec3& dir, Rng& rng,
                 const PathSettings& settings);

Image renderPath(const SceneTracer& tracer, const Camera& camera, int samplesPerPixel, uint64_t seed,
                 const PathSettings& settings = {});

}  // namespace penumbra
