// Statistical tests of every sampler, as pbrt-v4 tests its own: the directions, points, branches and
// photons each routine draws are binned, and the counts held against the counts the distribution it
// claims to draw from expects there, by Pearson's chi-square at significance 1e-4 per suite with a
// Sidak correction over the repeated tests within it. A sampler off by a few percent anywhere in its
// domain fails; the sample counts make each test a fraction of a second.
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "core/optics.h"
#include "fixtures.h"
#include "render/photon_map.h"
#include "solver/tracer.h"
#include "statistics.h"

using namespace penumbra;

namespace {

constexpr double kAlpha = 1e-4;

void expectChiSquare(const std::vector<double>& observed, const std::vector<double>& expected, double alpha,
                     const std::string& what) {
    const test::ChiSquare c = test::chiSquareTest(observed, expected);
    EXPECT_GT(c.pValue, alpha) << what << ": chi-square " << c.statistic << " with " << c.degreesOfFreedom
                               << " degrees of freedom";
}

// A frame of our own around n (not the sampler's), to measure the azimuth in.
void frameAround(const Vec3& n, Vec3& t, Vec3& b) {
    const Vec3 a = std::abs(n.x()) < 0.6 ? Vec3::UnitX() : Vec3::UnitY();
    t = (a - a.dot(n) * n).normalized();
    b = n.cross(t);
}

}  // namespace

TEST(Sampling, CosineHemisphereIsCosineDistributedAboutAnyNormal) {
    // For pdf cos(theta) / pi, sin^2(theta) and the azimuth are independent and uniform: a 10 x 20
    // grid over them has equal expected counts. Normals include both poles and the branch point of
    // the basis (n.z near -1).
    const std::vector<Vec3> normals{Vec3::UnitZ(),
                                    -Vec3::UnitZ(),
                                    Vec3::UnitX(),
                                    Vec3(1, 2, 3).normalized(),
                                    Vec3(1e-5, 0, -1).normalized(),
                                    Vec3(-0.3, 0.9, -0.1).normalized()};
    const int thetaBins = 10, phiBins = 20, samples = 200000;
    Rng rng(3);
    for (const Vec3& n : normals) {
        Vec3 t, b;
        frameAround(n, t, b);
        std::vector<double> observed(size_t(thetaBins * phiBins), 0);
        int below = 0;
        for (int s = 0; s < samples; ++s) {
            const Vec3 d = cosineDirection(n, rng);
            ASSERT_NEAR(d.norm(), 1, 1e-12);
            const double c = d.dot(n);
            if (c < 0) ++below;
            const double sin2 = std::clamp(1 - c * c, 0.0, 1.0 - 1e-15);
            double phi = std::atan2(d.dot(b), d.dot(t));
            if (phi < 0) phi += 2 * kPi;
            const int i = std::min(thetaBins - 1, int(sin2 * thetaBins)),
                      j = std::min(phiBins - 1, int(phi / (2 * kPi) * phiBins));
            observed[size_t(i * phiBins + j)] += 1;
        }
        EXPECT_EQ(below, 0) << "directions below the surface";
        const std::vector<double> expected(observed.size(), double(samples) / double(observed.size()));
        expectChiSquare(observed, expected, test::sidak(kAlpha, int(normals.size())),
                        cat("normal (", n.transpose(), ")"));
    }
}

