// Named regions of a view, for comparing two renders of it region by region (tests, `penumbra
// compare --scene`, the bench): each object the camera sees directly, objects grouped by their common
// name stem ("ceiling_front" and "ceiling_back" make "ceiling", "short_block_1" .. "_top" make
// "short_block"), every object whose name holds "block" as "blocks", and regions the caller adds (the
// caustic). A pixel belongs to an object's region when the centres of it and of its eight neighbours
// see that object first, so that the edges, where a 5x5 blur mixes two surfaces, stay out.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "mesh/scene.h"
#include "render/image.h"
#include "render/photon_map.h"
#include "solver/tracer.h"

namespace penumbra {

struct ImageRegions {
    int width = 0, height = 0;
    std::vector<SurfaceHit> hits;          // what each pixel's centre sees first
    std::vector<std::string> names;        // one per region
    std::vector<std::vector<char>> masks;  // width x height, row-major, per region

    void add(const std::string& name, std::vector<char> mask);
    // The region's mask, or null when there is none of that name.
    const std::vector<char>* find(const std::string& name) const;
};

// The object regions (and groups) of `camera`'s view of the tracer's scene.
ImageRegions objectRegions(const SceneTracer& tracer, const Camera& camera);

// The caustic: pixels whose centre sees a diffuse, non-emitting front face (directly, not through
// glass) where the photon map's caustic irradiance is at least `share` of both the direct irradiance
// from the emitters there and its mean over the view (estimated with `lightSamples` emitter samples
// per pixel), grown by `grow` pixels over the same surface. All zero when there is none.
std::vector<char> causticMask(const SceneTracer& tracer, const PhotonMap& caustics, const ImageRegions& regions,
                              double share = 1.0, int grow = 3, int lightSamples = 64);

struct RegionError {
    std::string name;
    int pixels = 0;
    Rgb mean = Rgb::Zero(), referenceMean = Rgb::Zero();  // mean radiance over the region
    double ratio = 0;     // sum of the image over the region's pixels and channels / the reference's
    double pooledL1 = 0;  // after the 5x5 blur, within the region
};

// Every region of `regions`, measured on `image` against `reference` (same size as the regions).
std::vector<RegionError> compareRegions(const Image& image, const Image& reference, const ImageRegions& regions,
                                        int blurRadius = 2);

}  // namespace penumbra
