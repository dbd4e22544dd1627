// Both integrators against closed forms: the furnace (radiance E / (1 - rho) / pi, also with a
// perfect mirror wall, which keeps it a furnace), a glass slab that transmits (1 - R) / (1 + R) at
// normal incidence, the photons' total power, the two rooms (no light through the shared wall),
// and determinism (the same bits whatever the thread count; another seed changes only noise).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "core/counters.h"
#include "core/optics.h"
#include "core/parallel.h"
#include "fixtures.h"
#include "render/camera.h"
#include "render/direct_light.h"
#include "render/final_gather.h"
#include "render/image_metrics.h"
#include "render/occlusion.h"
#include "render/path_tracer.h"
#include "render/photon_map.h"
#include "render/radiosity_view.h"
#include "render/visibility_buffer.h"
#include "solver/radiosity/form_factor_kernel.h"
#include "statistics.h"

using namespace penumbra;

namespace {

// The furnace cube seen from inside; its top may be a perfect mirror.
std::string furnace(double rho, bool mirrorTop) {
    return test::furnaceCube(rho, R"({"type": "mirror", "reflectance": 1})", mirrorTop, "",
                             R"(, "camera": {"position": [0.5, 0.3, 0.2], "look_at": [0.5, 0.8, 1], "up": [0, 1, 0],
                                            "fov_y_deg": 90, "resolution": [16, 16]})");
}

// A 2 x 2 x 0.1 glass slab in front of a black lamp of radiance 1 filling the view.
std::string glassSlab(double ior) {
    return cat(R"({"materials": {"glass": {"type": "dielectric", "ior": )", ior, R"(},
                   "lamp": {"type": "diffuse", "reflectance": 0, "emission": 1}},
      "objects": [
        {"name": "near", "type": "quad", "material": "glass", "vertices": [[-1,-1,0],[-1,1,0],[1,1,0],[1,-1,0]]},
        {"name": "far",  "type": "quad", "material": "glass", "vertices": [[-1,-1,0.1],[1,-1,0.1],[1,1,0.1],[-1,1,0.1]]},
        {"name": "xlo",  "type": "quad", "material": "glass", "vertices": [[-1,-1,0],[-1,-1,0.1],[-1,1,0.1],[-1,1,0]]},
        {"name": "xhi",  "type": "quad", "material": "glass", "vertices": [[1,-1,0],[1,1,0],[1,1,0.1],[1,-1,0.1]]},
        {"name": "ylo",  "type": "quad", "material": "glass", "vertices": [[-1,-1,0],[1,-1,0],[1,-1,0.1],[-1,-1,0.1]]},
        {"name": "yhi",  "type": "quad", "material": "glass", "vertices": [[-1,1,0],[-1,1,0.1],[1,1,0.1],[1,1,0]]},
        {"name": "lamp", "type": "quad", "material": "lamp", "vertices": [[-5,-5,1],[-5,5,1],[5,5,1],[5,-5,1]]}],
      "camera": {"position": [0, 0, -1], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y_deg": 2, "resolution": [8, 8]}})");
}

// Two lamps of different colours and sizes, a glass ball between them and the floor.
std::string twoLampsAndAGlassBall() {
    return R"({"materials": {
          "warm": {"type": "diffuse", "reflectance": 0.5, "emission": [4, 2, 1]},
          "cold": {"type": "diffuse", "reflectance": 0.5, "emission": [0.5, 1, 3]},
          "white": {"type": "diffuse", "reflectance": 0.7},
          "glass": {"type": "dielectric", "ior": 1.5}},
      "objects": [
        {"name": "floor", "type": "quad", "material": "white", "vertices": [[-2,0,-2],[-2,0,2],[2,0,2],[2,0,-2]]},
        {"name": "warm", "type": "quad", "material": "warm", "vertices": [[-1,2,-1],[1,2,-1],[1,2,0],[-1,2,0]]},
        {"name": "cold", "type": "quad", "material": "cold", "vertices": [[-0.5,2,0.5],[0.5,2,0.5],[0.5,2,1],[-0.5,2,1]]},
        {"name": "ball", "type": "sphere", "material": "glass", "center": [0, 0.7, 0], "radius": 0.5}]})";
}

PhotonStats tracePhotons(const std::string& json, int64_t photons, Rgb& emitted) {
    const Scene scene = test::sceneFromJson(json);
    const PatchSet patches = meshScene(scene, {});
    const SceneTracer tracer(scene, patches);
    PhotonSettings settings;
    settings.photons = photons;
    settings.aim = false;  // the emission itself
    emitted = tracer.emittedPower();
    return PhotonMap(tracer, settings).stats();
}

Rgb imageMean(const Image& image) { return meanOver(image, 0, 0, image.width, image.height); }

Image pathImage(const std::string& json, int spp, uint64_t seed = 1) {
    const Scene scene = test::sceneFromJson(json);
    const PatchSet patches = meshScene(scene, {});
    const SceneTracer tracer(scene, patches);
    return renderPath(tracer, scene.camera, spp, seed);
}

Image gatherImage(const std::string& json, int patches, int spp, uint64_t seed = 1, const Camera* camera = nullptr) {
    const Scene scene = test::sceneFromJson(json);
    const SolveResult r = test::solve(json, patches);
    // As `render` does by default: the solve's indirect light read where the scene has small sources.
    const SolvedScene solved(scene, r.patches, r.corners, {}, {}, seed, r.rays, &r.solution.display, r.indirect);
    return solved.render(camera ? *camera : scene.camera, spp, seed);
}

}  // namespace

TEST(PathTracer, FurnaceRadianceIsEOverOneMinusRho) {
    for (double rho : {0.5, 0.9}) {
        const Rgb mean = imageMean(pathImage(furnace(rho, false), 1024));
        EXPECT_NEAR(mean[0], 1 / (1 - rho), 0.01 / (1 - rho)) << "rho " << rho;
    }
}

TEST(PathTracer, PerfectMirrorWallKeepsTheFurnace) {
    const Image image = pathImage(furnace(0.5, true), 64);
    EXPECT_NEAR(imageMean(image)[0], 2.0, 0.02);
    // The upper rows look into the mirror: they see the furnace too.
    EXPECT_NEAR(meanOver(image, 0, 0, 16, 4)[0], 2.0, 0.04);
}

