// The final-gather view and the radiosity view against the project's unbiased path tracer on the
// same scene, camera and geometry (suites named *Slow: they run in the Release build, not under the
// sanitizers). The measure is the project's: pooled L1 after a 5x5 box blur over the image, and the
// mean radiance of each named region (render/regions.h: each wall, the ceiling, the floor, each block
// face and the blocks, the caustic, the two balls) within 3%, the radiosity view too (it shows the
// balls through their mirror and glass). A failing test leaves the rendered, reference and
// difference images (EXR and PNG) in the build tree and prints their paths.
//   Cornell box: also the same 3% along the blocks' contact with the floor (no leaks, no blotches);
//   cornell-glass: also the caustic's power against a backward (eye-side) estimate of the same light
//   paths, and against the light the glass ball intercepts.
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "core/optics.h"
#include "fixtures.h"
#include "io/image_io.h"
#include "render/camera.h"
#include "render/final_gather.h"
#include "render/image_metrics.h"
#include "render/path_tracer.h"
#include "render/photon_map.h"
#include "render/radiosity_view.h"
#include "render/regions.h"

using namespace penumbra;

namespace {

struct Pair {
    Scene scene;
    Camera camera;
    SolveResult solved;
    Image gather, radiosity, path;
    std::unique_ptr<SceneTracer> tracer;  // over the solved patches, for pixel labels
};

// Solves the scene with the defaults, renders it three ways at `size` x `size`: the final gather
// (default settings, reading the solve's indirect light, but `gatherSpp`), the radiosity view (its default 4 spp) and
// the path tracer.
std::unique_ptr<Pair> renderAll(const std::string& file, int size, int gatherSpp, int pathSpp) {
    auto p = std::make_unique<Pair>();
    const std::string json = test::sceneFile(file);
    p->scene = test::sceneFromJson(json, file);
    p->camera = p->scene.camera;
    p->camera.width = p->camera.height = size;
    SolveOptions options;
    p->solved = solveScene(p->scene, options);
    // As `render` does by default: the solve's indirect light read where the camera looks.
    if (p->solved.indirect.empty()) ADD_FAILURE() << file << ": the solve holds no indirect light to read";
    const SolvedScene solved(p->scene, p->solved.patches, p->solved.corners, {}, {}, 1, p->solved.rays,
                             &p->solved.solution.display, p->solved.indirect);
    p->gather = solved.render(p->camera, gatherSpp, 1);
    p->radiosity =
        renderRadiosityView(p->scene, p->camera, p->solved.patches, p->solved.rays, p->solved.corners, {4, 1});
    p->tracer = std::make_unique<SceneTracer>(p->scene, p->solved.patches, p->solved.rays);
    p->path = renderPath(*p->tracer, p->camera, pathSpp, 7);
    return p;
}

// Writes image, reference and their absolute difference (EXR and PNG) beside the test binary when
// the test has failed so far, and says where.
void keepImagesIfFailed(const std::string& name, const Image& image, const Image& reference) {
    if (!::testing::Test::HasFailure()) return;
    Image diff(image.width, image.height);
    for (size_t k = 0; k < diff.rgb.size(); ++k) diff.rgb[k] = std::abs(image.rgb[k] - reference.rgb[k]);
    const std::string dir = std::string(PENUMBRA_TEST_OUTPUT_DIR) + "/failed-images";
    std::filesystem::create_directories(dir);
    for (const auto& [suffix, im] :
         {std::pair<const char*, const Image*>{"rendered", &image}, {"reference", &reference}, {"difference", &diff}}) {
        const std::string path = cat(dir, "/", name, "-", suffix, ".exr");
        writeLinearImage(*im, path);
        writePreviewPng(*im, previewPathFor(path));
        std::printf("kept %s and %s\n", path.c_str(), previewPathFor(path).c_str());
    }
}

// The whole image within `imageL1` (pooled L1 after the blur) and every region of at least
// `minPixels` pixels within `regionTolerance` of the reference's mean, except those `skip` names.
void expectRegions(const std::string& name, const Image& image, const Image& reference, const ImageRegions& regions,
                   double imageL1, const std::vector<std::string>& skip = {}, double regionTolerance = 0.03,
                   int minPixels = 40) {
    const ImageError e = compareBlurred(image, reference);
    std::printf("%s: pooled L1 after 5x5 blur %.4f (per-pixel relative error %.4f), brightness ratio %.4f\n",
                name.c_str(), e.pooledL1, e.meanRelative, e.meanRatio);
    EXPECT_LT(e.pooledL1, imageL1) << name << ": whole image";
    int tested = 0;
    for (const RegionError& r : compareRegions(image, reference, regions)) {
        const bool skipped = std::find(skip.begin(), skip.end(), r.name) != skip.end() || r.pixels < minPixels;
        std::printf("  %-16s %5d pixels: mean ratio %.4f, pooled L1 %.4f%s\n", r.name.c_str(), r.pixels, r.ratio,
                    r.pooledL1, skipped ? " (not tested)" : "");
        if (skipped) continue;
        EXPECT_NEAR(r.ratio, 1.0, regionTolerance) << name << ": region " << r.name << " (" << r.pixels << " pixels)";
        ++tested;
    }
    EXPECT_GT(tested, 5) << name;
    keepImagesIfFailed(name, image, reference);
}

// Mean relative error (the compareImages measure) over the pixels where `keep` is true.
double maskedRelativeError(const Image& a, const Image& ref, const std::vector<char>& keep) {
    double refSum = 0;
    for (float v : ref.rgb) refSum += v;
    const double floor = 0.01 * refSum / double(ref.rgb.size());
    double rel = 0;
    size_t count = 0;
    for (size_t k = 0; k < keep.size(); ++k) {
        if (!keep[k]) continue;
        for (size_t c = 0; c < 3; ++c)
            rel += std::abs(a.rgb[3 * k + c] - ref.rgb[3 * k + c]) / (ref.rgb[3 * k + c] + floor);
        count += 3;
    }
    return count ? rel / double(count) : 0;
}

double segmentDistance(const Vec3& p, const Vec3& a, const Vec3& b) {
    const Vec3 ab = b - a;
    const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    return (p - (a + t * ab)).norm();
}

}  // namespace

