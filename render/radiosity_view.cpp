#include "render/radiosity_view.h"

#include "core/parallel.h"
#include "core/progress.h"
#include "core/rng.h"
#include "render/camera.h"

namespace penumbra {

Rgb interpolateAt(const PatchSet& patches, size_t patch, double u, double v, const std::array<Rgb, 4>& c) {
    if (patches.isTriangle(patch)) return (1 - u - v) * c[0] + u * c[1] + v * c[2];
    return (1 - u) * (1 - v) * c[0] + u * (1 - v) * c[1] + u * v * c[2] + (1 - u) * v * c[3];
}

Image renderRadiosityView(const Scene& scene, const Camera& camera, const PatchSet& patches, const RayScene& rays,
                          const std::vector<std::array<Rgb, 4>>& corners, const ViewSettings& settings) {
    const PinholeCamera cam(camera);
    Image image(camera.width, camera.height);
    int side = 1;
    while (side * side < settings.samplesPerPixel) ++side;
    const int spp = side * side;
    Progress progress("view", camera.height);
    parallelFor(camera.height, [&](int64_t y0, int64_t y1) {
        prepareTracingThread();
        for (int64_t y = y0; y < y1; ++y) {
            for (int x = 0; x < camera.width; ++x) {
                Rng rng(mixSeed(settings.seed, uint64_t(y), uint64_t(x)));
                Rgb sum = Rgb::Zero();
                for (int s = 0; s < spp; ++s) {
                    const double px = x + ((s % side) + rng.uniform()) / side;
                    const double py = double(y) + ((s / side) + rng.uniform()) / side;
                    const Vec3 dir = cam.direction(px, py);
                    const Hit hit = rays.intersect(cam.origin(), dir);
                    if (hit.patch < 0) continue;
                    const size_t p = size_t(hit.patch);
                    if (patches.normal[p].dot(dir) >= 0) continue;   // back face: black
                    const Material& m = scene.materialOf(scene.objects[size_t(patches.object[p])]);
                    if (m.type != MaterialType::Diffuse) continue;
                    sum += interpolateAt(patches, p, hit.u, hit.v, corners[p]) * kInvPi;
                }
                image.set(x, int(y), sum / spp);
            }
            progress.update();
        }
    });
    return image;
}

}  // namespace penumbra