TEST(FinalGather, FurnaceRadianceIsEOverOneMinusRho) {
    for (bool mirror : {false, true}) {
        const Rgb mean = imageMean(gatherImage(furnace(0.5, mirror), 150, 64));
        EXPECT_NEAR(mean[0], 2.0, 0.02) << (mirror ? "with a mirror wall" : "all diffuse");
    }
}

TEST(GlassSlab, TransmitsWhatFresnelSays) {
    // Normal incidence, all internal reflections summed: T = (1 - R)^2 / (1 - R^2) = (1 - R) / (1 + R).
    for (double ior : {1.5, 2.4}) {
        const double R = fresnelDielectric(1, 1, ior), T = (1 - R) / (1 + R);
        // Each path sample is 1 (through to the lamp) or 0 (reflected away): a Bernoulli trial of
        // mean T, so the image mean of N samples has standard deviation sqrt(T (1 - T) / N). z-test,
        // two-sided at 1e-4 (|z| < 3.9), Sidak-corrected over the two indices.
        const int spp = 1024, pixels = 64;
        const double sigma = std::sqrt(T * (1 - T) / (double(spp) * pixels));
        const double z = (imageMean(pathImage(glassSlab(ior), spp))[0] - T) / sigma;
        EXPECT_LT(std::abs(z), test::zLimit(test::sidak(1e-4, 2))) << "path, ior " << ior;
        EXPECT_NEAR(imageMean(gatherImage(glassSlab(ior), 100, 4))[0], T, 1e-3 * T) << "final gather, ior " << ior;
    }
}

TEST(Photons, TotalPowerEqualsTheEmittersPower) {
    Rgb expected;
    const PhotonStats stats = tracePhotons(twoLampsAndAGlassBall(), 200000, expected);
    // pi L_e A per lamp: the tracer's sum is the closed form.
    EXPECT_NEAR(expected[0], kPi * (4 * 2 + 0.5 * 0.5), 1e-9);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(stats.emittedPower[c], expected[c], 0.01 * expected[c]) << c;
    EXPECT_GT(stats.stored, 1000);
    EXPECT_LT(stats.storedPower.sum(), stats.emittedPower.sum());
}

// Photons aimed at the glass ball (cones about it from each lamp point) against photons emitted over
// the lamps' hemispheres, two independent estimates of the same caustic: the power stored on the
// floor in a 4 x 4 grid under the ball, bin by bin within 4.5 standard errors of the plain pass (its
// photons' powers' spread), and the aimed pass tracing under a fifth as many photons. A wrong
// density over a cone (its solid angle, the cosine, two lamps' mixture) moves power between bins or
// scales it all.
TEST(Photons, AimedAtTheGlassTheyStoreWhatPlainEmissionStores) {
    const Scene scene = test::sceneFromJson(twoLampsAndAGlassBall());
    const PatchSet patches = meshScene(scene, {});
    const SceneTracer tracer(scene, patches);
    constexpr int kGrid = 4;
    const auto bins = [&](const PhotonMap& map, std::vector<double>& power, std::vector<double>& square) {
        power.assign(kGrid * kGrid, 0), square.assign(kGrid * kGrid, 0);
        for (const PhotonMap::Stored& p : map.storedPhotons()) {
            const int i = int(std::floor((p.position.x() + 1) / 2 * kGrid)),
                      j = int(std::floor((p.position.z() + 1) / 2 * kGrid));
            if (p.position.y() > 1e-3 || i < 0 || j < 0 || i >= kGrid || j >= kGrid) continue;
            power[size_t(i * kGrid + j)] += p.power.sum(),
                square[size_t(i * kGrid + j)] += p.power.sum() * p.power.sum();
        }
    };
    PhotonSettings plain;
    plain.photons = 2000000;
    plain.aim = false;
    plain.precompute = 0;
    PhotonSettings aimed = plain;
    aimed.aim = true;
    aimed.seed = 2;
    const PhotonMap a(tracer, aimed), b(tracer, plain);
    EXPECT_GT(a.stats().aimed, 0);
    EXPECT_LT(a.stats().aimed, plain.photons / 5);
    EXPECT_EQ(b.stats().aimed, 0);
    std::vector<double> pa, sa, pb, sb;
    bins(a, pa, sa);
    bins(b, pb, sb);
    double total = 0;
    for (size_t k = 0; k < pa.size(); ++k) {
        total += pb[k];
        EXPECT_NEAR(pa[k], pb[k], 4.5 * std::sqrt(sb[k] + sa[k]) + 1e-9) << "bin " << k;
    }
    EXPECT_GT(total, 0.5 * b.stats().storedPower.sum()) << "the caustic falls within the grid";
}

// A ball through the middle of a lamp (none of the lamp's corners in it): from the points inside it
// every direction meets the ball, which no cone holds, so the photons are emitted plainly.
TEST(Photons, ABallThroughALampIsNotAimedAt) {
    const Scene scene = test::sceneFromJson(R"({"materials": {
          "lamp": {"type": "diffuse", "reflectance": 0.5, "emission": 1},
          "white": {"type": "diffuse", "reflectance": 0.7},
          "glass": {"type": "dielectric", "ior": 1.5}},
      "objects": [
        {"name": "floor", "type": "quad", "material": "white", "vertices": [[-2,0,-2],[-2,0,2],[2,0,2],[2,0,-2]]},
        {"name": "lamp", "type": "quad", "material": "lamp", "vertices": [[-1,2,-1],[1,2,-1],[1,2,1],[-1,2,1]]},
        {"name": "ball", "type": "sphere", "material": "glass", "center": [0.5, 2, 0.5], "radius": 0.3}]})");
    MeshingOptions coarse;
    coarse.patchSize = 1;  // the lamp in 2 x 2 patches, the ball in the middle of one
    const PatchSet patches = meshScene(scene, coarse);
    const SceneTracer tracer(scene, patches);
    PhotonSettings settings;
    settings.photons = 20000;
    const PhotonMap map(tracer, settings);
    EXPECT_EQ(map.stats().aimed, 0);
    EXPECT_GT(map.stats().stored, 0);
}

TEST(Photons, OneLampsPhotonsCarryExactlyItsPower) {
    const std::string json = R"({"materials": {"lamp": {"type": "diffuse", "reflectance": 0.5, "emission": [3, 2, 1]},
          "chrome": {"type": "mirror", "reflectance": 0.9}},
      "objects": [
        {"name": "lamp", "type": "quad", "material": "lamp", "vertices": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]},
        {"name": "mirror", "type": "quad", "material": "chrome", "vertices": [[0,0,1],[0,1,1],[1,1,1],[1,0,1]]}]})";
    Rgb expected;
    const PhotonStats stats = tracePhotons(json, 10000, expected);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(stats.emittedPower[c], kPi * (3 - c), 1e-9) << c;
}

