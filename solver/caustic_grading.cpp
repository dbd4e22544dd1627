#include "solver/caustic_grading.h"

#include <algorithm>

#include "core/log.h"
#include "core/optics.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "mesh/refine.h"
#include "solver/tracer.h"

namespace penumbra {
namespace {

// Light that reached a diffuse patch through mirrors or glass: where, and how much (the share of
// the emitted power, summed over channels).
struct Deposit {
    int patch;
    Vec3 point;
    double power;
};

std::vector<Deposit> traceCausticPhotons(const SceneTracer& tracer, const CausticGrading& settings) {
    constexpr int64_t kBlock = 4096;
    const int64_t blocks = (settings.photons + kBlock - 1) / kBlock;
    const int64_t total = blocks * kBlock;
    std::vector<std::vector<Deposit>> found(static_cast<size_t>(blocks));
    parallelFor(blocks, [&](int64_t begin, int64_t end) {
        prepareTracingThread();
        for (int64_t b = begin; b < end; ++b) {
            Rng rng = pairRng(settings.seed, Stream::CausticGrading, uint64_t(b), 0);
            for (int64_t k = 0; k < kBlock; ++k) {
                const EmitterSample e = tracer.sampleEmitter(rng);
                const Vec3 w = cosineDirection(e.normal, rng);
                const SurfaceHit hit = tracer.trace(e.point + tracer.epsilon() * e.normal, w);
                if (!hit.found || hit.material->type == MaterialType::Diffuse) continue;
                const SpecularWalk walk = walkSpecular(tracer, hit, w, rng, 16, 1e-3);
                if (walk.end != WalkEnd::Diffuse || walk.hit.patch < 0 || !walk.hit.frontFacing(walk.dir)) continue;
                found[size_t(b)].push_back({walk.hit.patch, walk.hit.point, walk.throughput.sum() / 3 / double(total)});
            }
        }
    });
    std::vector<Deposit> all;
    for (const auto& f : found) all.insert(all.end(), f.begin(), f.end());
    return all;
}

}  // namespace

size_t gradeCaustics(const Scene& scene, PatchSet& patches, std::shared_ptr<const RayScene>& rays,
                     const CausticGrading& settings) {
    if (settings.levels <= 0 || !scene.hasSpecular() || patches.size() == 0) return 0;
    if (!rays) rays = buildRayScene(scene, patches);
    std::vector<Deposit> deposits;
    {
        const SceneTracer tracer(scene, patches, rays);
        if (!tracer.hasEmitters()) return 0;
        deposits = traceCausticPhotons(tracer, settings);
    }
    double area = 0;
    for (double a : patches.area) area += a;
    // The mean irradiance, as a share of the emitted power per m^2: all of it spread over every surface.
    const double mean = 1 / area;
    size_t made = 0;
    for (int level = 0; level < settings.levels; ++level) {
        const size_t n = patches.size();
        std::vector<double> power(n, 0.0);
        std::vector<int> count(n, 0);
        for (const Deposit& d : deposits) power[size_t(d.patch)] += d.power, ++count[size_t(d.patch)];
        std::vector<char> split(n, 0);
        for (size_t i = 0; i < n; ++i)
            split[i] = count[i] >= settings.minPhotons && patches.area[i] >= 4 * settings.minArea &&
                       power[i] / patches.area[i] > settings.brighter * mean;
        const size_t asked = size_t(std::count(split.begin(), split.end(), 1));
        if (asked == 0) break;
        patches = splitPatches(patches, split);  // adds to `split` what the 2:1 rule needs
        // Each deposit to the child of its patch whose centre is nearest (children in place of
        // their parent, in order).
        std::vector<size_t> first(n + 1, 0);
        for (size_t i = 0; i < n; ++i) first[i + 1] = first[i] + (split[i] ? 4 : 1);
        for (Deposit& d : deposits) {
            const size_t i = size_t(d.patch);
            size_t best = first[i];
            for (size_t c = first[i] + 1; c < first[i + 1]; ++c)
                if ((patches.centroid[c] - d.point).squaredNorm() < (patches.centroid[best] - d.point).squaredNorm())
                    best = c;
            d.patch = int(best);
        }
        const size_t now = size_t(std::count(split.begin(), split.end(), 1));
        made += now;
        logDebug("caustic grading, level ", level + 1, ": ", asked, " patches lit by a caustic split (", now - asked,
                 " more for the 2:1 rule) -> ", patches.size(), " patches");
    }
    if (made > 0) rays = nullptr;
    return made;
}

}  // namespace penumbra
