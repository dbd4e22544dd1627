// Adaptive subdivision and the displayed vertex radiosity: splits keep the geometry and the 2:1
// rule, hanging vertices leave no crack, the radiosity equation at the vertices meets the closed
// form of a point under a rectangle, and refinement puts its patches along a shadow's penumbra.
#include <gtest/gtest.h>

#include <map>
#include <set>

#include "fixtures.h"
#include "mesh/refine.h"
#include "solver/contact_grading.h"
#include "solver/radiosity/vertex_radiosity.h"

namespace penumbra {
namespace {

using test::lampOverFloor;
using test::pointToRectangle;
using test::unshadowedFloor;

TEST(Refinement, SplitsKeepTheAreaTheTwoToOneRuleAndLeaveNoCrack) {
    const Scene scene = test::sceneFromJson(lampOverFloor(true));
    MeshingOptions o;
    o.patchSize = 0.25;
    PatchSet p = meshScene(scene, o);
    auto objectAreas = [](const PatchSet& s) {
        std::map<int, double> a;
        for (size_t i = 0; i < s.size(); ++i) a[s.object[i]] += s.area[i];
        return a;
    };
    const auto before = objectAreas(p);
    // Split a floor patch, then its child at the edge it shares with an unsplit neighbour, then that
    // child's: the 2:1 rule must split the neighbours in turn.
    for (const Vec3& target : {Vec3(-0.6, -0.6, 0), Vec3(-0.52, -0.6, 0), Vec3(-0.505, -0.6, 0)}) {
        std::vector<char> split(p.size(), 0);
        size_t nearest = 0;
        for (size_t i = 0; i < p.size(); ++i)
            if (p.object[i] == 0 && (p.centroid[i] - target).norm() < (p.centroid[nearest] - target).norm())
                nearest = i;
        split[nearest] = 1;
        const size_t n = p.size();
        p = splitPatches(p, split);
        ASSERT_GE(p.size(), n + 3);
    }
    const auto after = objectAreas(p);
    for (const auto& [object, area] : before) EXPECT_NEAR(after.at(object), area, 1e-12) << "object " << object;

    // 2:1: no vertex sits at a quarter of any patch's edge (a neighbour two levels finer).
    std::set<std::array<long long, 4>> vertexAt;
    auto key = [](int object, const Vec3& x) {
        return std::array<long long, 4>{object, std::llround(x.x() * 1e9), std::llround(x.y() * 1e9),
                                        std::llround(x.z() * 1e9)};
    };
    for (size_t i = 0; i < p.size(); ++i)
        for (int k = 0; k < p.cornerCount[i]; ++k) vertexAt.insert(key(p.object[i], p.corners[i][size_t(k)]));
    for (size_t i = 0; i < p.size(); ++i)
        for (int k = 0; k < p.cornerCount[i]; ++k) {
            const Vec3& a = p.corners[i][size_t(k)];
            const Vec3& b = p.corners[i][size_t((k + 1) % p.cornerCount[i])];
            const Vec3 m = 0.5 * (a + b);
            EXPECT_FALSE(vertexAt.count(key(p.object[i], 0.5 * (a + m))) ||
                         vertexAt.count(key(p.object[i], 0.5 * (m + b))))
                << "patch " << i << " edge " << k;
        }

    // A linear field shown through the hanging vertices: each takes the mean of its coarse edge's
    // ends, so both sides of the join interpolate the same line.
    const auto hanging = hangingVertices(p);
    ASSERT_FALSE(hanging.empty());
    std::vector<Rgb> value(p.size());
    for (size_t i = 0; i < p.size(); ++i) value[i] = Rgb::Constant(1 + p.centroid[i].x() + 2 * p.centroid[i].y());
    const CornerValues corners = interpolateCorners(p, value);
    for (const HangingVertex& h : hanging) {
        const Rgb mean =
            0.5 * (corners[size_t(h.patch)][size_t(h.cornerA)] + corners[size_t(h.patch)][size_t(h.cornerB)]);
        for (size_t j = 0; j < p.size(); ++j)
            for (int k = 0; k < p.cornerCount[j]; ++k)
                if (p.cornerVertex[j][size_t(k)] == h.vertex) {
                    ASSERT_DOUBLE_EQ(corners[j][size_t(k)][0], mean[0]);
                }
    }
}

class VertexRadiosity : public ::testing::TestWithParam<std::string> {};

TEST_P(VertexRadiosity, MeetsTheClosedFormOfAPointUnderARectangle) {
    SolveOptions o;
    o.meshing.patchSize = 0.2;
    o.vertexRadiosity = GetParam();
    const SolveResult r = solveScene(test::sceneFromJson(lampOverFloor(false)), o);
    ASSERT_EQ(r.corners.size(), r.patches.size());
    double worst = 0;
    for (size_t i = 0; i < r.patches.size(); ++i) {
        if (r.patches.object[i] != 0) continue;
        for (int k = 0; k < r.patches.cornerCount[i]; ++k) {
            const double exact = unshadowedFloor(r.patches.corners[i][size_t(k)]);
            worst = std::max(worst, std::abs(r.corners[i][size_t(k)][0] - exact) / exact);
        }
    }
    EXPECT_LT(worst, 5e-3);
}

INSTANTIATE_TEST_SUITE_P(Modes, VertexRadiosity, ::testing::Values("gather", "direct"));

TEST(VertexRadiosity, ACeilingAboveALampSeesItsBackNotItsLight) {
    // The lamp (facing down, 1 m up) with a ceiling 1 cm above it, facing down too (the building's
    // lamps under its ceilings). The ceiling sees the floor and the lamp's back: its irradiance is at
    // most the floor's brightest radiosity, rho E F(0 -> lamp), the ceiling's own light on the floor
    // adding a few percent. Read as the lamp's front, the ceiling's vertices above the lamp showed
    // rho E F(1 cm -> lamp), about 80 times that.
    std::string json = lampOverFloor(false);
    json.insert(json.rfind(']'), R"(,
        {"name": "ceiling", "type": "quad", "material": "floor",
         "vertices": [[-1,-1,1.01],[-1,1,1.01],[1,1,1.01],[1,-1,1.01]]})");
    SolveOptions o;
    o.meshing.patchSize = 0.2;
    o.vertexRadiosity = "direct";
    const Scene scene = test::sceneFromJson(json);
    const SolveResult r = solveScene(scene, o);
    const double bound = 1.2 * 0.5 * unshadowedFloor(Vec3::Zero());
    int above = 0;
    for (size_t i = 0; i < r.patches.size(); ++i) {
        if (scene.objects[size_t(r.patches.object[i])].name != "ceiling") continue;
        for (int k = 0; k < r.patches.cornerCount[i]; ++k) {
            const Vec3& x = r.patches.corners[i][size_t(k)];
            above += std::abs(x.x()) < 0.1 && std::abs(x.y()) < 0.1;
            EXPECT_LT(r.corners[i][size_t(k)][0], bound) << "ceiling corner at " << x.transpose();
        }
    }
    EXPECT_GT(above, 0) << "a ceiling vertex lies above the lamp";
}

TEST(VertexRadiosity, DirectDrawsThePenumbraAtTheVertices) {
    // The black square halfway up hides part of the lamp from floor points 0.3 to 0.5 m off the axis:
    // from x it covers, in the lamp's plane, the square of side 0.8 centred at -x (its shadow cast
    // back through x, twice as far), so x sees the lamp less that overlap; the floor's radiosity is
    // then rho E F(x -> visible lamp) in closed form (nothing else lights it). Patches of 0.13 m
    // (a grid the penumbra's edges do not follow) span most of the penumbra each: their means smear it; the vertices
    // must not.
    SolveOptions o;
    o.meshing.patchSize = 0.13;
    const SolveResult r = solveScene(test::sceneFromJson(lampOverFloor(true)), o);
    auto exact = [](const Vec3& x) {
        const double x0 = std::max(-0.1, -x.x() - 0.4), x1 = std::min(0.1, -x.x() + 0.4);
        const double y0 = std::max(-0.1, -x.y() - 0.4), y1 = std::min(0.1, -x.y() + 0.4);
        const double hidden = x0 < x1 && y0 < y1
                                  ? 0.5 * kPi * 10 * pointToRectangle(x0 - x.x(), x1 - x.x(), y0 - x.y(), y1 - x.y(), 1)
                                  : 0.0;
        return unshadowedFloor(x) - hidden;
    };
    const double peak = unshadowedFloor(Vec3::Zero());
    double worst = 0, worstMean = 0;
    for (size_t i = 0; i < r.patches.size(); ++i) {
        if (r.patches.object[i] != 0) continue;
        for (int k = 0; k < r.patches.cornerCount[i]; ++k) {
            const Vec3& x = r.patches.corners[i][size_t(k)];
            worst = std::max(worst, std::abs(r.corners[i][size_t(k)][0] - exact(x)) / peak);
            worstMean = std::max(worstMean, std::abs(r.solution.B[i][0] - exact(x)) / peak);
        }
    }
    std::printf("penumbra: worst vertex %.4f of the peak, worst patch mean against its corners %.4f\n", worst,
                worstMean);
    EXPECT_LT(worst, 0.02);
    EXPECT_GT(worstMean, 0.1) << "the patch means smear the penumbra (else the test shows nothing)";
}

TEST(Refinement, PutsItsPatchesAlongThePenumbraAndKeepsTheClosedFormOutsideIt) {
    SolveOptions o;
    o.meshing.targetPatches = 150;
    o.refine.tolerance = 0.05;
    o.refine.maxPatches = 2500;
    o.refine.maxRounds = 4;
    const Scene scene = test::sceneFromJson(lampOverFloor(true));
    const SolveResult r = solveScene(scene, o);
    ASSERT_GE(r.refinement.size(), 2u);
    EXPECT_GT(r.patches.size(), r.refinement.front().patches);
    EXPECT_LE(r.patches.size(), 2500u);

    // The penumbra, 0.3 to 0.5 m off the axis (either way), holds much finer patches than the floor
    // far from it.
    double bandArea = 0, farArea = 0;
    int band = 0, far = 0;
    for (size_t i = 0; i < r.patches.size(); ++i) {
        if (r.patches.object[i] != 0) continue;
        const double d = r.patches.centroid[i].head<2>().cwiseAbs().maxCoeff();
        if (d > 0.3 && d < 0.5) bandArea += r.patches.area[i], ++band;
        if (d > 0.8) farArea += r.patches.area[i], ++far;
    }
    ASSERT_GT(band, 0);
    ASSERT_GT(far, 0);
    EXPECT_LT(bandArea / band, 0.25 * farArea / far) << band << " patches in the penumbra, " << far << " far off";

    // Outside the penumbra the vertices see the whole lamp (closed form); inside the umbra none of it.
    const Rgb peak = Rgb::Constant(unshadowedFloor(Vec3::Zero()));
    for (size_t i = 0; i < r.patches.size(); ++i) {
        if (r.patches.object[i] != 0) continue;
        for (int k = 0; k < r.patches.cornerCount[i]; ++k) {
            const Vec3& x = r.patches.corners[i][size_t(k)];
            const double d = x.head<2>().cwiseAbs().maxCoeff();
            if (d > 0.55) {
                EXPECT_NEAR(r.corners[i][size_t(k)][0], unshadowedFloor(x), 5e-3 * unshadowedFloor(x)) << x.transpose();
            } else if (d < 0.25) {
                EXPECT_LT(r.corners[i][size_t(k)][0], 1e-3 * peak[0]) << x.transpose();
            }
        }
    }
    // And the power still balances: emitted = absorbed + escaped, the escaped power counted by rays.
    test::expectBalanceByRays(scene, r);
}

}  // namespace
}  // namespace penumbra

