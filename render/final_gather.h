// The final-gather view of a solved scene: the picture a user looks at. At every diffuse point the
// camera sees (through any chain of mirrors and glass, split Whitted-style), the reflected radiance
// is rho / pi times the sum of three irradiances that never count a light path twice:
//   direct    light paths E -> x, by area sampling of the emitters with shadow rays, combined with
//             the gather rays that hit an emitter by multiple importance sampling;
//   caustic   paths E -> (mirror|glass)+ -> x, from the photon map;
//   indirect  paths that last left a diffuse surface y, by cosine gather rays that read y's solved
//             radiosity minus its emission (through mirrors and glass, if they meet any).
// Gather rays that land within a few patch radii of their origin, where patch-level radiosity is
// too coarse (corners, contact shadows), shade their landing point one bounce deeper instead.
#pragma once

#include <array>
#include <memory>
#include <vector>

#include "core/rng.h"
#include "render/direct_light.h"
#include "render/film.h"
#include "render/photon_map.h"
#include "solver/tracer.h"

namespace penumbra {

struct GatherSettings {
    int directSamples = 4;  // emitter samples per shading point and camera sample
    // No shadow rays from a patch to a small source that no surface can hide from it (the shaft
    // between them proved clear, solver/shafts.h): the same image with fewer rays.
    bool clearShafts = true;
    int gatherRays = 16;          // gather rays per shading point and camera sample
    int maxSpecularDepth = 16;    // mirror and glass bounces before a path stops
    double minThroughput = 1e-3;  // specular branches carrying less are dropped
    double closeFactor = 8;       // gather hits nearer than this many patch radii are shaded deeper
    // Read the solve's indirect irradiance (indirectCorners) at the points the camera sees, with the
    // small sources' direct light at each (DirectLight, `directSamples` shadow rays), instead of
    // gathering it with rays; where the solve has none (the hierarchy, no small sources), gather.
    bool solvedIndirect = true;
};

class FinalGather {
public:
    // `cornerRadiosity`: the solved radiosity B per patch corner (see interpolateCorners);
    // `caustics` may be null when the scene has no mirrors or glass.
    // `indirect`: the solve's indirect irradiance per patch corner (indirectCorners), or null.
    FinalGather(const SceneTracer& tracer, const std::vector<std::array<Rgb, 4>>& cornerRadiosity,
                const PhotonMap* caustics, const GatherSettings& settings, const CornerValues* indirect = nullptr);

    // Radiance arriving along a camera ray, its numbers from `g` (an Rng, or the pixel's PixelSampler).
    template <typename Generator>
    Rgb radiance(const Vec3& origin, const Vec3& dir, Generator& g) const {
        return trace(origin, dir, g, 0, Rgb::Ones());
    }

    // Light reflected by the diffuse front face at `x` (emission excluded), W sr^-1 m^-2; `level`
    // 0 for points the camera sees, 1 for the close landings of their gather rays.
    template <typename Generator>
    Rgb reflected(const SurfaceHit& x, Generator& g, int level) const;
    // The solved radiosity at a diffuse hit, interpolated between the patch corners, W/m^2.
    Rgb radiosityAt(const SurfaceHit& y) const;

private:
    // `carried`: what the camera's ray carries here (mirrors' and glass's weights so far).
    template <typename Generator>
    Rgb trace(const Vec3& origin, const Vec3& dir, Generator& g, int depth, const Rgb& carried) const;
    // Both estimate direct light too, combined by multiple importance sampling: each needs the
    // other's sample count.
    template <typename Generator>
    Rgb directIrradiance(const SurfaceHit& x, Generator& g, int samples, int gatherRays) const;
    template <typename Generator>
    Rgb indirectIrradiance(const SurfaceHit& x, Generator& g, int rays, int lightSamples, int level) const;