TEST(Sampling, EmittersArePickedByPowerAndUniformlyOverTheirArea) {
    // Three lamps of different sizes and radiance (summed over channels 3, 7 and 1.5), and a wall
    // that does not emit. A lamp is chosen with probability A L / sum(A L), a point on it uniformly:
    // a 4 x 4 grid over each lamp expects A L / sum(A L) / 16 of the samples in each cell.
    const std::string json = R"({"materials": {
          "a": {"type": "diffuse", "reflectance": 0.5, "emission": [1, 1, 1]},
          "b": {"type": "diffuse", "reflectance": 0.5, "emission": [4, 2, 1]},
          "c": {"type": "diffuse", "reflectance": 0.5, "emission": [0, 0, 1.5]},
          "wall": {"type": "diffuse", "reflectance": 0.5}},
      "objects": [
        {"name": "a", "type": "quad", "material": "a", "vertices": [[0,2,0],[0,2,1],[1,2,1],[1,2,0]]},
        {"name": "b", "type": "quad", "material": "b", "vertices": [[2,2,0],[2,2,0.5],[2.25,2,0.5],[2.25,2,0]]},
        {"name": "c", "type": "quad", "material": "c", "vertices": [[-3,2,-1],[-3,2,1],[-1,2,1],[-1,2,-1]]},
        {"name": "wall", "type": "quad", "material": "wall", "vertices": [[0,0,0],[1,0,0],[1,0,1],[0,0,1]]}]})";
    const Scene scene = test::sceneFromJson(json);
    MeshingOptions meshing;
    meshing.targetPatches = 200;  // many patches per lamp: the pick goes through the patch table
    const PatchSet patches = meshScene(scene, meshing);
    const SceneTracer tracer(scene, patches);
    struct Box {
        double x0, x1, z0, z1, power;
    };
    const std::vector<Box> lamps{{0, 1, 0, 1, 1.0 * 3}, {2, 2.25, 0, 0.5, 0.125 * 7}, {-3, -1, -1, 1, 4.0 * 1.5}};
    double total = 0;
    for (const Box& l : lamps) total += l.power;
    const int samples = 300000, grid = 4;
    std::vector<double> observed(lamps.size() * grid * grid + 1, 0), expected(observed.size(), 0);
    Rng rng(5);
    for (int s = 0; s < samples; ++s) {
        const EmitterSample e = tracer.sampleEmitter(rng);
        size_t bin = observed.size() - 1;  // nowhere on a lamp
        for (size_t k = 0; k < lamps.size(); ++k) {
            const Box& l = lamps[k];
            if (e.point.x() < l.x0 || e.point.x() > l.x1 || e.point.z() < l.z0 || e.point.z() > l.z1) continue;
            const int i = std::min(grid - 1, int((e.point.x() - l.x0) / (l.x1 - l.x0) * grid));
            const int j = std::min(grid - 1, int((e.point.z() - l.z0) / (l.z1 - l.z0) * grid));
            bin = k * grid * grid + size_t(i * grid + j);
            // The density it reports is the one it samples with.
            const double area = (l.x1 - l.x0) * (l.z1 - l.z0);
            ASSERT_NEAR(e.pdfArea, l.power / total / area, 1e-9 * e.pdfArea) << "lamp " << k;
        }
        ASSERT_NEAR(e.point.y(), 2, 1e-12);
        ASSERT_NEAR(e.normal.y(), 1, 1e-12) << "lamps face up";
        observed[bin] += 1;
    }
    for (size_t k = 0; k < lamps.size(); ++k)
        for (int c = 0; c < grid * grid; ++c)
            expected[k * grid * grid + size_t(c)] = samples * lamps[k].power / total / (grid * grid);
    expectChiSquare(observed, expected, kAlpha, "emitter points");
}

TEST(Sampling, GlassPicksReflectionWithTheFresnelProbability) {
    // At a smooth glass surface a path reflects with probability F and refracts with 1 - F, its weight
    // then the branch's share over its probability (1 untinted, the tint once on the way in).
    Material glass;
    glass.type = MaterialType::Dielectric;
    glass.ior = 1.5;
    glass.transmittance = Rgb(0.9, 0.8, 0.7);
    SurfaceHit hit;
    hit.found = true;
    hit.normal = Vec3::UnitZ();
    hit.material = &glass;
    struct Case {
        double thetaDeg;
        bool outside;
    };
    const std::vector<Case> cases{{0, true},  {30, true},  {60, true},  {80, true},   {89, true},
                                  {0, false}, {20, false}, {40, false}, {41.5, false}};
    const int samples = 100000;
    Rng rng(9);
    for (const Case& c : cases) {
        const double th = c.thetaDeg * kPi / 180;
        // Arriving from above (outside, against the normal) or from below (inside the glass).
        const Vec3 dir = c.outside ? Vec3(std::sin(th), 0, -std::cos(th)) : Vec3(std::sin(th), 0, std::cos(th));
        const double F = c.outside ? fresnelDielectric(std::cos(th), 1, 1.5) : fresnelDielectric(std::cos(th), 1.5, 1);
        double reflected = 0;
        for (int s = 0; s < samples; ++s) {
            const std::optional<SpecularBranch> b = sampleSpecular(hit, dir, rng);
            ASSERT_TRUE(b.has_value());
            const bool isReflection = (b->dir.z() > 0) == c.outside;
            reflected += isReflection;
            const Rgb weight = isReflection || !c.outside ? Rgb(Rgb::Ones()) : glass.transmittance;
            ASSERT_LT((b->weight - weight).abs().maxCoeff(), 1e-12) << c.thetaDeg;
        }
        expectChiSquare({reflected, samples - reflected}, {samples * F, samples * (1 - F)},
                        test::sidak(kAlpha, int(cases.size())),
                        cat(c.thetaDeg, " degrees, ", c.outside ? "outside" : "inside"));
    }
}

