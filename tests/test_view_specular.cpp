// The radiosity view through mirrors and glass (issue 18), against closed forms: a mirror shows the
// wall it faces at that wall's radiosity times the mirror's reflectance over pi, and a glass slab
// at normal incidence passes (1 - R) / (1 + R) of what lies behind it (R Fresnel's reflectance,
// with every internal reflection summed).
#include <gtest/gtest.h>

#include "core/counters.h"
#include "fixtures.h"
#include "render/image_metrics.h"
#include "render/radiosity_view.h"

using namespace penumbra;

namespace {

// A lamp wall of radiance 1 (reflectance 0: its radiosity is its emission, pi) at z = 0 facing +z,
// 4 m wide, and `between` (objects between it and the camera, or behind the camera); a camera of
// 10 degrees at (0, 0, z) looking along `look`.
Image viewOf(const std::string& between, double z, double look, CounterValues* counted = nullptr) {
    const std::string json = R"({"materials": {
        "lamp": {"type": "diffuse", "reflectance": 0, "emission": 1},
        "chrome": {"type": "mirror", "reflectance": 0.8},
        "glass": {"type": "dielectric", "ior": 1.5}},
      "objects": [
        {"name": "wall", "type": "quad", "material": "lamp",
         "vertices": [[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]]})" +
                             between + "]}";
    const SolveResult r = test::solve(json, 200);
    Camera camera;
    camera.position = Vec3(0, 0, z);
    camera.lookAt = Vec3(0, 0, z + look);
    camera.fovYDeg = 10;
    camera.width = camera.height = 32;
    const CounterValues before = counterValues();
    Image image = renderRadiosityView(test::sceneFromJson(json), camera, r.patches, r.rays, r.corners, {4, 1});
    if (counted) *counted = countersSince(before);  // the view's own rays and samples
    return image;
}

}  // namespace

// Camera at z = 1 looking away from the wall, at a mirror at z = 2 facing it: every pixel is the
// wall's radiance, 1, times 0.8.
TEST(RadiosityView, AMirrorShowsTheWallItFacesTimesItsReflectance) {
    const Image image = viewOf(R"(, {"name": "mirror", "type": "quad", "material": "chrome",
         "vertices": [[-2, -2, 2], [-2, 2, 2], [2, 2, 2], [2, -2, 2]]})",
                               1, 1);
    const Rgb mean = meanOver(image, 0, 0, image.width, image.height);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c], 0.8, 0.8 * 0.005) << c;
}

// Camera at z = 3 looking at the wall through a glass slab (z from 1 to 1.1, its faces facing out):
// T = (1 - R)^2 (1 + R^2 + R^4 ...) = (1 - R) / (1 + R) with R = (0.5 / 2.5)^2 = 0.04: 0.923077.
TEST(RadiosityView, AGlassSlabAtNormalIncidencePassesWhatFresnelSays) {
    const Image image = viewOf(R"(, {"name": "front", "type": "quad", "material": "glass",
         "vertices": [[-2, -2, 1.1], [2, -2, 1.1], [2, 2, 1.1], [-2, 2, 1.1]]},
        {"name": "back", "type": "quad", "material": "glass",
         "vertices": [[-2, -2, 1], [-2, 2, 1], [2, 2, 1], [2, -2, 1]]})",
                               3, -1);
    const double R = 0.04, T = (1 - R) / (1 + R);
    const Rgb mean = meanOver(image, 0, 0, image.width, image.height);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c], T, T * 0.005) << c;
}

// The same slab: a branch is followed while what the camera's ray carries stays above a thousandth
// (ViewSettings::minThroughput), not while each step's own weight does. Each camera sample then casts
// seven rays: off the front (0.04), to the back (0.96), through it (0.92) and back up (0.038), out
// of the front (0.037) and down again (0.0015), through the back (0.0015); the next reflection
// (6e-5) is dropped. Judged by each step's weight (0.04 > 0.001) the walk went on to the depth cap,
// 16 bounces, four times the rays for light ten thousand times fainter than the picture's error.
TEST(RadiosityView, GlassIsFollowedWhileItsLightCountsAndNoFurther) {
    CounterValues counted;
    viewOf(R"(, {"name": "front", "type": "quad", "material": "glass",
         "vertices": [[-2, -2, 1.1], [2, -2, 1.1], [2, 2, 1.1], [-2, 2, 1.1]]},
        {"name": "back", "type": "quad", "material": "glass",
         "vertices": [[-2, -2, 1], [-2, 2, 1], [2, 2, 1], [2, -2, 1]]})",
           3, -1, &counted);
    const double samples = double(counted.at("render.camera_samples"));
    ASSERT_GT(samples, 0);
    EXPECT_NEAR(double(counted.at("rays.nearest")) / samples, 7.0, 0.01);
}
