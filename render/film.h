// The pixel loop every integrator shares: stratified samples over each pixel's square (the
// contract's one-pixel box filter), rows spread over the threads, one random stream per pixel so
// the image does not depend on the thread count, and a progress bar.
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

// Renders with about `samplesPerPixel` samples (rounded up to a square number for stratification).
// `edges`: a pixel whose samples differ by more than their mean (a lamp's edge: the lamp is fifty
// times brighter than the ceiling around it), and its eight neighbours, are sampled again on a grid
// twice as fine (at least 12 x 12 beside a lamp's edge), and take the mean of all their samples.
Image renderPixels(const Camera& camera, int samplesPerPixel, uint64_t seed, const char* title,
                   const RadianceFn& radiance, bool edges = false);

// Radiance arriving at the camera along origin + t dir, its decisions drawn from `sampler`.
using SampledRadianceFn = std::function<Rgb(const Vec3& origin, const Vec3& dir, PixelSampler& sampler)>;

// Renders with exactly `samplesPerPixel` samples (a power of two stratifies best) from PixelSamplers
// that neighbouring pixels share, tile by tile: each pixel's samples are an aligned run of the sets'
// indices, by its Morton rank, so that any aligned block of pixels draws a net too and neighbours'
// errors cancel (blue noise). Sample s of a pixel takes its point in the pixel from dimensions 0-1,
// and the radiance function the dimensions from 4 on. The same image whatever the thread count.
// `edges` as for renderPixels: edge pixels take four times their samples again (at least 64
// beside a lamp's edge).
Image renderPixelsSampled(const Camera& camera, int samplesPerPixel, uint64_t seed, const char* title,
                          const SampledRadianceFn& radiance, bool edges = false);

}  // namespace penumbra
