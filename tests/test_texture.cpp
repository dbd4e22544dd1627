// Textures (issue 17): a diffuse material's reflectance (and emission) multiplied by an image laid on
// by texture coordinates. The solve takes each patch's mean over its area, the ray tracers the texel
// under each hit. Checked against closed forms: the furnace with a textured wall, and a textured
// floor under a parallel lamp (the irradiance of a point under a rectangle, times the texel).
#include <gtest/gtest.h>

#include <cmath>

#include "fixtures.h"
#include "io/image_io.h"
#include "render/camera.h"
#include "render/final_gather.h"
#include "render/path_tracer.h"
#include "render/radiosity_view.h"

using namespace penumbra;

namespace {

// IEC 61966-2-1, written out here rather than taken from the code under test.
double srgbDecoded(int byte) {
    const double c = byte / 255.0;
    return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

// A linear float EXR of `width` x `height` from value(x, y), in the test folder.
template <typename Value>
std::string writeTexture(const std::string& name, int width, int height, const Value& value) {
    Image image(width, height);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) image.set(x, y, Rgb::Constant(value(x, y)));
    const std::string path = test::tempDir() + "/" + name;
    writeLinearImage(image, path);
    return path;
}

// Stripes along u, four texels a period, of values a, b, b, b: over whole periods the bilinear
// texture's mean is (a + 3b) / 4, while at a boundary of periods (a patch's centroid) it reads
// (a + b) / 2.
constexpr double kA = 0.2, kB = 0.6, kStripeMean = (kA + 3 * kB) / 4;

}  // namespace

TEST(Texture, BilinearFilterAndWrapModes) {
    const Texture t("t", 2, 1, {0, 0, 0, 1, 1, 1}, Wrap::Repeat, Wrap::Clamp);
    EXPECT_DOUBLE_EQ(t.at(Vec2(0.25, 0.5))[0], 0);  // texel centres
    EXPECT_DOUBLE_EQ(t.at(Vec2(0.75, 0.5))[0], 1);
    EXPECT_DOUBLE_EQ(t.at(Vec2(0.5, 0.5))[0], 0.5);  // between them
    EXPECT_DOUBLE_EQ(t.at(Vec2(0.0, 0.5))[0], 0.5);  // repeat: the edge blends the last and first
    EXPECT_DOUBLE_EQ(t.at(Vec2(3.25, 7.0))[0], 0);   // periods away, v clamped
    EXPECT_DOUBLE_EQ(t.at(Vec2(-0.25, 0.5))[0], 1);
    const Texture c("c", 2, 1, {0, 0, 0, 1, 1, 1}, Wrap::Clamp, Wrap::Clamp);
    EXPECT_DOUBLE_EQ(c.at(Vec2(5.0, 0.5))[0], 1);
    EXPECT_DOUBLE_EQ(c.at(Vec2(-5.0, 0.5))[0], 0);
    const Texture m("m", 2, 1, {0, 0, 0, 1, 1, 1}, Wrap::Mirror, Wrap::Clamp);
    EXPECT_DOUBLE_EQ(m.at(Vec2(1.25, 0.5))[0], 1);  // mirrored: the second period runs backwards
    EXPECT_DOUBLE_EQ(m.at(Vec2(2.25, 0.5))[0], 0);
    EXPECT_DOUBLE_EQ(t.mean()[0], 0.5);
}

TEST(Texture, PngIsDecodedFromSrgbAndExrIsLinear) {
    const std::string png = test::tempDir() + "/srgb.png";
    writeRgb8(png, 2, 1, {0, 128, 255, 64, 64, 64});
    const auto t = readTextureFile(png);
    ASSERT_EQ(t->width(), 2);
    EXPECT_NEAR(t->texel(0, 0)[0], srgbDecoded(0), 1e-6);
    EXPECT_NEAR(t->texel(0, 0)[1], srgbDecoded(128), 1e-6);
    EXPECT_NEAR(t->texel(0, 0)[2], srgbDecoded(255), 1e-6);
    EXPECT_NEAR(t->texel(1, 0)[0], srgbDecoded(64), 1e-6);
    const auto e = readTextureFile(writeTexture("linear.exr", 2, 1, [](int x, int) { return x ? 0.3 : 0.7; }));
    EXPECT_NEAR(e->texel(0, 0)[0], 0.7, 1e-7);
    EXPECT_NEAR(e->texel(1, 0)[0], 0.3, 1e-7);
}

// The furnace (every surface emits 1 and reflects rho) with its top a striped texture whose mean over
// each patch is rho: B = pi / (1 - rho) everywhere. A solve that read the texel at each patch's centre
// ((a + b) / 2, not the mean) or left the texture out would miss it by percents. 64 periods a metre:
// 16 to a 0.25 m patch, whole periods still in its children four splits down (contact grading splits
// the patches along the cube's edges).
TEST(Texture, FurnaceWithATexturedWallKeepsItsClosedForm) {
    writeTexture("stripes.exr", 4 * 64, 1, [](int x, int) { return x % 4 == 0 ? kA : kB; });
    const std::string striped = cat(R"({"type": "diffuse", "reflectance_texture": "stripes.exr", "emission": 1})");
    const std::string json = test::furnaceCube(kStripeMean, striped, true);
    SolveOptions o;
    o.meshing.patchSize = 0.25;
    o.solverSettings.tolerance = 1e-9;
    o.solverSettings.maxIterations = 100000;
    const SolveResult r = solveScene(test::sceneFromJson(json, "striped-furnace.json"), o);
    ASSERT_TRUE(r.patches.hasUv());
    const double expected = kPi / (1 - kStripeMean);
    double worst = 0;
    for (const Rgb& B : r.solution.B) worst = std::max(worst, std::abs(B[0] / expected - 1));
    EXPECT_LT(worst, 0.005) << "furnace B off its closed form pi / (1 - rho)";
}