// The small sources' direct light as the final gather takes it (closed form times stratified shadow
// rays) against emitter sampling (the path tracer's next-event estimate, 200,000 samples a point):
// a lamp over a floor, and a wall beside it whose plane cuts the lamp. Points in its penumbra on
// both sides, one on the wall itself (which sees only the lamp's part in front of it: the closed
// form leaves the rest out, so rays to it must not count as blocked), and one in full view.
TEST(DirectLight, AgreesWithEmitterSamplingInPenumbraeAndWhereAPlaneCutsTheLamp) {
    const Scene scene = test::sceneFromJson(R"({"materials": {"white": {"type": "diffuse", "reflectance": 0.5},
                   "lamp": {"type": "diffuse", "reflectance": 0, "emission": 10}},
      "objects": [
        {"name": "floor", "type": "quad", "material": "white", "vertices": [[2,0,-2],[-2,0,-2],[-2,0,2],[2,0,2]]},
        {"name": "wall", "type": "quad", "material": "white",
         "vertices": [[0.1,0,-2],[0.1,0.9,-2],[0.1,0.9,2],[0.1,0,2]]},
        {"name": "lamp", "type": "quad", "material": "lamp",
         "vertices": [[0.25,1,-0.25],[0.25,1,0.25],[-0.25,1,0.25],[-0.25,1,-0.25]]}]})");
    const PatchSet patches = meshScene(scene, {});
    const SceneTracer tracer(scene, patches);
    const DirectLight direct(scene, patches);
    ASSERT_EQ(direct.sources(), 1u) << "the lamp, as one polygon";
    const Vec3 up(0, 1, 0), side(1, 0, 0);
    const std::vector<std::pair<Vec3, Vec3>> points{
        {{0.5, 0, 0.3}, up}, {{-0.5, 0, -0.2}, up}, {{0, 0, 0}, up}, {{0.1, 0.5, 0.5}, side}, {{1.5, 0, 1.5}, up}};
    for (const auto& [x, n] : points) {
        Rng rng(7);
        const int samples = 200000;
        double sum = 0, sum2 = 0;
        for (int k = 0; k < samples; ++k) {
            const LightSample l = tracer.sampleLight(x, n, rng);
            const double e = l.found() ? l.radiance[0] * l.cosine / l.pdf : 0;
            sum += e, sum2 += e * e;
        }
        const double mean = sum / samples, sigma = std::sqrt(std::max(0.0, sum2 / samples - mean * mean) / samples);
        double ours = 0;
        for (int k = 0; k < 16; ++k) ours += direct.irradiance(tracer, x + tracer.epsilon() * n, n, 1024, rng)[0] / 16;
        std::printf("at (%g, %g, %g): closed form x shadow rays %.5f, emitter sampling %.5f +- %.5f W/m^2\n", x.x(),
                    x.y(), x.z(), ours, mean, sigma);
        EXPECT_GT(mean, 0.01);
        EXPECT_NEAR(ours, mean, 4 * sigma + 0.005 * mean) << "at " << x.transpose();
    }
}

// The pixels of an image share their sets (renderPixelsSampled): at one sample per pixel, the points
// an aligned 2^k x 2^k block of pixels draws (here dimensions 4 and 5, the first a radiance function
// takes) are a (0, 2k, 2)-net, one point in each 2^-a x 2^-(2k-a) box, so that neighbours' errors
// cancel. A block ordered other than by its Morton ranks, or a stride that overlapped two pixels'
// runs, breaks it; tiles of 64 x 64 draw from sets of their own.
TEST(PathTracer, NeighbouringPixelsDrawOneNet) {
    Camera camera;
    camera.width = camera.height = 128;
    const Image image = renderPixelsSampled(camera, 1, 7, "test", [](const Vec3&, const Vec3&, PixelSampler& s) {
        const double u = s.uniform(), v = s.uniform();
        return Rgb(u, v, 0);
    });
    for (int k = 1; k <= 3; ++k) {
        const int side = 1 << k, n = side * side;
        for (int by = 0; by < camera.height; by += side)
            for (int bx = 0; bx < camera.width; bx += side)
                for (int a = 0; a <= 2 * k; ++a) {
                    std::vector<int> box(size_t(n), 0);
                    for (int y = by; y < by + side; ++y)
                        for (int x = bx; x < bx + side; ++x) {
                            const Rgb p = image.at(x, y);
                            ++box[size_t(int(p[0] * (1 << a)) * (1 << (2 * k - a)) + int(p[1] * (1 << (2 * k - a))))];
                        }
                    ASSERT_EQ(*std::max_element(box.begin(), box.end()), 1)
                        << side << " x " << side << " block at (" << bx << ", " << by << "), boxes 2^-" << a;
                }
    }
    EXPECT_NE(image.at(0, 0)[0], image.at(64, 0)[0]) << "two tiles drew the same set";
    EXPECT_NE(image.at(0, 0)[0], image.at(0, 64)[0]) << "two tiles drew the same set";
}

// A lamp's edge across a pixel at one sample per pixel: one sample has no spread, so the edge is told
// by the pixel's neighbours, and the pixel sampled again (four more samples, a net over it). A lamp
// of radiance 50 beside a wall of 1, its edge at x = 10.3 px: pixel 10 is 0.3 or 0.7 lamp, its mean
// 15.7 or 35.3; with five samples within a fifth of the lamp's 49 of it. Without the edge pass it
// reads 1 or 50, 14.7 or 15.3 off.
TEST(PathTracer, ALampsEdgeIsFoundAtOneSamplePerPixel) {
    Camera camera;
    camera.fovYDeg = 60;
    camera.width = camera.height = 16;
    const PinholeCamera cam(camera);
    const Vec3 edge = cam.direction(10.3, 8), side = edge.cross(camera.up).normalized();
    const auto radiance = [&](const Vec3&, const Vec3& d, PixelSampler&) {
        return Rgb::Constant(d.dot(side) < 0 ? 50 : 1);
    };
    const double leftIsLamp = cam.direction(10.0, 8).dot(side) < 0;
    const double lamp = leftIsLamp ? 0.3 : 0.7, expected = 50 * lamp + (1 - lamp);
    const Image image = renderPixelsSampled(camera, 1, 3, "test", radiance, true);
    for (int y = 0; y < camera.height; ++y) EXPECT_NEAR(image.at(10, y)[0], expected, 49 / 5.0) << "row " << y;
    EXPECT_EQ(image.at(2, 8)[0], leftIsLamp ? 50 : 1) << "far from the edge";
}