namespace penumbra {

TEST(ContactGrading, SplitsThePatchesBesideAContactAndNoOthers) {
    // A 0.4 m box standing on a 2 m floor, meshed at 0.1 m: the floor patches that touch the box's
    // footprint (another surface closer than their width) and the box's lowest row split into four,
    // the floor far from the box and the box's upper rows keep their size.
    const std::string json = R"({"materials": {"m": {"type": "diffuse", "reflectance": 0.5, "emission": 1}},
      "objects": [
        {"name": "floor", "type": "quad", "material": "m", "vertices": [[-1,0,-1],[-1,0,1],[1,0,1],[1,0,-1]]},
        {"name": "top",   "type": "quad", "material": "m", "vertices": [[-0.2,0.4,-0.2],[-0.2,0.4,0.2],[0.2,0.4,0.2],[0.2,0.4,-0.2]]},
        {"name": "px",    "type": "quad", "material": "m", "vertices": [[0.2,0,-0.2],[0.2,0.4,-0.2],[0.2,0.4,0.2],[0.2,0,0.2]]},
        {"name": "nx",    "type": "quad", "material": "m", "vertices": [[-0.2,0,-0.2],[-0.2,0,0.2],[-0.2,0.4,0.2],[-0.2,0.4,-0.2]]},
        {"name": "pz",    "type": "quad", "material": "m", "vertices": [[-0.2,0,0.2],[0.2,0,0.2],[0.2,0.4,0.2],[-0.2,0.4,0.2]]},
        {"name": "nz",    "type": "quad", "material": "m", "vertices": [[-0.2,0,-0.2],[-0.2,0.4,-0.2],[0.2,0.4,-0.2],[0.2,0,-0.2]]}]})";
    const Scene scene = test::sceneFromJson(json);
    MeshingOptions meshing;
    meshing.patchSize = 0.1;
    const PatchSet uniform = meshScene(scene, meshing);
    ContactGrading grading;
    grading.levels = 1;
    const GradedMesh graded = gradeContacts(scene, uniform, grading);
    ASSERT_GT(graded.split, 0u);
    EXPECT_EQ(graded.rays, nullptr) << "split patches need a scene of their own";
    const PatchSet& p = graded.patches;
    const double whole = 0.01, quarter = whole / 4;
    int near = 0, far = 0, low = 0, high = 0;
    for (size_t i = 0; i < p.size(); ++i) {
        const Vec3& c = p.centroid[i];
        if (p.object[i] == 0) {
            // Distance from the centroid to the box's footprint.
            const double d = std::max(std::abs(c.x()), std::abs(c.z())) - 0.2;
            if (d > 0 && d < 0.05) {
                EXPECT_NEAR(p.area[i], quarter, 1e-9) << "floor beside the box " << c.transpose();
                ++near;
            }
            if (d > 0.35) {
                EXPECT_NEAR(p.area[i], whole, 1e-9) << "floor far from the box " << c.transpose();
                ++far;
            }
        } else if (p.object[i] >= 2) {
            if (c.y() < 0.05) {
                EXPECT_NEAR(p.area[i], quarter, 1e-9) << "box side at the floor " << c.transpose();
                ++low;
            }
            if (c.y() > 0.2) {
                EXPECT_NEAR(p.area[i], whole, 1e-9) << "box side high up " << c.transpose();
                ++high;
            }
        }
    }
    EXPECT_GT(near, 0);
    EXPECT_GT(far, 0);
    EXPECT_GT(low, 0);
    EXPECT_GT(high, 0);
    double before = 0, after = 0;
    for (double a : uniform.area) before += a;
    for (double a : p.area) after += a;
    EXPECT_NEAR(after, before, 1e-9 * before) << "splitting keeps the surface";
}

TEST(ContactGrading, KeepsAboutTheAskedPatchCount) {
    SolveOptions o;
    o.meshing.targetPatches = 1000;
    o.grading.levels = 1;
    const SolveResult r = solveScene(test::sceneFromJson(test::sceneFile("cornell-box.json")), o);
    EXPECT_NEAR(double(r.patches.size()), 1000.0, 150.0) << "--patches N: about N patches in all";
}

}  // namespace penumbra
