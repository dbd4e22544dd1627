#include "render/film.h"

#include "core/counters.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "core/rng.h"
#include "render/camera.h"
#include "solver/visibility.h"

namespace penumbra {
namespace {
const Counter g_cameraSamples("render.camera_samples", "camera rays (samples of pixels), all integrators");
}  // namespace

Image renderPixels(const Camera& camera, int samplesPerPixel, uint64_t seed, const char* title,
                   const RadianceFn& radiance) {
    const PinholeCamera cam(camera);
    Image image(camera.width, camera.height);
    const int side = stratumSide(samplesPerPixel);
    const int spp = side * side;
    Progress progress(title, camera.height);
    parallelFor(camera.height, [&](int64_t y0, int64_t y1) {
        prepareTracingThread();
        for (int64_t y = y0; y < y1; ++y) {
            for (int x = 0; x < camera.width; ++x) {
                Rng rng = pairRng(seed, Stream::Pixels, uint64_t(y), uint64_t(x));
                Rgb sum = Rgb::Zero();
                for (int s = 0; s < spp; ++s) {
                    const double px = x + ((s % side) + rng.uniform()) / side;
                    const double py = double(y) + ((s / side) + rng.uniform()) / side;
                    sum += radiance(cam.origin(), cam.direction(px, py), rng);
                }
                image.set(x, int(y), sum / spp);
            }
            g_cameraSamples.add(uint64_t(camera.width) * uint64_t(spp));
            progress.update();
        }
    });
    progress.done();
    return image;
}

}  // namespace penumbra
