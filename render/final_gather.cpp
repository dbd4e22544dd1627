#include "render/final_gather.h"

#include <algorithm>
#include <cmath>
#include <memory>

#include "core/counters.h"
#include "core/log.h"
#include "core/optics.h"
#include "core/timer.h"
#include "render/radiosity_view.h"
#include "solver/radiosity/form_factors.h"

namespace penumbra {
namespace {
const Counter g_gatherRays("render.gather_rays", "final gather: cosine rays that read the solved radiosity");
}  // namespace

FinalGather::FinalGather(const SceneTracer& tracer, const std::vector<std::array<Rgb, 4>>& cornerRadiosity,
                         const PhotonMap* caustics, const GatherSettings& settings, const CornerValues* indirect)
    : tracer_(tracer),
      corners_(cornerRadiosity),
      caustics_(caustics),
      settings_(settings),
      direct_(tracer.scene(), tracer.patches()) {
    if (settings.clearShafts && !direct_.empty()) {
        const Timer timer;
        const double share = direct_.proveClearShafts(tracer);
        logDebug("final gather: ", 100 * share, "% of the patch-source pairs facing each other proved clear in ",
                 timer.seconds(), " s");
    }
    if (settings.solvedIndirect && indirect && indirect->size() == tracer.patches().size() && !direct_.empty())
        indirect_ = indirect;
}

Rgb FinalGather::radiosityAt(const SurfaceHit& y) const {
    return interpolateAt(tracer_.patches(), size_t(y.patch), y.u, y.v, corners_[size_t(y.patch)]);
}

template <typename Generator>
Rgb FinalGather::trace(const Vec3& origin, const Vec3& dir, Generator& rng, int depth, const Rgb& carried) const {
    const SurfaceHit hit = tracer_.trace(origin, dir);
    if (!hit.found) return Rgb::Zero();
    const Material& m = *hit.material;
    if (m.type == MaterialType::Diffuse) {
        if (!hit.frontFacing(dir)) return Rgb::Zero();
        return hit.emission + reflected(hit, rng, 0);
    }
    if (depth >= settings_.maxSpecularDepth) return Rgb::Zero();
    SpecularBranch branches[2];
    const int count = specularBranches(hit, dir, branches);
    Rgb L = Rgb::Zero();
    for (int b = 0; b < count; ++b) {
        const Rgb next = carried * branches[b].weight;
        if (next.maxCoeff() >= settings_.minThroughput)
            L +=
                branches[b].weight * trace(tracer_.offset(hit, branches[b].dir), branches[b].dir, rng, depth + 1, next);
    }
    return L;
}

template <typename Generator>
Rgb FinalGather::reflected(const SurfaceHit& x, Generator& rng, int level) const {
    const Rgb& rho = x.reflectance;
    if ((rho <= 0).all()) return Rgb::Zero();
    if (level == 0 && indirect_ && x.patch >= 0) {
        // The solve's indirect light where the camera looks, the direct light of the small sources
        // at the point itself, and the caustics: no gather rays.
        const Vec3 from = x.point + tracer_.epsilon() * x.normal;
        Rgb E = direct_.irradiance(tracer_, from, x.normal, settings_.directSamples, rng, x.patch);
        if (caustics_) E += caustics_->irradiance(x.point, x.normal);
        E += interpolateAt(tracer_.patches(), size_t(x.patch), x.u, x.v, (*indirect_)[size_t(x.patch)]).max(0.0);
        return rho * kInvPi * E;
    }
    const int lightSamples = level == 0 ? settings_.directSamples : 1;
    const int gatherRays = level == 0 ? settings_.gatherRays : 1;
    Rgb E = directIrradiance(x, rng, lightSamples, gatherRays);
    if (caustics_) E += caustics_->irradiance(x.point, x.normal);
    E += indirectIrradiance(x, rng, gatherRays, lightSamples, level);
    return rho * kInvPi * E;
}

namespace {
// Power heuristic for a sample of strategy a (n_a samples, pdf p_a) against strategy b.
double misWeight(int na, double pa, int nb, double pb) {
    const double a = na * pa, b = nb * pb;
    return a * a / (a * a + b * b);
}
}  // namespace

template <typename Generator>
Rgb FinalGather::directIrradiance(const SurfaceHit& x, Generator& rng, int samples, int gatherRays) const {
    if (!tracer_.hasEmitters()) return Rgb::Zero();
    Rgb sum = Rgb::Zero();
    for (int s = 0; s < samples; ++s) {
        const LightSample l = tracer_.sampleLight(x.point, x.normal, rng);
        if (!l.found()) continue;
        // Emitters are also found by the gather rays: the two estimates are combined by multiple
        // importance sampling (power heuristic), which tames the 1/d^2 of points near an emitter.
        const double weight = misWeight(samples, l.pdf, gatherRays, l.cosine * kInvPi);
        sum += l.radiance * (l.cosine / l.pdf * weight);
    }
    return sum / samples;
}

template <typename Generator>
Rgb FinalGather::indirectIrradiance(const SurfaceHit& x, Generator& rng, int rays, int lightSamples, int level) const {
    const Vec3 from = x.point + tracer_.epsilon() * x.normal;
    g_gatherRays.add(uint64_t(rays));
    Rgb sum = Rgb::Zero();
    for (int r = 0; r < rays; ++r) {
        const Vec3 d = cosineDirection(x.normal, rng);
        // Through mirrors and glass, one branch at a time in proportion to its share.
        const SpecularWalk w =
            walkSpecular(tracer_, tracer_.trace(from, d), d, rng, settings_.maxSpecularDepth, settings_.minThroughput);
        if (w.end != WalkEnd::Diffuse || !w.hit.frontFacing(w.dir)) continue;
        const SurfaceHit& y = w.hit;
        if (w.bounces == 0 && y.material->emits()) {
            // Direct light found by a gather ray: its share of the MIS combination.
            const double cosX = x.normal.dot(d), cosL = -y.normal.dot(d);
            const double lightPdf = tracer_.emitterPdfArea(y.patch) * y.t * y.t / cosL;
            sum += y.emission * misWeight(rays, cosX * kInvPi, lightSamples, lightPdf);
        }
        if (level == 0 && w.length < settings_.closeFactor * tracer_.patches().radius[size_t(y.patch)]) {
            // Too close for patch-level radiosity: shade the landing point itself.
            sum += w.throughput * reflected(y, rng, level + 1);
        } else {
            const Rgb B = radiosityAt(y) - kPi * y.emission;
            sum += w.throughput * B.max(0.0) * kInvPi;
        }
    }
    // Cosine sampling: E = pi * mean(L_in).
    return kPi * sum / rays;
}

template Rgb FinalGather::reflected(const SurfaceHit&, Rng&, int) const;
template Rgb FinalGather::reflected(const SurfaceHit&, PixelSampler&, int) const;
template Rgb FinalGather::trace(const Vec3&, const Vec3&, Rng&, int, const Rgb&) const;
template Rgb FinalGather::trace(const Vec3&, const Vec3&, PixelSampler&, int, const Rgb&) const;

GatherEffort gatherEffortFor(int samplesPerPixel) {
    constexpr int kFullSamples = 16;
    const double e = std::sqrt(double(std::clamp(samplesPerPixel, 1, kFullSamples)) / kFullSamples);
    GatherEffort effort;
    effort.ffNoise = FormFactorSettings{}.objectNoise / e;
    effort.photons = e;
    effort.specularPaths = std::sqrt(e);
    effort.patches = std::sqrt(std::sqrt(e));
    return effort;
}

Image renderFinalGather(const FinalGather& gather, const Camera& camera, int samplesPerPixel, uint64_t seed) {
    return renderPixelsSampled(
        camera, samplesPerPixel, seed, "final gather",
        [&](const Vec3& o, const Vec3& d, PixelSampler& sampler) { return gather.radiance(o, d, sampler); }, true);
}

CornerValues meanPreservingCorners(const PatchSet& patches, CornerValues corners, const std::vector<Rgb>& means) {
    for (size_t i = 0; i < corners.size() && i < means.size(); ++i) {
        const int n = patches.cornerCount[i];
        Rgb mean = Rgb::Zero();
        for (int k = 0; k < n; ++k) mean += corners[i][size_t(k)];
        const Rgb shift = means[i] - mean / double(n);
        for (Rgb& c : corners[i]) c += shift;
    }
    return corners;
}

SolvedScene::SolvedScene(const Scene& scene, const PatchSet& patches, CornerValues cornerRadiosity,
                         const GatherSettings& settings, PhotonSettings photons, uint64_t seed,
                         std::shared_ptr<const RayScene> rays, const std::vector<Rgb>* means, CornerValues indirect)
    : corners_(means ? meanPreservingCorners(patches, std::move(cornerRadiosity), *means) : std::move(cornerRadiosity)),
      indirect_(std::move(indirect)),
      tracer_(std::make_unique<SceneTracer>(scene, patches, std::move(rays))) {
    if (tracer_->hasSpecular()) {
        photons.seed = seed;
        caustics_ = std::make_unique<PhotonMap>(*tracer_, photons);
    } else {
        logInfo("no mirrors or glass in the scene: no photon pass, no specular paths");
    }
    gather_ = std::make_unique<FinalGather>(*tracer_, corners_, caustics_.get(), settings, &indirect_);
}

Image renderSolvedScene(const Scene& scene, const PatchSet& patches, const std::vector<Rgb>& radiosity,
                        const Camera& camera, int samplesPerPixel, uint64_t seed, const GatherSettings& settings,
                        PhotonSettings photons) {
    return SolvedScene(scene, patches, radiosity, settings, photons, seed).render(camera, samplesPerPixel, seed);
}

}  // namespace penumbra