TEST(ReferenceSlow, CornellBoxFinalGatherMatchesThePathTracer) {
    const auto p = renderAll("cornell-box.json", 64, 64, 8192);
    const ImageRegions regions = objectRegions(*p->tracer, p->camera);
    ASSERT_TRUE(regions.find("ceiling") && regions.find("floor") && regions.find("blocks"));
    // Every object seen, however few pixels it covers (each wall and block face), within 3%.
    expectRegions("cornell-box-final-gather", p->gather, p->path, regions, 0.015, {}, 0.03, 1);
    // The radiosity view's whole image is not held to a bound: at its 4 samples per pixel the lamp's
    // edges alias (measured 2.9% and 4.0% pooled L1 with two pixel streams); its regions are.
    expectRegions("cornell-box-radiosity-view", p->radiosity, p->path, regions, 1.0);

    const std::vector<SurfaceHit>& hits = regions.hits;
    const int w = p->camera.width;
    // Along the blocks' contact with the floor: floor points within 30 mm of a block's base, and
    // block faces below 30 mm, compared after the same blur.
    std::vector<std::pair<Vec3, Vec3>> bases;
    for (const SceneObject& o : p->scene.objects) {
        if (o.name.find("block") == std::string::npos || o.vertices.size() != 4) continue;
        std::vector<Vec3> low;
        for (const Vec3& v : o.vertices)
            if (std::abs(v.y()) < 1e-9) low.push_back(v);
        if (low.size() == 2) bases.emplace_back(low[0], low[1]);
    }
    ASSERT_EQ(bases.size(), 8u);
    std::vector<char> contact(hits.size(), 0);
    int count = 0;
    for (size_t k = 0; k < hits.size(); ++k) {
        if (!hits[k].found) continue;
        const std::string& name = p->scene.objects[size_t(hits[k].object)].name;
        double d = 1e9;
        for (const auto& [a, b] : bases) d = std::min(d, segmentDistance(hits[k].point, a, b));
        contact[k] =
            (name == "floor" || name.find("block") != std::string::npos) && d < 0.03 && hits[k].point.y() < 0.03;
        count += contact[k];
    }
    ASSERT_GT(count, 50);
    const double contactError = maskedRelativeError(boxBlur(p->gather, 2), boxBlur(p->path, 2), contact);
    Rgb cg = Rgb::Zero(), cp = Rgb::Zero();
    for (size_t k = 0; k < contact.size(); ++k)
        if (contact[k]) {
            cg += p->gather.at(int(k) % w, int(k) / w);
            cp += p->path.at(int(k) % w, int(k) / w);
        }
    std::printf("contact region (%d pixels): blurred mean relative error %.4f, brightness ratio %.4f\n", count,
                contactError, cg.sum() / cp.sum());
    EXPECT_LT(contactError, 0.03);
}

