// The pixel loop every integrator shares: low-discrepancy samples over each pixel's square (the
// contract's one-pixel box filter) from sets that neighbouring pixels share, rows spread over the
// threads, every pixel's numbers fixed by the seed so the image does not depend on the thread
// count, edge pixels sampled again, and a progress bar.
#pragma once

#include <functional>

#include "core/math.h"
#include "core/rng.h"
#include "core/sampler.h"
#include "mesh/scene.h"
#include "render/image.h"

namespace penumbra {

// Radiance arriving at the camera along origin + t dir.
using RadianceFn = std::function<Rgb(const Vec3& origin, const Vec3& dir, Rng& rng)>;

// Renders with about `samplesPerPixel` samples (rounded up to a square number), jittered on a grid,
// from independent numbers: the path tracer's plain sampler, kept to measure the sets against.
Image renderPixels(const Camera& camera, int samplesPerPixel, uint64_t seed, const char* title,
                   const RadianceFn& radiance);

// Radiance arriving at the camera along origin + t dir, its decisions drawn from `sampler`.
using SampledRadianceFn = std::function<Rgb(const Vec3& origin, const Vec3& dir, PixelSampler& sampler)>;

// Renders with exactly `samplesPerPixel` samples (a power of two stratifies best) from PixelSamplers
// that neighbouring pixels share, tile by tile: each pixel's samples are an aligned run of the sets'
// indices, by its Morton rank, so that any aligned block of pixels draws a net too and neighbours'
// errors cancel (blue noise). Sample s of a pixel takes its point in the pixel from dimensions 0-1,
// and the radiance function the dimensions from 4 on. The same image whatever the thread count.
// `edges`: a pixel whose samples differ by more than their mean, and its eight neighbours (at one
// sample per pixel: a pixel whose 3 x 3 neighbourhood's values do), take four times their samples
// again, at least 64 beside a lamp's edge (a lamp is fifty times brighter than the ceiling around it).
// `batch`, if given, takes the samples of each band and pass instead of `radiance`, many at once (in
// row order, at most about 65,536 a call): for a view that finds what they see without rays
// (VisibilityBuffer).
struct CameraSample {
    int x;
    int64_t y;  // the pixel
    Vec2 at;    // the image position in it (pixels, continuous)
};
using BatchRadianceFn = std::function<void(const std::vector<CameraSample>& samples, std::vector<Rgb>& radiance)>;
Image renderPixelsSampled(const Camera& camera, int samplesPerPixel, uint64_t seed, const char* title,
                          const SampledRadianceFn& radiance, bool edges = false,
                          const BatchRadianceFn& batch = nullptr);

}  // namespace penumbra