// The path tracer's low-discrepancy numbers (one dimension per decision, Owen-scrambled Sobol per
// pixel, shared by neighbouring pixels) against independent ones at equal samples: the Cornell box
// at 64 x 64 and 16 samples per pixel, both against the same 1,024-sample image (another seed), by
// the project's measure (pooled L1 after the 5x5 blur) and without the blur. Measured 0.743 and
// 0.791 (0.767 and 0.778 with a set per pixel; at 256 x 256 against the 4,096-sample reference:
// 1.51% at 16 spp, 0.71% at 64, 0.35% at 256). A sampler that lost its stratification (or reused
// a number for two decisions) reads about 1.
TEST(PathTracerSlow, LowDiscrepancyNumbersCutTheErrorAtEqualSamples) {
    const Scene scene = test::sceneFromJson(test::sceneFile("cornell-box.json"), "cornell-box.json");
    const PatchSet patches = meshScene(scene, {});
    const SceneTracer tracer(scene, patches);
    Camera camera = scene.camera;
    camera.width = camera.height = 64;
    const Image reference = renderPath(tracer, camera, 1024, 9);
    PathSettings independent;
    independent.lowDiscrepancy = false;
    double sampled = 0, plain = 0, sampledRaw = 0, plainRaw = 0;
    for (uint64_t seed : {1, 2, 3}) {
        const Image a = renderPath(tracer, camera, 16, seed), b = renderPath(tracer, camera, 16, seed, independent);
        sampled += compareBlurred(a, reference).pooledL1 / 3, plain += compareBlurred(b, reference).pooledL1 / 3;
        sampledRaw += compareImages(a, reference).pooledL1 / 3, plainRaw += compareImages(b, reference).pooledL1 / 3;
    }
    std::printf(
        "16 spp, pooled L1 after the blur: low-discrepancy %.4f, independent %.4f (ratio %.3f); without the "
        "blur %.4f, %.4f (%.3f)\n",
        sampled, plain, sampled / plain, sampledRaw, plainRaw, sampledRaw / plainRaw);
    EXPECT_LT(sampled, 0.85 * plain);
    EXPECT_LT(sampledRaw, 0.9 * plainRaw);
}

// Light paths against camera paths: two independent estimates of one light, the caustics a camera
// ray's first surface shows (eye, diffuse, one or more mirror or glass bounces, lamp). The camera's
// estimate is its paths with that light less the same paths (the same numbers) without it; the
// light paths' is the photons from the lamps joined to the eye (lightPathsToEye). A wrong pixel for a
// landing, a wrong factor in its value (the cosines, the distance, the pixel's area) or light left
// out or counted twice by either side shows as a difference, in the image and per block of it.
TEST(PathTracer, LightPathsCarryWhatCameraPathsFindThroughMirrorsAndGlass) {
    std::string json = twoLampsAndAGlassBall();
    json.replace(json.rfind("]}"), 2, R"(,
        {"name": "mirror", "type": "sphere", "material": "mirror", "center": [1.2, 0.4, 0.3], "radius": 0.4}],
      "camera": {"position": [0, 3.2, 3.2], "look_at": [0, 0.3, 0], "up": [0, 1, 0], "fov_y_deg": 55,
                 "resolution": [24, 24]}})");
    json.replace(json.find("\"glass\": {"), 0, R"("mirror": {"type": "mirror", "reflectance": 0.9}, )");
    const Scene scene = test::sceneFromJson(json);
    const PatchSet patches = meshScene(scene, {});
    const SceneTracer tracer(scene, patches);
    constexpr int kSpp = 2048;
    PathSettings all, others;
    others.causticsByLight = PhotonSettings{}.maxDepth;
    auto camera = [&](const PathSettings& s) {
        return renderPixelsSampled(
            scene.camera, kSpp, 3, "camera paths",
            [&](const Vec3& o, const Vec3& d, PixelSampler& p) { return pathRadiance(tracer, o, d, p, s); });
    };
    const Image withCaustics = camera(all), without = camera(others);
    Image byCamera(24, 24);
    for (size_t k = 0; k < byCamera.rgb.size(); ++k) byCamera.rgb[k] = withCaustics.rgb[k] - without.rgb[k];
    const Image byLight = lightPathsToEye(tracer, scene.camera, 24 * 24 * kSpp, 3, PhotonSettings{}.maxDepth);
    const Rgb cameraMean = imageMean(byCamera), lightMean = imageMean(byLight);
    std::printf(
        "caustics seen directly, image mean: camera paths %.5f %.5f %.5f, light paths %.5f %.5f %.5f; "
        "the whole image %.5f\n",
        cameraMean[0], cameraMean[1], cameraMean[2], lightMean[0], lightMean[1], lightMean[2],
        imageMean(withCaustics).sum() / 3);
    ASSERT_GT(lightMean.sum(), 0.02 * imageMean(withCaustics).sum());  // a share worth testing
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(cameraMean[c], lightMean[c], 0.05 * lightMean[c]) << "channel " << c;
    // Per 8 x 8 block of pixels: the brightest (the glass ball's caustic, 90% of this light) within
    // 5%, the others with more than 1% of the light within 30% (the camera's estimate of
    // them varies by up to 21% between seeds at these samples).
    double brightest = 0, brightestCamera = 0;
    for (int by = 0; by < 24; by += 8)
        for (int bx = 0; bx < 24; bx += 8) {
            const double a = meanOver(byCamera, bx, by, bx + 8, by + 8).sum(),
                         b = meanOver(byLight, bx, by, bx + 8, by + 8).sum();
            if (b > brightest) brightest = b, brightestCamera = a;
            if (b / 9 > 0.01 * lightMean.sum()) {
                EXPECT_NEAR(a, b, 0.3 * b) << "block " << bx << ", " << by;
            }
        }
    EXPECT_NEAR(brightestCamera, brightest, 0.05 * brightest);
}

