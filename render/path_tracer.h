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
    // Light paths (renderPath): the caustics a camera ray meets first (eye, a diffuse surface, then
    // one or more mirror or glass bounces to a lamp) come from caustic photons traced from the lamps
    // and joined to the eye, this many per camera sample; the camera's paths leave those out. A
    // camera path finds them only when its bounce hits the lamp's image in a mirror or through glass.
    // 0: the camera's paths alone, as before 2026-12-07.
    double lightPathsPerSample = 0.25;
    // (renderPath sets it) pathRadiance leaves out the paths eye-diffuse-specular^k-lamp with
    // 1 <= k <= this, which the light paths carry; 0: none.
    int causticsByLight = 0;
};

// Radiance along a ray, its decisions drawn from `rng`: an Rng (independent numbers) or a
// PixelSampler (one dimension per decision, low-discrepancy over a pixel's samples).
template <typename Generator>
Rgb pathRadiance(const SceneTracer& tracer, const Vec3& origin, const Vec3& dir, Generator& rng,
                 const PathSettings& settings);

// With settings.lowDiscrepancy (the default), each pixel's samples from its own PixelSampler: the
// camera's point in the pixel and every decision of the path stratified over the pixel's samples.
// With settings.lightPathsPerSample > 0 and mirrors or glass in the scene, the light paths add the
// caustics seen directly (lightPathsToEye).
Image renderPath(const SceneTracer& tracer, const Camera& camera, int samplesPerPixel, uint64_t seed,
                 const PathSettings& settings = {});

// The light paths' share of an image: `paths` caustic photons traced from the lamps (Stream::LightPaths,
// `seed`; at most `maxBounces` specular bounces), each joined to the eye from where it landed and
// added to its pixel as the mean radiance over the pixel's square: power x rho / pi x cos_surface /
// (distance^2 x cos_axis^3 x the pixel's area at unit distance). The same image whatever the thread
// count (the additions in the photons' order).
Image lightPathsToEye(const SceneTracer& tracer, const Camera& camera, int64_t paths, uint64_t seed, int maxBounces);

}  // namespace penumbra