TEST(ReferenceSlow, CornellGlassCausticAndMirrorBall) {
    // The final gather at 512 samples per pixel: the lamp's image in the mirror ball covers parts of
    // three pixels and carries two thirds of the ring's light below, and at 64 (8 x 8 strata) their
    // coverage alone moved the ring's mean by 3.5% (one standard deviation over six seeds, 0.954 to
    // 1.058 on the graded mesh; 1.000 at 8192).
    const auto p = renderAll("cornell-glass.json", 64, 512, 8192);
    ImageRegions regions = objectRegions(*p->tracer, p->camera);
    regions.add("caustic", causticMask(*p->tracer, PhotonMap(*p->tracer, {}), regions));
    ASSERT_TRUE(regions.find("ceiling") && regions.find("mirror_ball") && regions.find("glass_ball"));
    ASSERT_GE(std::count(regions.find("caustic")->begin(), regions.find("caustic")->end(), 1), 40)
        << "a caustic in view";
    expectRegions("cornell-glass-final-gather", p->gather, p->path, regions, 0.015);
    // The radiosity view shows the balls by following their mirror and glass to the solved room
    // (issue 18): the whole image within 3% (measured 1.32%), every region within 3% (measured: mirror
    // ball 1.015, glass ball 0.995, caustic 1.004; before, the balls were black and the image 11.7-16%
    // off). Its floor read 3.4-4.0% bright on a uniform mesh (the contact at the balls' feet, coarser
    // than its light); the default mesh, graded towards contacts, reads 1.4%.
    expectRegions("cornell-glass-radiosity-view", p->radiosity, p->path, regions, 0.03);

    // The mirror ball: the ring between half and 0.85 of its image radius (its centre reflects the
    // open front, which is black) shows the room as the path tracer sees it.
    const SceneObject* ball = nullptr;
    const SceneObject* glass = nullptr;
    for (const SceneObject& o : p->scene.objects) {
        if (o.name == "mirror_ball") ball = &o;
        if (o.name == "glass_ball") glass = &o;
    }
    ASSERT_TRUE(ball && glass);
    const PinholeCamera cam(p->camera);
    const Vec3 centre = ball->toWorld * ball->center;
    const double radius = ball->radius * p->scene.unitScale;
    std::vector<char> ring(size_t(p->camera.width * p->camera.height), 0);
    for (int y = 0; y < p->camera.height; ++y)
        for (int x = 0; x < p->camera.width; ++x) {
            const Vec3 d = cam.direction(x + 0.5, y + 0.5);
            const Vec3 oc = centre - cam.origin();
            const double along = oc.dot(d), off = std::sqrt(std::max(0.0, oc.squaredNorm() - along * along));
            ring[size_t(y * p->camera.width + x)] = off > 0.5 * radius && off < 0.85 * radius;
        }
    Rgb g = Rgb::Zero(), r = Rgb::Zero();
    for (size_t k = 0; k < ring.size(); ++k)
        if (ring[k]) {
            g += p->gather.at(int(k) % p->camera.width, int(k) / p->camera.width);
            r += p->path.at(int(k) % p->camera.width, int(k) / p->camera.width);
        }
    EXPECT_NEAR(g.sum() / r.sum(), 1.0, 0.05) << "mirror ball";
    EXPECT_GT(g.sum(), 0.2 * meanOver(p->gather, 0, 0, p->camera.width, p->camera.height).sum() *
                           double(std::count(ring.begin(), ring.end(), 1)))
        << "the mirror ball reflects the room";

    // The caustic on the floor under the glass ball. Photon map (light side) against a backward
    // estimate of the same paths (floor -> glass -> lamp) on a grid of floor points, in W.
    const PhotonMap photons(*p->tracer, {});
    const Vec3 g0 = glass->toWorld * glass->center;
    const double R = glass->radius * p->scene.unitScale, cell = 0.01;
    // The lamp, as a grid of small squares: its light on the ball and on the bare floor.
    const SceneObject* lamp = nullptr;
    for (const SceneObject& o : p->scene.objects)
        if (o.name == "light") lamp = &o;
    ASSERT_TRUE(lamp);
    const Rgb Le = p->scene.materialOf(*lamp).emission;
    const Vec3 l0 = lamp->vertices[0], lu = lamp->vertices[1] - l0, lv = lamp->vertices[3] - l0;
    const Vec3 ln = lu.cross(lv).normalized();
    const int lampGrid = 40;
    const double dA = lu.cross(lv).norm() / (lampGrid * lampGrid);
    auto overLamp = [&](const auto& f) {
        double sum = 0;
        for (int a = 0; a < lampGrid; ++a)
            for (int b = 0; b < lampGrid; ++b) sum += f(l0 + (a + 0.5) / lampGrid * lu + (b + 0.5) / lampGrid * lv);
        return sum * dA;
    };
    // Power the ball intercepts: a lamp element sends L_e dA pi sin^2(alpha) cos(theta) into the
    // cone of half-angle alpha around the ball (exact for a cone inside its hemisphere).
    const double intercepted = overLamp([&](const Vec3& q) {
        const Vec3 d = g0 - q;
        return Le.sum() * kPi * R * R / d.squaredNorm() * ln.dot(d.normalized());
    });
    auto bareFloor = [&](const Vec3& x) {
        return overLamp([&](const Vec3& q) {
            const Vec3 d = x - q;
            return Le.sum() * ln.dot(d.normalized()) * d.normalized().y() * -1.0 / d.squaredNorm();
        });
    };
    double photonPower = 0, backwardPower = 0, peak = 0, peakBare = 0, ring2 = 0;
    int ringCount = 0;
    for (int i = -15; i <= 15; ++i)
        for (int j = -15; j <= 15; ++j) {
            const Vec3 x(g0.x() + i * cell, 0, g0.z() + j * cell);
            const Vec3 up(0, 1, 0);
            const double ep = photons.irradiance(x, up).sum();
            Rng rng(mixSeed(11, uint64_t(i + 100), uint64_t(j + 100)));
            double eb = 0;
            const int rays = 2000;
            for (int k = 0; k < rays; ++k) {
                const Vec3 d = cosineDirection(up, rng);
                const SpecularWalk w =
                    walkSpecular(*p->tracer, p->tracer->trace(x + p->tracer->epsilon() * up, d), d, rng, 32);
                if (w.end == WalkEnd::Diffuse && w.bounces > 0 && w.hit.frontFacing(w.dir))
                    eb += (w.throughput * w.hit.material->emission).sum();
            }
            eb *= kPi / rays;
            photonPower += ep * cell * cell;
            backwardPower += eb * cell * cell;
            const double rr = std::hypot(i * cell, j * cell);
            if (rr > 1.2 * R && rr < 1.5 * R) {
                ring2 += eb;
                ++ringCount;
            }
            if (eb > peak) {
                peak = eb;
                peakBare = bareFloor(x);
            }
        }
    std::printf(
        "caustic power within 15 cm of the glass ball's foot: photon map %.5f W, backward %.5f W, the ball "
        "intercepts %.5f W; peak %.3f W/m^2 (the bare floor there gets %.3f directly), %.3f around it\n",
        photonPower, backwardPower, intercepted, peak, peakBare, ring2 / ringCount);
    EXPECT_NEAR(photonPower / backwardPower, 1.0, 0.10);
    // Two glass-air interfaces of index 1.5 pass 80-90% of the intercepted light (Fresnel averaged
    // over the ball's disc); the mirror ball adds a little of its own caustic to the window.
    EXPECT_GT(photonPower, 0.75 * intercepted);
    EXPECT_LT(photonPower, 1.05 * intercepted);
    // Focused: the spot is brighter than the lamp alone makes the bare floor, many times over.
    EXPECT_GT(peak, 5 * peakBare) << "the caustic concentrates the lamp's light";
    EXPECT_GT(peak, 20 * ring2 / ringCount) << "the caustic stands out from its surroundings";
}