// A lamp of more polygons than the closed form sums at every point (a sphere, meshed): its direct
// light by emitter sampling against the sum of the closed form over the patches that face the
// point (on a convex lamp, exactly the ones it sees), at two points of a floor below it.
TEST(DirectLight, AFinelyMeshedLampIsSampledToItsClosedForm) {
    const Scene scene = test::sceneFromJson(R"({"materials": {"white": {"type": "diffuse", "reflectance": 0.5},
                   "lamp": {"type": "diffuse", "reflectance": 0, "emission": 10}},
      "objects": [
        {"name": "floor", "type": "quad", "material": "white",
         "vertices": [[1.5,0,-1.5],[-1.5,0,-1.5],[-1.5,0,1.5],[1.5,0,1.5]]},
        {"name": "bulb", "type": "sphere", "material": "lamp", "center": [0, 1, 0], "radius": 0.2}]})");
    const PatchSet patches = meshScene(scene, {});
    const SceneTracer tracer(scene, patches);
    const DirectLight direct(scene, patches);
    ASSERT_GT(direct.sources(), DirectLight::kMostPolygons) << "the sphere's patches, each a source";
    for (const Vec3& x : {Vec3(0, 0, 0), Vec3(0.8, 0, 0.3)}) {
        const Vec3 n(0, 1, 0);
        double exact = 0;
        for (size_t j = 0; j < patches.size(); ++j)
            if (scene.objects[size_t(patches.object[j])].name == "bulb" &&
                patches.normal[j].dot(x - patches.centroid[j]) > 0)
                exact += pointPolygonFormFactor(x, n, patches.corners[j].data(), patches.cornerCount[j]) * kPi * 10;
        Rng rng(3);
        double sum = 0, sum2 = 0;
        const int calls = 200000;
        for (int k = 0; k < calls; ++k) {
            const double e = direct.irradiance(tracer, x + tracer.epsilon() * n, n, 4, rng)[0];
            sum += e, sum2 += e * e;
        }
        const double mean = sum / calls, sigma = std::sqrt(std::max(0.0, sum2 / calls - mean * mean) / calls);
        std::printf("at (%g, %g, %g): emitter sampling %.5f +- %.5f, closed form over the facing patches %.5f W/m^2\n",
                    x.x(), x.y(), x.z(), mean, sigma, exact);
        EXPECT_NEAR(mean, exact, 4 * sigma + 0.005 * exact);
    }
}

TEST(FinalGather, DarkRoomBehindASharedWallStaysBlack) {
    const Image image = gatherImage(test::sceneFile("two-rooms.json"), 600, 4, 1);
    double maxValue = 0;
    for (float v : image.rgb) maxValue = std::max(maxValue, double(v));
    EXPECT_EQ(maxValue, 0.0);
}

TEST(Determinism, RendersDoNotDependOnTheThreadCountAndSeedsChangeOnlyNoise) {
    const std::string json = test::sceneFile("cornell-glass.json");
    const Scene scene = test::sceneFromJson(json);
    Camera camera = scene.camera;
    camera.width = camera.height = 24;
    const PatchSet patches = meshScene(scene, {});
    const SceneTracer tracer(scene, patches);
    const std::vector<Rgb> flat(patches.size(), Rgb::Constant(1.0));
    PhotonSettings photons;
    photons.photons = 20000;
    setThreadCount(1);
    const Image path1 = renderPath(tracer, camera, 16, 1);
    const Image gather1 = renderSolvedScene(scene, patches, flat, camera, 4, 1, {}, photons);
    setThreadCount(2);
    const Image path2 = renderPath(tracer, camera, 16, 1);
    const Image gather2 = renderSolvedScene(scene, patches, flat, camera, 4, 1, {}, photons);
    setThreadCount(0);
    EXPECT_EQ(path1.rgb, path2.rgb);
    EXPECT_EQ(gather1.rgb, gather2.rgb);
    // Another seed: another draw of the noise, the same picture (its mean within a few percent).
    const Image path3 = renderPath(tracer, camera, 16, 2);
    const Image gather3 = renderSolvedScene(scene, patches, flat, camera, 4, 2, {}, photons);
    EXPECT_NE(path1.rgb, path3.rgb);
    EXPECT_NE(gather1.rgb, gather3.rgb);
    // Paired z-test on the pixels: with independent noise in the two, the mean of their difference
    // is zero within its standard error (the spread of the differences over sqrt(pixels)).
    auto z = [](const Image& a, const Image& b) {
        const size_t n = a.rgb.size() / 3;
        double sum = 0, sum2 = 0;
        for (size_t k = 0; k < n; ++k) {
            const double d = double(a.rgb[3 * k] + a.rgb[3 * k + 1] + a.rgb[3 * k + 2]) -
                             (b.rgb[3 * k] + b.rgb[3 * k + 1] + b.rgb[3 * k + 2]);
            sum += d;
            sum2 += d * d;
        }
        const double mean = sum / double(n), var = (sum2 / double(n) - mean * mean) * double(n) / double(n - 1);
        return mean / std::sqrt(var / double(n));
    };
    const double limit = test::zLimit(test::sidak(1e-4, 2));
    EXPECT_LT(std::abs(z(path3, path1)), limit) << "path tracer, seeds 2 and 1";
    EXPECT_LT(std::abs(z(gather3, gather1)), limit) << "final gather, seeds 2 and 1";
}

TEST(FinalGather, ReadsCornersWhoseMeanIsThePatchsRadiosity) {
    // What a gather ray from afar reads, averaged over where it lands on a patch, must be the patch's
    // radiosity; the displayed corners keep their shape across it (a ramp stays a ramp) but are
    // shifted to that mean. Quads and triangles (whose fourth corner repeats the third).
    const Scene scene = test::sceneFromJson(test::lampOverFloor(false));
    MeshingOptions o;
    o.patchSize = 0.5;
    const PatchSet p = meshScene(scene, o);
    CornerValues corners(p.size());
    std::vector<Rgb> means(p.size());
    for (size_t i = 0; i < p.size(); ++i) {
        for (int k = 0; k < 4; ++k) corners[i][size_t(k)] = Rgb::Constant(1 + p.corners[i][size_t(k)].x());
        means[i] = Rgb::Constant(2 + 0.1 * double(i));
    }
    const CornerValues shifted = meanPreservingCorners(p, corners, means);
    for (size_t i = 0; i < p.size(); ++i) {
        const int n = p.cornerCount[i];
        Rgb mean = Rgb::Zero();
        for (int k = 0; k < n; ++k) mean += shifted[i][size_t(k)] / double(n);
        EXPECT_NEAR(mean[0], means[i][0], 1e-12) << "patch " << i;
        for (int k = 1; k < n; ++k)
            EXPECT_NEAR(shifted[i][size_t(k)][0] - shifted[i][0][0], corners[i][size_t(k)][0] - corners[i][0][0],
                        1e-12);
        // The interpolation's mean over the patch, by a grid of points in its parameters.
        double sum = 0;
        const int g = 40;
        for (int a = 0; a < g; ++a)
            for (int b = 0; b < g; ++b) sum += interpolateAt(p, i, (a + 0.5) / g, (b + 0.5) / g, shifted[i])[0];
        if (!p.isTriangle(i)) {
            EXPECT_NEAR(sum / (g * g), means[i][0], 1e-9) << "patch " << i;
        }
    }
}

