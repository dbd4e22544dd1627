// The unbiased reference: a path tracer over the same geometry, materials and camera as the
// final-gather view. Next-event estimation with multiple importance sampling (power heuristic)
// against cosine sampling on diffuse surfaces, exact specular bounces, Russian roulette.
#pragma once

#include "core/rng.h"
#include "core/sampler.h"
#include "render/film.h"
#include "solver/tracer.h"

namespace penumbra {

struct PathSettings {
    int rouletteDepth = 3;  // Russian roulette from this many bounces on
    // ... of the paths whose throughput (its largest channel) fell below this: they go on with
    // probability throughput / rouletteThroughput, every other path with 0.95. At 1 (until
    // 2026-12-06) a path in a white room went on with probability about 0.75 at each bounce; at 0.25
    // the Cornell box at 16 spp has 0.77x the error for 1.3x the rays, cornell-glass at 64 spp 0.80x
    // for 1.3x the time (docs/performance.md, "Russian roulette").
    double rouletteThroughput = 0.25;
    int maxDepth = 1000;  // a guard against endless paths only; roulette ends paths long before
    // Each pixel's decisions from a PixelSampler (renderPixelsSampled); false: independent numbers
    // per pixel (renderPixels), as before 2026-12-06.
    bool lowDiscrepancy = true;
};

// Radiance along a ray, its decisions drawn from `rng`: an Rng (independent numbers) or a
// PixelSampler (one dimension per decision, low-discrepancy over a pixel's samples).
template <typename Generator>
Rgb pathRadiance(const SceneTracer& tracer, const Vec3& origin, const Vec3& dir, Generator& rng,
                 const PathSettings& settings);

// With settings.lowDiscrepancy (the default), each pixel's samples from its own PixelSampler: the
// camera's point in the pixel and every decision of the path stratified over the pixel's samples.
Image renderPath(const SceneTracer& tracer, const Camera& camera, int samplesPerPixel, uint64_t seed,
                 const PathSettings& settings = {});

}  // namespace penumbra