TEST(Sampling, PhotonsLandWhereTheLampsMirrorImageLightsTheFloor) {
    // A lamp facing up (0.5 m square, L_e = 1) on a floor, under a perfect mirror 1 m above: the
    // photons that come down land as if sent by the lamp's image at 2 m, so the count expected in a
    // floor cell is N E(cell) / (pi L_e A), E by the closed-form point-to-rectangle factor (Howell
    // B-3). Tests the emission (points by area, cosine directions, power), the mirror and the storage
    // together; photons that leave between the planes make one more bin.
    const std::string json = R"({"materials": {
          "lamp": {"type": "diffuse", "reflectance": 0.5, "emission": 1},
          "floor": {"type": "diffuse", "reflectance": 0.5},
          "chrome": {"type": "mirror", "reflectance": 1}},
      "objects": [
        {"name": "lamp", "type": "quad", "material": "lamp", "vertices": [[-0.25,0.001,-0.25],[-0.25,0.001,0.25],[0.25,0.001,0.25],[0.25,0.001,-0.25]]},
        {"name": "floor", "type": "quad", "material": "floor", "vertices": [[-10,0,-10],[-10,0,10],[10,0,10],[10,0,-10]]},
        {"name": "mirror", "type": "quad", "material": "chrome", "vertices": [[-10,1,-10],[10,1,-10],[10,1,10],[-10,1,10]]}]})";
    const Scene scene = test::sceneFromJson(json);
    const PatchSet patches = meshScene(scene, {});
    const SceneTracer tracer(scene, patches);
    PhotonSettings settings;
    settings.photons = 200000;
    settings.precompute = 0;
    const PhotonMap map(tracer, settings);
    const double h = 1.999, half = 2.0, cell = 0.25;
    const int grid = int(2 * half / cell);
    std::vector<double> observed(size_t(grid * grid) + 1, 0), expected(observed.size(), 0);
    for (const PhotonMap::Stored& p : map.storedPhotons()) {
        const int i = int(std::floor((p.position.x() + half) / cell)),
                  j = int(std::floor((p.position.z() + half) / cell));
        const bool inside = i >= 0 && j >= 0 && i < grid && j < grid;
        observed[inside ? size_t(i * grid + j) : observed.size() - 1] += 1;
    }
    // Photons that were not stored left the scene: they join the outside bin.
    observed.back() += double(settings.photons - map.stats().stored);
    const double lampPower = kPi * 1 * 0.25, photonPower = lampPower / double(settings.photons);
    double inside = 0;
    for (int i = 0; i < grid; ++i)
        for (int j = 0; j < grid; ++j) {
            // E over the cell by a 6 x 6 midpoint rule; E = pi L_e F(x -> image lamp).
            double power = 0;
            const int sub = 6;
            for (int a = 0; a < sub; ++a)
                for (int b = 0; b < sub; ++b) {
                    const double x = -half + (i + (a + 0.5) / sub) * cell, z = -half + (j + (b + 0.5) / sub) * cell;
                    power += kPi * test::pointToRectangle(-0.25 - x, 0.25 - x, -0.25 - z, 0.25 - z, h);
                }
            power *= cell * cell / (sub * sub);
            expected[size_t(i * grid + j)] = power / photonPower;
            inside += expected[size_t(i * grid + j)];
        }
    expected.back() = double(settings.photons) - inside;
    expectChiSquare(observed, expected, kAlpha, "photons on the floor");
    // Every stored photon carries the lamp's power over the photon count (one lamp, uniform L_e).
    for (const PhotonMap::Stored& p : map.storedPhotons()) ASSERT_NEAR(p.power[0], photonPower, 1e-6 * photonPower);
}