TEST(FinalGather, ProvedClearShaftsChangeNoPixelAndSpareRays) {
    // Where a shaft is proved clear the shadow rays would all have arrived: the image is the same,
    // bit for bit, with fewer rays. A false proof would light a penumbra (the blocks' shadows on
    // the floor, the lamp's edge on the walls) and change pixels.
    // The balls of cornell-glass are exact spheres among the occluders.
    for (const char* name : {"cornell-box.json", "cornell-glass.json"}) {
        const std::string json = test::sceneFile(name);
        const Scene scene = test::sceneFromJson(json);
        SolveOptions options;
        options.meshing.targetPatches = 600;
        options.formFactors.method = "rays";
        const SolveResult r = solveScene(scene, options);
        Camera camera = scene.camera;
        camera.width = camera.height = 48;
        Image images[2];
        uint64_t rays[2];
        for (int proofs = 0; proofs < 2; ++proofs) {
            GatherSettings settings;
            settings.clearShafts = proofs == 1;
            const CounterValues before = counterValues();
            const SolvedScene solved(scene, r.patches, r.corners, settings, {}, 1, r.rays, &r.solution.display,
                                     r.indirect);
            images[proofs] = solved.render(camera, 4, 1);
            rays[proofs] = countersSince(before).at("rays.occlusion");
        }
        ASSERT_EQ(images[0].rgb.size(), images[1].rgb.size());
        size_t differ = 0;
        for (size_t k = 0; k < images[0].rgb.size(); ++k) differ += images[0].rgb[k] != images[1].rgb[k];
        EXPECT_EQ(differ, 0u) << name;
        EXPECT_LT(double(rays[1]), 0.7 * double(rays[0]))
            << name << ": " << rays[1] << " shadow rays against " << rays[0];
    }
}

TEST(FinalGather, ReadsNoDisplayedCornerWhereItReadsTheSolvedIndirectLight) {
    // With small sources, the default final gather shades what it sees from the solve's indirect
    // corners and the sources' direct light: the displayed corners (vertex shadow rays, what views
    // and export show) may be the cheapest, the image the same bit for bit. A gather that read them
    // (a gather ray's landing, a point without the solved indirect light) would change pixels:
    // "direct" corners hold the lamp's penumbrae at the vertices, "average" ones blur them.
    // The balls of cornell-glass send the camera's rays on to the room behind them.
    for (const char* name : {"cornell-box.json", "cornell-glass.json"}) {
        const Scene scene = test::sceneFromJson(test::sceneFile(name));
        SolveOptions options;
        options.meshing.targetPatches = 600;
        options.formFactors.method = "rays";
        const SolveResult r = solveScene(scene, options);
        options.forSolvedIndirectGather = true;
        const SolveResult cheap = solveScene(scene, options);
        const CornerValues average = interpolateCorners(r.patches, r.solution.display);
        ASSERT_EQ(cheap.corners.size(), average.size()) << name;
        size_t cornersDiffer = 0, differ = 0;
        for (size_t i = 0; i < average.size(); ++i)
            for (size_t k = 0; k < 4; ++k) {
                EXPECT_EQ((cheap.corners[i][k] - average[i][k]).abs().maxCoeff(), 0.0) << name << " patch " << i;
                cornersDiffer += (r.corners[i][k] - average[i][k]).abs().maxCoeff() > 1e-6 * average[i][k].maxCoeff();
            }
        ASSERT_GT(cornersDiffer, 100u) << name << ": the direct corners are no different from the averaged ones";
        Camera camera = scene.camera;
        camera.width = camera.height = 48;
        Image images[2];
        for (int k = 0; k < 2; ++k) {
            const SolvedScene solved(scene, r.patches, k == 0 ? r.corners : average, GatherSettings{}, {}, 1, r.rays,
                                     &r.solution.display, r.indirect);
            images[k] = solved.render(camera, 4, 1);
        }
        for (size_t k = 0; k < images[0].rgb.size(); ++k) differ += images[0].rgb[k] != images[1].rgb[k];
        EXPECT_EQ(differ, 0u) << name;
    }
}

namespace {

// OpenGL's clip space for an eye at `eye` looking at `at` (up +y), as the viewer's projection.
Eigen::Matrix4d glViewProjection(const Vec3& eye, const Vec3& at, double fovDeg, double aspect) {
    const Vec3 f = (at - eye).normalized(), s = f.cross(Vec3(0, 1, 0)).normalized(), u = s.cross(f);
    Eigen::Matrix4d view = Eigen::Matrix4d::Identity();
    view.row(0) << s.x(), s.y(), s.z(), -s.dot(eye);
    view.row(1) << u.x(), u.y(), u.z(), -u.dot(eye);
    view.row(2) << -f.x(), -f.y(), -f.z(), f.dot(eye);
    const double near = 0.01, far = 100, t = 1 / std::tan(fovDeg * kPi / 360);
    Eigen::Matrix4d projection = Eigen::Matrix4d::Zero();
    projection(0, 0) = t / aspect, projection(1, 1) = t;
    projection(2, 2) = (far + near) / (near - far), projection(2, 3) = 2 * far * near / (near - far);
    projection(3, 2) = -1;
    return projection * view;
}

using Polygon = std::vector<Vec3>;

Polygon quad(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) { return {a, b, c, d}; }

bool hiddenBehind(const std::vector<Polygon>& occluders, const Eigen::AlignedBox3d& box, const Eigen::Matrix4d& vp,
                  int w, int h, bool frontOnly = false) {
    OcclusionBuffer buffer(vp, w, h);
    for (const Polygon& p : occluders) buffer.occlude(p, frontOnly);
    return buffer.hidden(box);
}

}  // namespace

