#include "render/object_reference.h"

#include <algorithm>
#include <cmath>

#include "core/counters.h"
#include "core/log.h"
#include "core/parallel.h"
#include "core/progress.h"

namespace penumbra {
namespace {

const Counter g_referencePoints("reference.points", "points on objects whose radiosity the reference path traced");

constexpr int64_t kBatch = 1024;  // points per work item: the unit of seeding and of stopping

// Sums of one batch of points on one object.
struct Moments {
    Rgb sum = Rgb::Zero(), squares = Rgb::Zero();
    double totalSquares = 0;  // of the channel sum (whose sum is sum.sum())
    int64_t count = 0;
    void add(const Rgb& b) {
        sum += b;
        squares += b * b;
        totalSquares += b.sum() * b.sum();
        ++count;
    }
    void merge(const Moments& m) {
        sum += m.sum;
        squares += m.squares;
        totalSquares += m.totalSquares;
        count += m.count;
    }
    // Standard error of the mean of x from the sums of x and x^2 over `count` points.
    double stdError(double s, double s2) const {
        if (count < 2) return 0;
        const double mean = s / double(count);
        return std::sqrt(std::max(0.0, s2 / double(count) - mean * mean) / double(count - 1));
    }
    double relativeError() const {
        const double total = sum.sum();
        return total > 0 ? stdError(total, totalSquares) / (total / double(count)) : 0;
    }
};

// The patches of each object, with the cumulative share of the object's area up to each.
struct ObjectPatches {
    std::vector<int> patch;
    std::vector<double> cdf;
    double area = 0;
};

}  // namespace

Rgb pathRadiosityAt(const SceneTracer& tracer, int patch, Rng& rng, const PathSettings& path) {
    const PatchSet& patches = tracer.patches();
    const double u1 = rng.uniform(), u2 = rng.uniform();
    const Vec3 x = samplePatchPoint(patches, size_t(patch), u1, u2, rng.uniform());
    const Vec3& n = patches.normal[size_t(patch)];
    // The path tracer's own estimate of the radiance leaving x, seen from just in front of it: the
    // emission, and the reflected light by its next-event estimate and cosine bounce (MIS). The lift
    // is far above float precision at the patch and far below any gap between surfaces.
    const double lift = 1e-3 * patches.radius[size_t(patch)];
    return kPi * pathRadiance(tracer, x + lift * n, -n, rng, path);
}

std::vector<ObjectEstimate> pathObjectRadiosity(const SceneTracer& tracer, const ObjectReferenceSettings& settings) {
    const Scene& scene = tracer.scene();
    const PatchSet& patches = tracer.patches();
    const size_t objects = scene.objects.size();
    std::vector<ObjectPatches> of(objects);
    for (size_t i = 0; i < patches.size(); ++i) {
        ObjectPatches& o = of[size_t(patches.object[i])];
        o.area += patches.area[i];
        o.patch.push_back(int(i));
        o.cdf.push_back(o.area);
    }
    std::vector<ObjectEstimate> estimates(objects);
    std::vector<Moments> moments(objects);
    // Objects still sampled, and the batches each is to have after this round.
    std::vector<int64_t> planned(objects, 0);
    const int64_t minBatches = std::max<int64_t>(2, (settings.minSamples + kBatch - 1) / kBatch);
    const int64_t maxBatches = std::max(minBatches, (settings.maxSamples + kBatch - 1) / kBatch);
    for (size_t o = 0; o < objects; ++o) {
        estimates[o].area = of[o].area;
        const bool diffuse = scene.materialOf(scene.objects[o]).type == MaterialType::Diffuse;
        if (diffuse && of[o].area > 0 && of[o].area >= settings.minArea) planned[o] = minBatches;
    }
    for (int round = 1;; ++round) {
        // This round's work items: (object, batch) for every batch planned and not yet traced.
        std::vector<std::pair<size_t, int64_t>> items;
        for (size_t o = 0; o < objects; ++o)
            for (int64_t b = moments[o].count / kBatch; b < planned[o]; ++b) items.emplace_back(o, b);
        if (items.empty()) break;
        std::vector<Moments> results(items.size());
        Progress progress(cat("reference radiosity, round ", round), int64_t(items.size()));
        parallelFor(int64_t(items.size()), [&](int64_t k0, int64_t k1) {
            prepareTracingThread();
            for (int64_t k = k0; k < k1; ++k) {
                const auto [o, b] = items[size_t(k)];
                const ObjectPatches& op = of[o];
                Rng rng = pairRng(settings.seed, Stream::ObjectReference, o, uint64_t(b));
                Moments& r = results[size_t(k)];
                for (int64_t s = 0; s < kBatch; ++s) {
                    const double pick = rng.uniform() * op.area;
                    const size_t j =
                        std::min(size_t(std::upper_bound(op.cdf.begin(), op.cdf.end(), pick) - op.cdf.begin()),
                                 op.patch.size() - 1);
                    r.add(pathRadiosityAt(tracer, op.patch[j], rng, settings.path));
                }
                g_referencePoints.add(uint64_t(kBatch));
                progress.update();
            }
        });
        progress.done();
        // Merged in item order, so the sums do not depend on the threads; then each object's plan.
        for (size_t k = 0; k < items.size(); ++k) moments[items[k].first].merge(results[k]);
        for (size_t o = 0; o < objects; ++o) {
            if (planned[o] == 0 || moments[o].count < planned[o] * kBatch) continue;
            const double rel = moments[o].relativeError();
            if (rel <= settings.targetError || planned[o] >= maxBatches) continue;
            // The noise falls as 1/sqrt(points): plan for the target with a tenth to spare.
            const double need = double(planned[o]) * (rel / settings.targetError) * (rel / settings.targetError) * 1.1;
            planned[o] = std::min(maxBatches, std::max(planned[o] + 1, int64_t(std::ceil(need))));
        }
    }
    for (size_t o = 0; o < objects; ++o) {
        const Moments& m = moments[o];
        ObjectEstimate& e = estimates[o];
        e.samples = m.count;
        if (m.count == 0) continue;
        e.radiosity = m.sum / double(m.count);
        for (int c = 0; c < 3; ++c) e.stdError[c] = m.stdError(m.sum[c], m.squares[c]);
        e.relativeError = m.relativeError();
        if (e.relativeError > settings.targetError)
            logWarning("reference: ", scene.objects[o].name, " reached ", m.count, " points at ", 100 * e.relativeError,
                       "% standard error (target ", 100 * settings.targetError, "%)");
    }
    return estimates;
}

}  // namespace penumbra