// A floor of 8 x 8 checker blocks (reflectance 0.2 and 0.8) under a parallel lamp of radiance 1 and
// the floor's size, 1 m above it, black: the radiance leaving a floor point is rho(x) F(x -> lamp),
// F the point-to-rectangle form factor (Howell B-3). Pixels whose floor point lies well inside a block
// are compared, per kind of block, as the path tracer, the final gather and the radiosity view show
// them.
TEST(Texture, TexturedFloorUnderALampShowsTheTexelTimesTheIrradiance) {
    writeTexture("checker.exr", 128, 128, [](int x, int y) { return (x / 16 + y / 16) % 2 ? 0.8 : 0.2; });
    const std::string json = R"({"materials": {
          "floor": {"type": "diffuse", "reflectance_texture": "checker.exr"},
          "lamp": {"type": "diffuse", "reflectance": 0, "emission": 1}},
      "objects": [
        {"name": "floor", "type": "quad", "material": "floor", "vertices": [[-1,0,-1],[-1,0,1],[1,0,1],[1,0,-1]]},
        {"name": "lamp", "type": "quad", "material": "lamp", "vertices": [[-1,1,-1],[1,1,-1],[1,1,1],[-1,1,1]]}],
      "camera": {"position": [0, 0.5, 0], "look_at": [0, 0, 0], "up": [0, 0, -1], "fov_y_deg": 60,
                 "resolution": [32, 32]}})";
    const Scene scene = test::sceneFromJson(json, "checker-floor.json");
    SolveOptions o;
    o.meshing.targetPatches = 400;
    const SolveResult r = solveScene(scene, o);
    const SceneTracer tracer(scene, r.patches, r.rays);
    const SolvedScene solved(scene, r.patches, r.corners, {}, {}, 1, r.rays, &r.solution.display, r.indirect);
    const std::vector<std::pair<std::string, Image>> images = {
        {"path tracer", renderPath(tracer, scene.camera, 64, 1)},
        {"final gather", solved.render(scene.camera, 16, 1)},
        {"radiosity view", renderRadiosityView(scene, scene.camera, r.patches, r.rays, r.corners, {})}};
    const PinholeCamera eye(scene.camera);
    for (const auto& [what, image] : images) {
        Rgb sum[2] = {Rgb::Zero(), Rgb::Zero()}, expected[2] = {Rgb::Zero(), Rgb::Zero()};
        int pixels[2] = {0, 0};
        for (int y = 0; y < image.height; ++y)
            for (int x = 0; x < image.width; ++x) {
                const Vec3 d = eye.direction(x + 0.5, y + 0.5);
                const Vec3 p = eye.origin() + (-eye.origin().y() / d.y()) * d;
                // Texture coordinates: u along the first edge (z), v along the last (x); 128 texels.
                const double tu = (p.z() + 1) / 2 * 128, tv = (p.x() + 1) / 2 * 128;
                const auto inside = [](double t) { return std::abs(t / 16 - std::round(t / 16)) * 16 > 2.5; };
                if (!inside(tu) || !inside(tv)) continue;
                const int kind = (int(tu / 16) + int(tv / 16)) % 2;
                const double F = test::pointToRectangle(-1 - p.x(), 1 - p.x(), -1 - p.z(), 1 - p.z(), 1);
                sum[kind] += image.at(x, y);
                expected[kind] += Rgb::Constant((kind ? 0.8 : 0.2) * F);
                ++pixels[kind];
            }
        for (int kind = 0; kind < 2; ++kind) {
            ASSERT_GT(pixels[kind], 100) << what;
            const double ratio = sum[kind][0] / expected[kind][0];
            EXPECT_NEAR(ratio, 1, what == "radiosity view" ? 0.03 : 0.015)
                << what << ", blocks of reflectance " << (kind ? 0.8 : 0.2) << " (" << pixels[kind] << " pixels)";
        }
    }
}

TEST(Texture, AMissingOrBrightReflectanceTextureIsRefusedByName) {
    const auto scene = [](const std::string& file) {
        return cat(R"({"materials": {"m": {"type": "diffuse", "reflectance_texture": ")", file, R"("}},
          "objects": [{"name": "q", "type": "quad", "material": "m", "vertices": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}]})");
    };
    try {
        test::sceneFromJson(scene("nowhere.png"), "missing-texture.json");
        FAIL() << "a missing texture was accepted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("materials.m.reflectance_texture"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("nowhere.png"), std::string::npos) << e.what();
    }
    writeTexture("bright.exr", 1, 1, [](int, int) { return 2.0; });
    try {
        test::sceneFromJson(scene("bright.exr"), "bright-texture.json");
        FAIL() << "a reflectance of 2 was accepted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("[0, 1]"), std::string::npos) << e.what();
    }
}