// The viewer's occlusion culling (render/occlusion.h). A wall 5 m ahead hides a box behind it, also
// when the wall is two quads meeting at a seam, or a wall and a floor meeting at a crease (every
// pixel centre on the join is covered by one or the other); it hides no box in front of it, none
// that shows past its edge, none that reaches in front of the near plane, none within a thousandth
// of its depth behind it; seen from behind it hides nothing where back faces are culled.
TEST(Occlusion, AWallHidesWhatIsBehindItAndNothingElse) {
    const Eigen::Matrix4d vp = glViewProjection(Vec3(0, 0, 0), Vec3(0, 0, -1), 60, 4.0 / 3);
    const int w = 160, h = 120;
    const Polygon wall = quad(Vec3(-10, -10, -5), Vec3(10, -10, -5), Vec3(10, 10, -5), Vec3(-10, 10, -5));
    const Eigen::AlignedBox3d behind(Vec3(-1, -1, -8), Vec3(1, 1, -7));
    EXPECT_TRUE(hiddenBehind({wall}, behind, vp, w, h));
    EXPECT_FALSE(hiddenBehind({}, behind, vp, w, h));
    // Its corners run counter-clockwise seen from the eye: a front face. Reversed, it is a back
    // face, which hides nothing where back faces are culled.
    EXPECT_TRUE(hiddenBehind({wall}, behind, vp, w, h, true));
    const Polygon back(wall.rbegin(), wall.rend());
    EXPECT_TRUE(hiddenBehind({back}, behind, vp, w, h));
    EXPECT_FALSE(hiddenBehind({back}, behind, vp, w, h, true));
    // A box a hair behind the wall (a poster's width) is not taken as hidden: OpenGL's depth test
    // may not tell them apart.
    EXPECT_FALSE(hiddenBehind({wall}, Eigen::AlignedBox3d(Vec3(-1, -1, -5.002), Vec3(1, 1, -5.001)), vp, w, h));
    EXPECT_FALSE(hiddenBehind({wall}, Eigen::AlignedBox3d(Vec3(-1, -1, -3), Vec3(1, 1, -2)), vp, w, h));
    // Touching the wall from behind: its nearest point is on the wall, not behind it.
    EXPECT_FALSE(hiddenBehind({wall}, Eigen::AlignedBox3d(Vec3(-1, -1, -8), Vec3(1, 1, -5)), vp, w, h));
    // Past a wall's edge as seen from the eye (x / -z up to 3 / 7 = 0.43 > 2 / 5), though behind its plane.
    const Polygon narrow = quad(Vec3(-10, -10, -5), Vec3(2, -10, -5), Vec3(2, 10, -5), Vec3(-10, 10, -5));
    EXPECT_TRUE(hiddenBehind({narrow}, Eigen::AlignedBox3d(Vec3(0, -1, -8), Vec3(1, 1, -7)), vp, w, h));
    EXPECT_FALSE(hiddenBehind({narrow}, Eigen::AlignedBox3d(Vec3(2, -1, -8), Vec3(3, 1, -7)), vp, w, h));
    EXPECT_FALSE(hiddenBehind({wall}, Eigen::AlignedBox3d(Vec3(-1, -1, -8), Vec3(1, 1, 1)), vp, w, h));
    // The wall in two halves, meeting at x = 0.3 (not on a pixel's edge).
    const std::vector<Polygon> halves{
        quad(Vec3(-10, -10, -5), Vec3(0.3, -10, -5), Vec3(0.3, 10, -5), Vec3(-10, 10, -5)),
        quad(Vec3(0.3, -10, -5), Vec3(10, -10, -5), Vec3(10, 10, -5), Vec3(0.3, 10, -5))};
    EXPECT_TRUE(hiddenBehind(halves, behind, vp, w, h));
    // A corner seen from inside: a floor at y = -1 up to the wall at z = -5, the box behind the crease.
    const Polygon floor = quad(Vec3(-10, -1, 0), Vec3(10, -1, 0), Vec3(10, -1, -5), Vec3(-10, -1, -5));
    const Polygon upper = quad(Vec3(-10, -1, -5), Vec3(10, -1, -5), Vec3(10, 10, -5), Vec3(-10, 10, -5));
    EXPECT_TRUE(hiddenBehind({floor, upper}, Eigen::AlignedBox3d(Vec3(-1, -3, -8), Vec3(1, 0, -6)), vp, w, h));
}

// Conservative against rays: random walls (quads) and boxes seen from random eyes; wherever a box is
// found hidden, the ray through every pixel centre that meets the box meets a wall nearer (depth
// along the view axis) than the box's nearest point on it. Fails on any step that covers a centre
// no wall covers, or that takes a wall nearer than it is (which would cull what is in view).
TEST(Occlusion, AHiddenBoxIsHiddenAtEveryPixelCentre) {
    Rng rng(11);
    const int w = 40, h = 30;
    int hidden = 0;
    for (int trial = 0; trial < 300; ++trial) {
        const Vec3 eye(rng.uniform() * 4 - 2, rng.uniform() * 4 - 2, 4);
        const Vec3 at(rng.uniform() - 0.5, rng.uniform() - 0.5, 0);
        const Eigen::Matrix4d vp = glViewProjection(eye, at, 50 + 40 * rng.uniform(), double(w) / h);
        std::vector<Polygon> walls;
        for (int k = 0; k < 4; ++k) {
            // A planar quad: a random centre and two random edge vectors (a parallelogram).
            const Vec3 c(rng.uniform() * 4 - 2, rng.uniform() * 4 - 2, rng.uniform() * 2 - 1);
            const Vec3 a = Vec3(rng.uniform() - 0.5, rng.uniform() - 0.5, rng.uniform() - 0.5) * 6;
            const Vec3 b = Vec3(rng.uniform() - 0.5, rng.uniform() - 0.5, rng.uniform() - 0.5) * 6;
            walls.push_back(quad(c - a - b, c + a - b, c + a + b, c - a + b));
        }
        Vec3 lo(rng.uniform() * 4 - 2, rng.uniform() * 4 - 2, -3 + 2 * rng.uniform());
        const Eigen::AlignedBox3d box(lo, lo + Vec3(rng.uniform(), rng.uniform(), rng.uniform()) * 0.8);
        if (!hiddenBehind(walls, box, vp, w, h)) continue;
        ++hidden;
        // Every pixel centre's ray from the eye, by inverting the clip-space map.
        const Eigen::Matrix4d inverse = vp.inverse();
        const Vec3 axis = (at - eye).normalized();
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const double nx = (x + 0.5) / w * 2 - 1, ny = (y + 0.5) / h * 2 - 1;
                const Eigen::Vector4d p = inverse * Eigen::Vector4d(nx, ny, 0, 1);
                const Vec3 dir = (p.head<3>() / p.w() - eye).normalized();
                // The box along the ray (slabs), its entry depth.
                double t0 = 0, t1 = HUGE_VAL;
                for (int c = 0; c < 3; ++c) {
                    const double ta = (box.min()[c] - eye[c]) / dir[c], tb = (box.max()[c] - eye[c]) / dir[c];
                    t0 = std::max(t0, std::min(ta, tb)), t1 = std::min(t1, std::max(ta, tb));
                }
                if (!(t0 <= t1)) continue;
                const double boxDepth = t0 * dir.dot(axis);
                bool covered = false;
                for (const Polygon& q : walls) {
                    const Vec3 n = (q[1] - q[0]).cross(q[3] - q[0]);
                    const double t = (q[0] - eye).dot(n) / dir.dot(n);
                    if (!(t > 0)) continue;
                    const Vec3 hit = eye + t * dir;
                    bool inside = true;
                    for (size_t k = 0; k < 4; ++k)
                        inside = inside && (q[(k + 1) % 4] - q[k]).cross(hit - q[k]).dot(n) >= 0;
                    covered = covered || (inside && t * dir.dot(axis) < boxDepth);
                }
                EXPECT_TRUE(covered) << "trial " << trial << " pixel " << x << ", " << y;
            }
    }
    EXPECT_GT(hidden, 10);  // the check was made
}

