#include "render/path_tracer.h"

#include "core/cluster.h"
#include "core/optics.h"
#include "render/camera.h"
#include "render/photon_map.h"

namespace penumbra {
namespace {

double powerHeuristic(double a, double b) { return a * a / (a * a + b * b); }

// Where each decision of a path's diffuse vertex v takes its numbers from: one dimension per decision,
// four-dimensional groups of the pixel's Sobol sets (core/sampler.h). The camera's point in the pixel
// takes dimensions 0-1; vertex v the walk through mirrors and glass before it (one number per choice
// between two branches) from 4 + 12 v, its light sample from 8 + 12 v, its bounce and roulette from
// 12 + 12 v. An Rng draws them in the same order.
void skipTo(Rng&, uint32_t) {}
void skipTo(PixelSampler& s, uint32_t dimension) { s.skipTo(dimension); }
constexpr uint32_t kWalk = 4, kLight = 8, kBounce = 12, kPerVertex = 12;

}  // namespace

template <typename Generator>
Rgb pathRadiance(const SceneTracer& tracer, const Vec3& origin, const Vec3& dir, Generator& rng,
                 const PathSettings& settings) {
    Rgb L = Rgb::Zero(), throughput = Rgb::Ones();
    Vec3 o = origin, d = dir;
    bool specular = true;          // the last bounce was the camera or a mirror/glass: emission counts fully
    double bsdfPdf = 0;            // solid-angle pdf of the last diffuse bounce, for MIS on emitters
    bool cameraSawDiffuse = true;  // the camera ray's first surface was diffuse
    bool byLight = false;          // this vertex's emission is the light paths' (causticsByLight)
    for (int depth = 0, vertex = 0; depth < settings.maxDepth; ++depth, ++vertex) {
        const uint32_t dims = kPerVertex * uint32_t(vertex);
        SurfaceHit hit = tracer.trace(o, d);
        if (hit.found && hit.material->type != MaterialType::Diffuse) {
            skipTo(rng, dims + kWalk);
            // Through mirrors and glass to the next diffuse surface; each bounce counts as a depth.
            const SpecularWalk w = walkSpecular(tracer, std::move(hit), d, rng, settings.maxDepth - depth - 1);
            throughput *= w.throughput;
            depth += w.bounces;
            specular = true;
            if (vertex == 0) cameraSawDiffuse = false;
            byLight = vertex == 1 && cameraSawDiffuse && w.bounces <= settings.causticsByLight;
            if (w.end != WalkEnd::Diffuse) break;
            hit = w.hit;
            d = w.dir;
        }
        if (!hit.found) break;
        const Material& m = *hit.material;
        if (!hit.frontFacing(d)) break;  // back faces are black
        if (m.emits() && !byLight) {
            if (specular) {
                L += throughput * hit.emission;
            } else {
                const double cosL = -hit.normal.dot(d);
                const double lightPdf = tracer.emitterPdfArea(hit.patch) * hit.t * hit.t / cosL;
                L += throughput * hit.emission * powerHeuristic(bsdfPdf, lightPdf);
            }
        }
        if ((hit.reflectance <= 0).all()) break;
        const Vec3 x = tracer.offset(hit, -d);
        // Next-event estimation: one point on the emitters.
        if (tracer.hasEmitters()) {
            skipTo(rng, dims + kLight);
            const LightSample l = tracer.sampleLight(hit.point, hit.normal, rng);
            if (l.found())
                L += throughput * hit.reflectance * kInvPi * l.radiance * (l.cosine / l.pdf) *
                     powerHeuristic(l.pdf, l.cosine * kInvPi);
        }
        // Cosine-sampled bounce: f cos / pdf = rho.
        skipTo(rng, dims + kBounce);
        d = cosineDirection(hit.normal, rng);
        bsdfPdf = hit.normal.dot(d) * kInvPi;
        o = x;
        throughput *= hit.reflectance;
        specular = false;
        byLight = false;
        if (depth + 1 >= settings.rouletteDepth) {
            const double q = std::min(0.95, throughput.maxCoeff() / settings.rouletteThroughput);
            if (q <= 0 || rng.uniform() >= q) break;
            throughput /= q;
        }
    }
    return L;
}

template Rgb pathRadiance(const SceneTracer&, const Vec3&, const Vec3&, Rng&, const PathSettings&);
template Rgb pathRadiance(const SceneTracer&, const Vec3&, const Vec3&, PixelSampler&, const PathSettings&);

Image renderPath(const SceneTracer& tracer, const Camera& camera, int samplesPerPixel, uint64_t seed,
                 const PathSettings& settings) {
    PathSettings s = settings;
    const int64_t lightPaths =
        tracer.hasSpecular() && tracer.hasEmitters()
            ? int64_t(std::ceil(s.lightPathsPerSample * double(camera.width) * camera.height * samplesPerPixel))
            : 0;
    const int kLightBounces = PhotonSettings{}.maxDepth;
    if (lightPaths > 0) s.causticsByLight = kLightBounces;
    Image image =
        !s.lowDiscrepancy
            ? renderPixels(camera, samplesPerPixel, seed, "path tracing",
                           [&](const Vec3& o, const Vec3& d, Rng& rng) { return pathRadiance(tracer, o, d, rng, s); })
            : renderPixelsSampled(camera, samplesPerPixel, seed, "path tracing",
                                  [&](const Vec3& o, const Vec3& d, PixelSampler& sampler) {
                                      return pathRadiance(tracer, o, d, sampler, s);
                                  });
    if (lightPaths > 0) {
        const Image light = lightPathsToEye(tracer, camera, lightPaths, seed, kLightBounces);
        for (size_t k = 0; k < image.rgb.size(); ++k) image.rgb[k] += light.rgb[k];
    }
    return image;
}

Image lightPathsToEye(const SceneTracer& tracer, const Camera& camera, int64_t paths, uint64_t seed, int maxBounces) {
    PhotonSettings settings;
    settings.photons = paths;
    settings.seed = seed;
    settings.maxDepth = maxBounces;
    const PinholeCamera eye(camera);
    const double pixelArea = eye.pixelArea();
    struct Splat {
        uint32_t pixel;
        Eigen::Vector3f value;
    };
    std::vector<std::vector<Splat>> splats;  // per chunk of photons, added in chunk order
    traceCausticPhotons(
        tracer, settings, Stream::LightPaths, "light paths", [&](int64_t chunks) { splats.resize(size_t(chunks)); },
        [&](int64_t c, const std::vector<PhotonLanding>& landings) {
            for (const PhotonLanding& l : landings) {
                const Vec3 toEye = eye.origin() - l.hit.point;
                const double distance = toEye.norm(), cosSurface = l.hit.normal.dot(toEye) / distance;
                double px, py, cosAxis;
                if (!(cosSurface > 0) || !eye.project(l.hit.point, px, py, cosAxis)) continue;
                if (!tracer.visible(tracer.offset(l.hit, toEye), eye.origin())) continue;
                const Rgb value = l.power * l.hit.reflectance * kInvPi * cosSurface /
                                  (distance * distance * cosAxis * cosAxis * cosAxis * pixelArea);
                splats[size_t(c)].push_back({uint32_t(int(py) * camera.width + int(px)), value.matrix().cast<float>()});
            }
        });
    cluster::shareChunks(splats);
    std::vector<Rgb> sum(size_t(camera.width) * size_t(camera.height), Rgb::Zero());
    for (const std::vector<Splat>& chunk : splats)
        for (const Splat& s : chunk) sum[s.pixel] += s.value.cast<double>().array();
    Image image(camera.width, camera.height);
    for (int y = 0; y < camera.height; ++y)
        for (int x = 0; x < camera.width; ++x) image.set(x, y, sum[size_t(y) * size_t(camera.width) + size_t(x)]);
    return image;
}

}  // namespace penumbra
