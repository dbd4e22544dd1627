#include "render/radiosity_view.h"

#include "render/film.h"

namespace penumbra {

Rgb interpolateAt(const PatchSet& patches, size_t patch, double u, double v, const std::array<Rgb, 4>& c) {
    if (patches.isTriangle(patch)) return (1 - u - v) * c[0] + u * c[1] + v * c[2];
    return (1 - u) * (1 - v) * c[0] + u * (1 - v) * c[1] + u * v * c[2] + (1 - u) * v * c[3];
}

Image renderRadiosityView(const Scene& scene, const Camera& camera, const PatchSet& patches, const RayScene& rays,
                          const std::vector<std::array<Rgb, 4>>& corners, const ViewSettings& settings) {
    return renderPixelsSampled(
        camera, settings.samplesPerPixel, settings.seed, "view",
        [&](const Vec3& origin, const Vec3& dir, PixelSampler&) -> Rgb {
            const Hit hit = rays.intersect(origin, dir);
            if (hit.patch < 0) return Rgb::Zero();
            const size_t p = size_t(hit.patch);
            if (patches.normal[p].dot(dir) >= 0) return Rgb::Zero();  // back face: black
            const Material& m = scene.materialOf(scene.objects[size_t(patches.object[p])]);
            if (m.type != MaterialType::Diffuse) return Rgb::Zero();
            return interpolateAt(patches, p, hit.u, hit.v, corners[p]) * kInvPi;
        },
        true);
}

}  // namespace penumbra
