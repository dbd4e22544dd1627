#include "render/radiosity_view.h"

#include "render/film.h"
#include "solver/tracer.h"

namespace penumbra {

Rgb interpolateAt(const PatchSet& patches, size_t patch, double u, double v, const std::array<Rgb, 4>& c) {
    if (patches.isTriangle(patch)) return (1 - u - v) * c[0] + u * c[1] + v * c[2];
    return (1 - u) * (1 - v) * c[0] + u * (1 - v) * c[1] + u * v * c[2] + (1 - u) * v * c[3];
}

namespace {

// What the view shows along a ray that may meet mirrors and glass: both branches at each (Fresnel's
// reflection and refraction, or total internal reflection), weighted as the final gather's camera
// rays are, until a diffuse front face shows its interpolated radiosity B / pi. No random numbers:
// the picture is as smooth as the radiosity it shows.
Rgb throughSpecular(const SceneTracer& tracer, const std::vector<std::array<Rgb, 4>>& corners, const Vec3& origin,
                    const Vec3& dir, const ViewSettings& settings, int depth) {
    const SurfaceHit hit = tracer.trace(origin, dir);
    if (!hit.found) return Rgb::Zero();
    if (hit.material->type == MaterialType::Diffuse) {
        if (!hit.frontFacing(dir) || hit.patch < 0) return Rgb::Zero();
        const size_t p = size_t(hit.patch);
        return interpolateAt(tracer.patches(), p, hit.u, hit.v, corners[p]) * kInvPi;
    }
    if (depth >= settings.maxSpecularDepth) return Rgb::Zero();
    SpecularBranch branches[2];
    const int count = specularBranches(hit, dir, branches);
    Rgb L = Rgb::Zero();
    for (int b = 0; b < count; ++b)
        if (branches[b].weight.maxCoeff() >= settings.minThroughput)
            L += branches[b].weight * throughSpecular(tracer, corners, tracer.offset(hit, branches[b].dir),
                                                      branches[b].dir, settings, depth + 1);
    return L;
}

}  // namespace

Image renderRadiosityView(const Scene& scene, const Camera& camera, const PatchSet& patches,
                          const std::shared_ptr<const RayScene>& rays, const std::vector<std::array<Rgb, 4>>& corners,
                          const ViewSettings& settings) {
    // Mirrors and glass are followed by the tracer, which knows the materials (and the exact spheres).
    const std::unique_ptr<const SceneTracer> tracer =
        scene.hasSpecular() ? std::make_unique<const SceneTracer>(scene, patches, rays) : nullptr;
    return renderPixelsSampled(
        camera, settings.samplesPerPixel, settings.seed, "view",
        [&](const Vec3& origin, const Vec3& dir, PixelSampler&) -> Rgb {
            const Hit hit = rays->intersect(origin, dir);
            if (hit.patch < 0) return Rgb::Zero();
            const size_t p = size_t(hit.patch);
            const Material& m = scene.materialOf(scene.objects[size_t(patches.object[p])]);
            if (m.type != MaterialType::Diffuse)
                return tracer ? throughSpecular(*tracer, corners, origin, dir, settings, 0) : Rgb::Zero();
            if (patches.normal[p].dot(dir) >= 0) return Rgb::Zero();  // back face: black
            return interpolateAt(patches, p, hit.u, hit.v, corners[p]) * kInvPi;
        },
        true);
}

}  // namespace penumbra