// The visibility buffer finds what Embree's rays find (the Exact view: a ball's exact sphere, not its
// facets; triangle patches as Embree's degenerate quads), at random points of the image, from cameras outside the box,
// inside it, half a millimetre above the floor, and beside a ball, whose patches cross the plane of the eye: the same
// patch or sphere, the same distance and the same (u, v) (Embree's split of a quad into two triangles). Fails if a
// triangle of the split took the other's (u, v), if patches reaching behind the eye were dropped or drawn mirrored, if
// the depth test kept the farther, if the balls' facets hid their spheres, or if seams between patches let points
// through.
TEST(VisibilityBuffer, FindsWhatEmbreeFindsAtEverySample) {
    // The third: cornell-glass with its mirror ball white, meshed (triangles at its poles) and drawn
    // as patches.
    std::string white = test::sceneFile("cornell-glass.json");
    white.replace(white.find(R"("material": "chrome")"), 20, R"("material": "white" )");
    const std::vector<std::pair<std::string, std::string>> scenes{
        {"cornell-glass", test::sceneFile("cornell-glass.json")},
        {"cornell-box", test::sceneFile("cornell-box.json")},
        {"cornell-glass with a white ball", white}};
    for (const auto& [file, json] : scenes) {
        const Scene scene = test::sceneFromJson(json);
        const PatchSet patches = meshScene(scene, MeshingOptions{});
        const std::shared_ptr<const RayScene> rays = buildRayScene(scene, patches);
        size_t triangles = 0;
        for (size_t i = 0; i < patches.size(); ++i) triangles += patches.isTriangle(i) && !rays->onExactSphere(i);
        if (json == white) {
            EXPECT_GT(triangles, 0u) << file;
        }
        const Eigen::AlignedBox3d box = patchBounds(patches);
        const Vec3 centre = Vec3(box.center()), size = Vec3(box.sizes());
        std::vector<Camera> cameras{scene.camera};
        Camera c = scene.camera;
        c.position = centre + 0.2 * size.cwiseProduct(Vec3(0.5, 0.25, 1));  // inside the box
        c.lookAt = c.position + Vec3(0.3, -0.5, 1);
        cameras.push_back(c);
        // Half a millimetre above the floor, looking down past its feet: patches across the eye's plane.
        c.position = Vec3(centre.x(), box.min().y() + 5e-4, centre.z());
        c.lookAt = c.position + Vec3(0.2, -0.6, 1);
        c.fovYDeg = 100;
        cameras.push_back(c);
        c.fovYDeg = scene.camera.fovYDeg;
        c.position = centre + size.cwiseProduct(Vec3(0.9, 0.8, -1.1));  // outside, behind and above: walls before walls
        c.lookAt = centre;
        cameras.push_back(c);
        if (rays->sphereCount() > 0) {
            const RaySphere ball = rays->spheres()[0];
            c.position = ball.center + Vec3(0, 0, 1.2 * ball.radius);  // beside a ball, looking past it
            c.lookAt = ball.center + Vec3(0.5 * ball.radius, 0, 0);
            c.fovYDeg = 100;
            cameras.push_back(c);
        }
        Rng rng(5);
        for (size_t k = 0; k < cameras.size(); ++k) {
            Camera cam = cameras[k];
            cam.width = 48, cam.height = 36;
            std::vector<CameraSample> samples;
            for (int y = 0; y < cam.height; ++y)
                for (int x = 0; x < cam.width; ++x)
                    for (int s = 0; s < 3; ++s) samples.push_back({x, y, Vec2(x + rng.uniform(), y + rng.uniform())});
            const std::vector<BufferHit> hits = VisibilityBuffer(patches, *rays, cam).firstHits(samples);
            const PinholeCamera::ImagePlane p = PinholeCamera(cam).imagePlane();
            int differ = 0, found = 0;
            for (size_t i = 0; i < samples.size(); ++i) {
                const Vec3 D = p.corner + samples[i].at.x() * p.perX + samples[i].at.y() * p.perY;
                const Hit ray = rays->intersect(cam.position, D.normalized(), 0, 1e30, RayView::Exact);
                const BufferHit& h = hits[i];
                found += ray.found();
                if (ray.patch != h.patch || ray.sphere != h.sphere) {
                    ++differ;
                    continue;
                }
                if (!ray.found()) continue;
                EXPECT_NEAR(h.t * D.norm(), ray.t, 1e-5 * ray.t + 1e-6) << file << " camera " << k << " sample " << i;
                if (ray.patch >= 0) {
                    EXPECT_NEAR(h.u, ray.u, 1e-4) << file << " camera " << k << " sample " << i;
                    EXPECT_NEAR(h.v, ray.v, 1e-4) << file << " camera " << k << " sample " << i;
                }
            }
            EXPECT_GT(found, int(samples.size()) / 2) << file << " camera " << k;
            EXPECT_LE(differ, int(samples.size()) / 1000) << file << " camera " << k;
        }
    }
}
