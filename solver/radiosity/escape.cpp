#include "solver/radiosity/escape.h"

#include "core/error.h"
#include "core/optics.h"
#include "core/parallel.h"
#include "core/rng.h"

namespace penumbra {

EscapeEstimate estimateEscapedPower(const SceneTracer& tracer, const std::vector<Rgb>& B, int raysPerPatch,
                                    uint64_t seed, int maxBounces) {
    const PatchSet& p = tracer.patches();
    PENUMBRA_CHECK_EQ(B.size(), p.size());
    std::vector<Rgb> mean(p.size(), Rgb::Zero()), variance(p.size(), Rgb::Zero());
    const int side = stratumSide(raysPerPatch);
    const int rays = side * side;
    parallelFor(
        int64_t(p.size()),
        [&](int64_t begin, int64_t end) {
            prepareTracingThread();
            for (int64_t ii = begin; ii < end; ++ii) {
                const size_t i = size_t(ii);
                if (!(B[i].maxCoeff() > 0)) continue;
                Rng rng = streamRng(seed, Stream::EscapeRays, i);
                Rgb sum = Rgb::Zero(), sum2 = Rgb::Zero();
                for (int r = 0; r < rays; ++r) {
                    const double u1 = ((r % side) + rng.uniform()) / side, u2 = ((r / side) + rng.uniform()) / side;
                    const Vec3 x = samplePatchPoint(p, i, u1, u2, rng.uniform());
                    const Vec3 d = cosineDirection(p.normal[i], rng);
                    const SpecularWalk w =
                        walkSpecular(tracer, tracer.trace(x + tracer.epsilon() * p.normal[i], d), d, rng, maxBounces);
                    if (w.end != WalkEnd::Escaped) continue;
                    sum += w.throughput;
                    sum2 += w.throughput * w.throughput;
                }
                mean[i] = sum / rays;
                variance[i] = (sum2 / rays - mean[i] * mean[i]).max(0.0) / std::max(1, rays - 1);
            }
        },
        16);
    EscapeEstimate e;
    Rgb var = Rgb::Zero();
    for (size_t i = 0; i < p.size(); ++i) {
        const Rgb power = p.area[i] * B[i];
        e.escaped += power * mean[i];
        var += power * power * variance[i];
        if (B[i].maxCoeff() > 0) e.rays += rays;
    }
    e.standardError = var.sqrt();
    return e;
}

}  // namespace penumbra
