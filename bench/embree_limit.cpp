// Embree alone on the patches of a scene: the yardstick that the form-factor and final-gather stages
// are measured against. The scene is the solver's own RayScene; the rays are made before the clock
// starts and traced by Embree's calls directly, so only Embree is timed.
#include <embree3/rtcore.h>
#include <pmmintrin.h>
#include <xmmintrin.h>

#include <algorithm>
#include <vector>

#include "bench/limits.h"
#include "core/error.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "core/timer.h"
#include "solver/tracer.h"
#include "solver/visibility.h"

namespace penumbra::bench {
namespace {

struct Segment {
    float org[3], dir[3];
};

// A point uniform over the scene's surface: a patch by area, then a point on it.
struct SurfaceSampler {
    const PatchSet& patches;
    std::vector<double> cdf;
    explicit SurfaceSampler(const PatchSet& p) : patches(p), cdf(p.size()) {
        double sum = 0;
        for (size_t i = 0; i < p.size(); ++i) cdf[i] = sum += p.area[i];
        for (double& c : cdf) c /= sum;
    }
    size_t patch(Rng& rng) const {
        const auto it = std::lower_bound(cdf.begin(), cdf.end(), rng.uniform());
        return std::min(size_t(it - cdf.begin()), cdf.size() - 1);
    }
    Vec3 point(size_t i, Rng& rng) const {
        return samplePatchPoint(patches, i, rng.uniform(), rng.uniform(), rng.uniform());
    }
};

// Rays per second of `trace(begin, end)` over `count` rays split across the threads: the best of
// three passes (the machine is shared, and the first pass warms the caches).
template <typename Trace>
double raysPerSecond(size_t count, const Trace& trace) {
    double best = 0;
    for (int pass = 0; pass < 3; ++pass) {
        Timer timer;
        parallelFor(
            int64_t(count / 8),
            [&](int64_t b, int64_t e) {
                _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
                _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
                trace(size_t(b) * 8, size_t(e) * 8);
            },
            256);
        best = std::max(best, double(count) / timer.seconds());
    }
    return best;
}

}  // namespace

EmbreeLimit measureEmbreeLimit(const PatchSet& patches, uint64_t rays, uint64_t seed) {
    EmbreeLimit out;
    out.threads = threadCount();
    if (patches.size() == 0) return out;
    const size_t count = size_t(std::max<uint64_t>(8, rays / 8 * 8));
    out.rays = count;
    // The solver's own ray scene (same build flags and quality); only the queries below are Embree's alone.
    const RayScene rayScene(patches);
    const auto scene = static_cast<RTCScene>(rayScene.embreeScene());
    const SurfaceSampler sampler(patches);

    // Segments between random points of two different patches, trimmed at both ends as the form
    // factors trim theirs; and cosine rays leaving random points of the front faces.
    std::vector<Segment> segments(count), gathers(count);
    parallelFor(
        int64_t(count),
        [&](int64_t b, int64_t e) {
            for (int64_t k = b; k < e; ++k) {
                Rng rng(mixSeed(seed, uint64_t(k), 17));
                const size_t i = sampler.patch(rng);
                size_t j = sampler.patch(rng);
                if (j == i) j = (j + 1) % patches.size();
                const Vec3 a = sampler.point(i, rng) + 1e-4 * patches.radius[i] * patches.normal[i];
                const Vec3 c = sampler.point(j, rng) + 1e-4 * patches.radius[j] * patches.normal[j];
                Segment& s = segments[size_t(k)];
                for (int d = 0; d < 3; ++d) s.org[d] = float(a[d]), s.dir[d] = float(c[d] - a[d]);
                // A cosine-distributed direction about the normal (Malley's method).
                Vec3 t, bt;
                orthonormalBasis(patches.normal[i], t, bt);
                const double r = std::sqrt(rng.uniform()), phi = 2 * kPi * rng.uniform();
                const Vec3 w = r * std::cos(phi) * t + r * std::sin(phi) * bt +
                               std::sqrt(std::max(0.0, 1 - r * r)) * patches.normal[i];
                Segment& g = gathers[size_t(k)];
                for (int d = 0; d < 3; ++d) g.org[d] = float(a[d]), g.dir[d] = float(w[d]);
            }
        },
        1024);

    std::vector<uint64_t> blocked(count, 0);  // keeps the results alive, so no query is optimised away
    out.occluded1 = raysPerSecond(count, [&](size_t b, size_t e) {
        RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        for (size_t k = b; k < e; ++k) {
            const Segment& s = segments[k];
            RTCRay ray{s.org[0], s.org[1], s.org[2],  1e-5f,       s.dir[0], s.dir[1],
                       s.dir[2], 0.0f,     1 - 1e-5f, 0xFFFFFFFFu, 0,        0};
            rtcOccluded1(scene, &context, &ray);
            blocked[k] = ray.tfar < 0;
        }
    });
    out.occluded8 = raysPerSecond(count, [&](size_t b, size_t e) {
        RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        alignas(32) int valid[8];
        std::fill(valid, valid + 8, -1);
        for (size_t k = b; k < e; k += 8) {
            alignas(32) RTCRay8 ray;
            for (int l = 0; l < 8; ++l) {
                const Segment& s = segments[k + size_t(l)];
                ray.org_x[l] = s.org[0], ray.org_y[l] = s.org[1], ray.org_z[l] = s.org[2];
                ray.dir_x[l] = s.dir[0], ray.dir_y[l] = s.dir[1], ray.dir_z[l] = s.dir[2];
                ray.tnear[l] = 1e-5f, ray.tfar[l] = 1 - 1e-5f, ray.time[l] = 0;
                ray.mask[l] = 0xFFFFFFFFu, ray.id[l] = 0, ray.flags[l] = 0;
            }
            rtcOccluded8(valid, scene, &context, &ray);
            for (int l = 0; l < 8; ++l) blocked[k + size_t(l)] += ray.tfar[l] < 0;
        }
    });
    out.intersect1 = raysPerSecond(count, [&](size_t b, size_t e) {
        RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        for (size_t k = b; k < e; ++k) {
            const Segment& s = gathers[k];
            RTCRayHit rh;
            rh.ray = RTCRay{s.org[0], s.org[1], s.org[2], 0.0f,        s.dir[0], s.dir[1],
                            s.dir[2], 0.0f,     3e38f,    0xFFFFFFFFu, 0,        0};
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
            rtcIntersect1(scene, &context, &rh);
            blocked[k] += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
        }
    });
    return out;
}

}  // namespace penumbra::bench