    const SceneTracer& tracer_;
    const std::vector<std::array<Rgb, 4>>& corners_;
    const PhotonMap* caustics_;
    GatherSettings settings_;
    const CornerValues* indirect_ = nullptr;  // null: gather the indirect light
    DirectLight direct_;
};

Image renderFinalGather(const FinalGather& gather, const Camera& camera, int samplesPerPixel, uint64_t seed);

// What a solve and its photon map made for final-gathered images of `samplesPerPixel` need: the
// defaults from 16 samples up; below, where the image's own noise hides more of theirs, an effort
// e = sqrt(samples / 16) (1/4 at 1 sample, 1/2 at 4) sets the form factors' noise target to the
// default over e (2% at 1 sample), the photons to e times the default, the solve's specular paths to
// sqrt(e) times and the patches to e^(1/4) times it (0.71 at 1 sample): each term by how much of the
// image's error it makes. Measured at 1 spp, 256x256, seeds 1-2 (docs/performance.md): the Cornell
// box 0.82-0.85% in 0.27 s with 3,000 patches, 0.92% in 0.20 s with 2,000, 1.00% at 1,500; cornell-
// glass 0.87-0.94% in 0.51-0.56 s with 3,000 patches and 1 M photons, 1.14-1.18% in 0.31 s with 2,000,
// 250,000 and 48 specular paths.
struct GatherEffort {
    double ffNoise = 0;        // the form factors' noise target (--ff-noise)
    double photons = 1;        // times the default photons (--photons)
    double specularPaths = 1;  // times the default specular paths a patch (--specular-rays)
    double patches = 1;        // times the default patch count (--patches)
};
GatherEffort gatherEffortFor(int samplesPerPixel);

// The corner values shifted, patch by patch, so that their mean (the mean of the interpolation over
// the patch) is the patch's radiosity `means`. What a gather ray reads where it lands: the displayed
// corners follow the light across the patch, but their mean is not the solve's (the direct light of
// small sources is taken at the vertices, the patches around a vertex averaged), and a gather ray
// from afar lands anywhere on the patch. Read unshifted, the building's rooms came out 1-1.5% dark
// against the path tracer (a library 0.988, a meeting room 0.991; shifted 1.001 and 1.001).
CornerValues meanPreservingCorners(const PatchSet& patches, CornerValues corners, const std::vector<Rgb>& means);

// What the final gather of a solved scene needs, built once for any number of views: the corner
// radiosity, the ray scene, and the photon pass if (and only if) the scene has mirrors or glass.
// `radiosity` is B per patch of `patches`; both must outlive this object.
class SolvedScene {
public:
    // `rays`: the mesh's ray scene (buildRayScene), built here if null. With `means` (the displayed
    // radiosity per patch), the gather reads meanPreservingCorners.
    SolvedScene(const Scene& scene, const PatchSet& patches, CornerValues cornerRadiosity,
                const GatherSettings& settings, PhotonSettings photons, uint64_t seed,
                std::shared_ptr<const RayScene> rays = nullptr, const std::vector<Rgb>* means = nullptr,
                CornerValues indirect = {});
    // With corner values interpolated from B per patch (interpolateCorners).
    SolvedScene(const Scene& scene, const PatchSet& patches, const std::vector<Rgb>& radiosity,
                const GatherSettings& settings, PhotonSettings photons, uint64_t seed)
        : SolvedScene(scene, patches, interpolateCorners(patches, radiosity), settings, photons, seed, nullptr,
                      &radiosity) {}
    Image render(const Camera& camera, int samplesPerPixel, uint64_t seed) const {
        return renderFinalGather(*gather_, camera, samplesPerPixel, seed);
    }
    const FinalGather& gather() const { return *gather_; }

private:
    CornerValues corners_, indirect_;
    std::unique_ptr<SceneTracer> tracer_;
    std::unique_ptr<PhotonMap> caustics_;
    std::unique_ptr<FinalGather> gather_;
};

// One final-gather render of a solved scene (a SolvedScene for a single view).
Image renderSolvedScene(const Scene& scene, const PatchSet& patches, const std::vector<Rgb>& radiosity,
                        const Camera& camera, int samplesPerPixel, uint64_t seed, const GatherSettings& gather,
                        PhotonSettings photons);

}  // namespace penumbra
