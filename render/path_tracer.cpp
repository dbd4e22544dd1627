#include "render/path_tracer.h"

#include "core/optics.h"

namespace penumbra {
namespace {

double powerHeuristic(double a, double b) { return a * a / (a * a + b * b); }

}  // namespace

Rgb pathRadiance(const SceneTracer& tracer, const Vec3& origin, const Vec3& dir, Rng& rng,
                 const PathSettings& settings) {
    Rgb L = Rgb::Zero(), throughput = Rgb::Ones();
    Vec3 o = origin, d = dir;
    bool specular = true;  // the last bounce was the camera or a mirror/glass: emission counts fully
    double bsdfPdf = 0;    // solid-angle pdf of the last diffuse bounce, for MIS on emitters
    for (int depth = 0; depth < settings.maxDepth; ++depth) {
        SurfaceHit hit = tracer.trace(o, d);
        if (hit.found && hit.material->type != MaterialType::Diffuse) {
            // Through mirrors and glass to the next diffuse surface; each bounce counts as a depth.
            const SpecularWalk w = walkSpecular(tracer, std::move(hit), d, rng, settings.maxDepth - depth - 1);
            throughput *= w.throughput;
            depth += w.bounces;
            specular = true;
            if (w.end != WalkEnd::Diffuse) break;
            hit = w.hit;
            d = w.dir;
        }
        if (!hit.found) break;
        const Material& m = *hit.material;
        if (!hit.frontFacing(d)) break;  // back faces are black
        if (m.emits()) {
            if (specular) {
                L += throughput * m.emission;
            } else {
                const double cosL = -hit.normal.dot(d);
                const double lightPdf = tracer.emitterPdfArea(hit.patch) * hit.t * hit.t / cosL;
                L += throughput * m.emission * powerHeuristic(bsdfPdf, lightPdf);
            }
        }
        if ((m.reflectance <= 0).all()) break;
        const Vec3 x = tracer.offset(hit, -d);
        // Next-event estimation: one point on the emitters.
        if (tracer.hasEmitters()) {
            const LightSample l = tracer.sampleLight(hit.point, hit.normal, rng);
            if (l.found())
                L += throughput * m.reflectance * kInvPi * l.radiance * (l.cosine / l.pdf) *
                     powerHeuristic(l.pdf, l.cosine * kInvPi);
        }
        // Cosine-sampled bounce: f cos / pdf = rho.
        d = cosineDirection(hit.normal, rng);
        bsdfPdf = hit.normal.dot(d) * kInvPi;
        o = x;
        throughput *= m.reflectance;
        specular = false;
        if (depth + 1 >= settings.rouletteDepth) {
            const double q = std::min(0.95, throughput.maxCoeff());
            if (q <= 0 || rng.uniform() >= q) break;
            throughput /= q;
        }
    }
    return L;
}

Image renderPath(const SceneTracer& tracer, const Camera& camera, int samplesPerPixel, uint64_t seed,
                 const PathSettings& settings) {
    return renderPixels(camera, samplesPerPixel, seed, "path tracing", [&](const Vec3& o, const Vec3& d, Rng& rng) {
        return pathRadiance(tracer, o, d, rng, settings);
    });
}

}  // namespace penumbra
