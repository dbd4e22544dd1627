// Form factors against closed forms: differential area to a coaxial disk, parallel and
// perpendicular unit squares (Howell's catalogue, C-11 and C-14), reciprocity from two independent
// integrations, and closure of a box.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

#include "core/rng.h"
#include "fixtures.h"
#include "solver/radiosity/form_factor_kernel.h"
#include "solver/radiosity/form_factors.h"
#include "solver/radiosity/ray_form_factors.h"
#include "solver/shafts.h"
#include "solver/tracer.h"

using namespace penumbra;

namespace {

// Howell C-14: perpendicular rectangles sharing an edge of length l, widths w (from) and h (to).
double perpendicularRectangles(double l, double w, double h) {
    const double H = h / l, W = w / l;
    const double A = (1 + W * W) * (1 + H * H) / (1 + W * W + H * H);
    const double B = W * W * (1 + W * W + H * H) / ((1 + W * W) * (W * W + H * H));
    const double C = H * H * (1 + H * H + W * W) / ((1 + H * H) * (H * H + W * W));
    return 1 / (kPi * W) *
           (W * std::atan(1 / W) + H * std::atan(1 / H) -
            std::sqrt(H * H + W * W) * std::atan(1 / std::sqrt(H * H + W * W)) +
            0.25 * std::log(A * std::pow(B, W * W) * std::pow(C, H * H)));
}

const char* kTwoSquaresParallel = R"({"materials": {"m": {"type": "diffuse", "reflectance": 0.5}},
  "objects": [
    {"name": "a", "type": "quad", "material": "m", "vertices": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]},
    {"name": "b", "type": "quad", "material": "m", "vertices": [[0,0,1],[0,1,1],[1,1,1],[1,0,1]]}]})";

const char* kTwoSquaresPerpendicular = R"({"materials": {"m": {"type": "diffuse", "reflectance": 0.5}},
  "objects": [
    {"name": "a", "type": "quad", "material": "m", "vertices": [[0,0,0],[0,0,1],[1,0,1],[1,0,0]]},
    {"name": "b", "type": "quad", "material": "m", "vertices": [[0,0,0],[0,1,0],[0,1,1],[0,0,1]]}]})";

SolveResult solveWith(const std::string& json, int patches) {
    SolveOptions o;
    o.meshing.targetPatches = patches;
    return solveScene(test::sceneFromJson(json), o);
}

}  // namespace

TEST(FormFactorClosedForms, HowellValuesMatchTheIssue) {
    // The catalogue formulas themselves, against the published values for unit squares.
    EXPECT_NEAR(test::parallelRectangles(1, 1, 1), 0.19982, 1e-5);
    EXPECT_NEAR(perpendicularRectangles(1, 1, 1), 0.20004, 1e-5);
}

TEST(FormFactorKernel, DifferentialAreaToCoaxialDisk) {
    // F = R^2 / (R^2 + h^2); the disk is a 512-gon, whose area differs from the disk's by 2.5e-5.
    for (double h : {0.1, 1.0, 10.0}) {
        const double R = 1;
        std::vector<Vec3> poly;
        for (int k = 0; k < 512; ++k)
            poly.emplace_back(R * std::cos(2 * kPi * k / 512), R * std::sin(2 * kPi * k / 512), h);
        // The kernel takes up to 4 vertices at a time: sum the fan of triangles.
        double F = 0;
        for (int k = 0; k < 512; ++k) {
            const Vec3 tri[3] = {Vec3(0, 0, h), poly[size_t(k)], poly[size_t((k + 1) % 512)]};
            F += pointPolygonFormFactor(Vec3::Zero(), Vec3::UnitZ(), tri, 3);
        }
        EXPECT_NEAR(F, R * R / (R * R + h * h), 5e-3 * R * R / (R * R + h * h)) << "h = " << h;
    }
}

TEST(FormFactorKernel, ClipsWhatLiesBehindThePoint) {
    // A square standing on the point's plane, half below it: only the upper half counts, which is
    // the perpendicular-square configuration seen from a point on the shared edge's midline.
    const Vec3 full[4] = {Vec3(-1, 1, -1), Vec3(1, 1, -1), Vec3(1, 1, 1), Vec3(-1, 1, 1)};
    const Vec3 half[4] = {Vec3(-1, 1, 0), Vec3(1, 1, 0), Vec3(1, 1, 1), Vec3(-1, 1, 1)};
    EXPECT_NEAR(pointPolygonFormFactor(Vec3::Zero(), Vec3::UnitZ(), full, 4),
                pointPolygonFormFactor(Vec3::Zero(), Vec3::UnitZ(), half, 4), 1e-12);
}

TEST(FormFactorMatrix, SmallPatchToCoaxialDisk) {
    // A 1 mm square patch under a disk (a 256-gon mesh of radius 1 at height 1), through the
    // whole pipeline: F(patch -> disk) = R^2 / (R^2 + h^2) = 0.5.
    std::string obj = "v 0 0 1\n";
    for (int k = 0; k < 256; ++k)
        obj += cat("v ", std::cos(2 * kPi * k / 256), " ", std::sin(2 * kPi * k / 256), " 1\n");
    for (int k = 0; k < 256; ++k) obj += cat("f 1 ", 2 + (k + 1) % 256, " ", 2 + k, "\n");
    test::writeText("disk.obj", obj);
    const std::string json = R"({"materials": {"m": {"type": "diffuse", "reflectance": 0.5}},
      "objects": [
        {"name": "patch", "type": "quad", "material": "m", "vertices": [[-5e-4,-5e-4,0],[5e-4,-5e-4,0],[5e-4,5e-4,0],[-5e-4,5e-4,0]]},
        {"name": "disk", "type": "mesh", "material": "m", "file": "disk.obj"}]})";
    SolveOptions o;
    o.meshing.patchSize = 0.2;
    const SolveResult r = solveScene(test::sceneFromJson(json, "disk.json"), o);
    const double polygonArea = 256 * 0.5 * std::sin(2 * kPi / 256);
    const double Rp = std::sqrt(polygonArea / kPi);  // the disk of the polygon's area
    EXPECT_NEAR(test::objectFormFactor(r, 0, 1), Rp * Rp / (Rp * Rp + 1), 0.005 * 0.5);
}

TEST(FormFactorMatrix, UnitSquaresAtDefaultSettings) {
    for (int patches : {2, 50, 800}) {
        const SolveResult parallel = solveWith(kTwoSquaresParallel, patches);
        EXPECT_NEAR(test::objectFormFactor(parallel, 0, 1), 0.19982, 0.005 * 0.19982) << patches << " patches";
        const SolveResult perpendicular = solveWith(kTwoSquaresPerpendicular, patches);
        EXPECT_NEAR(test::objectFormFactor(perpendicular, 0, 1), 0.20004, 0.005 * 0.20004) << patches << " patches";
    }
}

TEST(FormFactorMatrix, UnequalRectanglesBothWays) {
    // Perpendicular 1 x 2 (wide) and 1 x 0.5 rectangles sharing the unit edge; reciprocity of the
    // closed forms gives both directions.
    const std::string json = R"({"materials": {"m": {"type": "diffuse", "reflectance": 0.5}},
      "objects": [
        {"name": "a", "type": "quad", "material": "m", "vertices": [[0,0,0],[0,0,1],[2,0,1],[2,0,0]]},
        {"name": "b", "type": "quad", "material": "m", "vertices": [[0,0,0],[0,0.5,0],[0,0.5,1],[0,0,1]]}]})";
    const SolveResult r = solveWith(json, 300);
    const double fab = perpendicularRectangles(1, 2, 0.5);
    EXPECT_NEAR(test::objectFormFactor(r, 0, 1), fab, 0.005 * fab);
    EXPECT_NEAR(test::objectFormFactor(r, 1, 0), fab * 2 / 0.5, 0.005 * fab * 4);
}

TEST(FormFactorMatrix, ReciprocityFromIndependentIntegrations) {
    // A_i F(i->j) integrated over i, and A_j F(j->i) integrated over j, are two independent
    // quadratures of the same double integral; they must agree within the estimator's tolerance.
    SolveOptions o;
    o.meshing.targetPatches = 150;
    const Scene scene =
        test::sceneFromJson(test::closedCube(R"({"type": "diffuse", "reflectance": 0.5})"), "cube.json");
    const PatchSet p = meshScene(scene, o.meshing);
    const CubatureSettings settings;
    double worst = 0;
    for (size_t i = 0; i < p.size(); i += 7)
        for (size_t j = 0; j < p.size(); j += 5) {
            if (i == j || std::abs(p.normal[i].dot(p.normal[j])) > 0.5) continue;  // skip coplanar / opposite faces
            const double gij = unoccludedAreaFactor(p, i, j, settings), gji = unoccludedAreaFactor(p, j, i, settings);
            worst = std::max(worst, std::abs(gij - gji) / std::max(gij, gji));
        }
    EXPECT_LT(worst, 1e-3);
}

TEST(FormFactorMatrix, ClosedBoxRowsSumToOne) {
    SolveOptions o;
    o.meshing.targetPatches = 600;
    const SolveResult r = solveScene(
        test::sceneFromJson(test::closedCube(R"({"type": "diffuse", "reflectance": 0.5, "emission": 1})"), "cube.json"),
        o);
    EXPECT_NEAR(r.rowSumMin, 1.0, 1e-5);
    EXPECT_NEAR(r.rowSumMax, 1.0, 1e-5);
    // In a closed box nothing escapes.
    EXPECT_NEAR(r.power.escaped.sum(), 0.0, 1e-5 * r.power.totalEmitted.sum());
}

namespace {

SolveResult solveByRays(const std::string& json, int patches, int rays, const std::string& solver = "gauss-seidel",
                        double tolerance = 1e-9) {
    SolveOptions o;
    o.meshing.targetPatches = patches;
    o.formFactors.method = "rays";
    o.formFactors.raysPerPatch = rays;
    o.solver = solver;
    o.solverSettings.tolerance = tolerance;
    o.solverSettings.maxIterations = 10000000;
    return solveScene(test::sceneFromJson(json), o);
}

// A floor of four 1 m patches (reflectance 0.5) over [-1, 1]^2 under a 20 m black sky of exitance 1
// at 1 m, with `objects` (JSON, material "black" for reflectance 0) beside them, solved by ray-cast
// form factors on 1 m patches, ungraded.
const char* kFloorUnderSky = R"({
      "materials": {"sky": {"type": "diffuse", "reflectance": 0, "emission": 0.3183098861837907},
                    "floor": {"type": "diffuse", "reflectance": 0.5},
                    "black": {"type": "diffuse", "reflectance": 0}},
      "objects": [
        {"name": "floor", "type": "quad", "material": "floor", "vertices": [[-1,0,-1],[-1,0,1],[1,0,1],[1,0,-1]]},
        {"name": "sky", "type": "quad", "material": "sky", "vertices": [[-10,1,-10],[10,1,-10],[10,1,10],[-10,1,10]]},)";

SolveResult solveFloorUnderSky(const Scene& scene, int rays) {
    SolveOptions o;
    o.meshing.patchSize = 1.0;
    o.formFactors.method = "rays";
    o.formFactors.raysPerPatch = rays;
    o.grading.levels = 0;
    return solveScene(scene, o);
}

}  // namespace

TEST(RayFormFactors, RowsOfAClosedSceneSumToOneWhateverTheOccluders) {
    const SolveResult r = solveByRays(test::furnaceWithOccluders(0.5), 300, 256);
    ASSERT_TRUE(r.F.sampled);
    for (double s : rowSums(r.F)) ASSERT_NEAR(s, 1.0, 1e-6) << "every ray lands on a front face";
    EXPECT_TRUE(r.F.backTransfers.empty()) << "no back face is in sight in a closed scene of closed objects";
}

// The furnace with occluders, towards rho = 1: B = E / (1 - rho) on every patch, whatever the solver
// and the form factors. Before issue 13 the analytic matrix read 1.2% off at rho = 0.995 and the
// hierarchy 2.5% at 0.9, 29% at 0.99 and 45% at 0.995: their rows summed to one only within their
// cubature and visibility sampling, and a furnace multiplies that by 1 / (1 - rho). Ray-cast rows sum
// to one by construction; the others are scaled to it once rays find the scene closed.
void expectFurnace(const SolveResult& r, double rho, const std::string& what) {
    const double expected = kPi / (1 - rho);
    double worst = 0;
    for (size_t i = 0; i < r.patches.size(); ++i)
        for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(r.solution.B[i][c] / expected - 1));
    EXPECT_TRUE(r.closedScene) << what;
    EXPECT_LT(worst, 5e-3) << what << " at rho " << rho;
    EXPECT_NEAR(r.power.totalAbsorbed[0], r.power.totalEmitted[0], 5e-3 * r.power.totalEmitted[0]) << what;
}

class FurnaceWithOccluders : public ::testing::TestWithParam<std::tuple<std::string, double>> {};

TEST_P(FurnaceWithOccluders, EveryPatchHoldsEOverOneMinusRhoAtTheDefaults) {
    const auto [solver, rho] = GetParam();
    SolveOptions o;
    o.meshing.targetPatches = test::kSanitized ? 150 : 300;
    o.solver = solver;
    o.solverSettings.tolerance = 1e-5 * (1 - rho);
    o.solverSettings.maxIterations = 10000000;
    expectFurnace(solveScene(test::sceneFromJson(test::furnaceWithOccluders(rho)), o), rho, solver);
}

INSTANTIATE_TEST_SUITE_P(Solvers, FurnaceWithOccluders,
                         ::testing::Combine(::testing::Values("jacobi", "gauss-seidel", "southwell", "hierarchical"),
                                            ::testing::Values(0.9, 0.99, 0.995, 0.999)));

class RayFurnace : public ::testing::TestWithParam<std::string> {};

TEST_P(RayFurnace, EveryPatchHoldsEOverOneMinusRho) {
    const std::string solver = GetParam();
    const double rho = 0.999;
    expectFurnace(
        solveByRays(test::furnaceWithOccluders(rho), test::kSanitized ? 120 : 250, 64, solver, 1e-5 * (1 - rho)), rho,
        solver + " by rays");
}

INSTANTIATE_TEST_SUITE_P(Solvers, RayFurnace, ::testing::Values("jacobi", "gauss-seidel", "southwell"));

TEST(RayFormFactors, AFurnaceWithANarrowGapHoldsEOverOneMinusRho) {
    // A panel 1 cm off a wall: the wall's patches behind it show the room the light of their part in
    // the room, the panel's face in the gap reads what it meets there as its own. Rows still sum to one.
    const double rho = 0.999;
    const SolveResult r = solveByRays(test::furnaceWithOccluders(rho, true), test::kSanitized ? 120 : 250, 64,
                                      "gauss-seidel", 1e-5 * (1 - rho));
    size_t weighted = 0;
    for (size_t i = 0; i < r.patches.size(); ++i) weighted += r.F.hasMeanRow(i);
    EXPECT_GT(weighted, 0u) << "wall patches partly behind the panel";
    // Reading the light where rays land moves weight between entries, some below zero: each row's
    // magnitudes must stay under 1 / rho, the bound under which Gauss-Seidel converges whatever the
    // mesh (on main before, this mesh's rows reached 1.41 / rho; on another, Gauss-Seidel diverged).
    double worst = 0;
    for (size_t i = 0; i < r.patches.size(); ++i) {
        const FormFactorMatrix::SparseRow row = r.F.sparseRow(i);
        double magnitude = 0;
        for (size_t k = 0; k < row.count; ++k) magnitude += std::abs(double(row.value[k]));
        worst = std::max(worst, rho * magnitude);
    }
    EXPECT_LT(worst, 1.0);
    expectFurnace(r, rho, "a narrow gap");
}

TEST(Closure, AnOpenSceneIsNotScaled) {
    // The furnace cube without its top face: rays leave through the opening, so the analytic rows keep
    // their own sums, below one near the opening. Scaled, the patches by the opening would read 1.
    const std::string open = R"({"materials": {"m": {"type": "diffuse", "reflectance": 0.5, "emission": 1}},
      "objects": [
        {"name": "bottom", "type": "quad", "material": "m", "vertices": [[0,0,0],[0,0,1],[1,0,1],[1,0,0]]},
        {"name": "left",   "type": "quad", "material": "m", "vertices": [[0,0,0],[0,1,0],[0,1,1],[0,0,1]]},
        {"name": "right",  "type": "quad", "material": "m", "vertices": [[1,0,0],[1,0,1],[1,1,1],[1,1,0]]},
        {"name": "back",   "type": "quad", "material": "m", "vertices": [[0,0,1],[0,1,1],[1,1,1],[1,0,1]]},
        {"name": "front",  "type": "quad", "material": "m", "vertices": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}]})";
    SolveOptions o;
    o.meshing.targetPatches = 200;
    const SolveResult r = solveScene(test::sceneFromJson(open), o);
    EXPECT_EQ(r.formFactorMethod, "analytic");
    EXPECT_FALSE(r.closedScene);
    const std::vector<double> rows = rowSums(r.F);
    EXPECT_LT(*std::min_element(rows.begin(), rows.end()), 0.9);
}

TEST(RayFormFactors, ParallelSquaresWithinTheirSamplingError) {
    // Howell's parallel unit squares at distance 1: F = 0.19982. Each of the k patches' N rays lands
    // on the other square with probability F (on average over the patch): the object-level estimate's
    // standard error is at most sqrt(F (1 - F) / (k N)), stratification only lowering it.
    const int rays = 1024;
    const SolveResult r = solveByRays(kTwoSquaresParallel, 64, rays);
    const double k = double(r.patches.size()) / 2;
    const double exact = test::parallelRectangles(1, 1, 1);
    const double sigma = std::sqrt(exact * (1 - exact) / (k * rays));
    EXPECT_NEAR(test::objectFormFactor(r, 0, 1), exact, 4.5 * sigma);
    EXPECT_NEAR(test::objectFormFactor(r, 1, 0), exact, 4.5 * sigma);
    // And a ray is a ray: the counter says how many were cast.
    EXPECT_EQ(r.counters.at("form_factors.cast_rays"), uint64_t(r.patches.size()) * rays);
}

TEST(RayFormFactors, ASmallLampsLightIsExactNotSampled) {
    // The 0.2 m lamp over the floor covers 1% of the surface: its column is taken analytically, so each
    // floor patch's radiosity is rho E F(patch -> lamp) to the cubature's accuracy. By rays alone, a
    // patch's 64 rays would find the lamp about twice at the centre, and never at the rim.
    SolveOptions o;
    o.meshing.patchSize = 0.2;
    o.formFactors.method = "rays";
    o.formFactors.raysPerPatch = 64;
    const SolveResult r = solveScene(test::sceneFromJson(test::lampOverFloor(false)), o);
    double worst = 0;
    for (size_t i = 0; i < r.patches.size(); ++i) {
        if (r.patches.object[i] != 0) continue;
        // The patch's mean of the closed form, by a 4 x 4 midpoint rule.
        double exact = 0;
        for (int a = 0; a < 4; ++a)
            for (int b = 0; b < 4; ++b)
                exact += test::unshadowedFloor(r.patches.pointAt(i, (a + 0.5) / 4, (b + 0.5) / 4));
        exact /= 16;
        worst = std::max(worst, std::abs(r.solution.B[i][0] - exact) / exact);
    }
    EXPECT_LT(worst, 5e-3);
}

// A floor of four 1 m patches under a uniform sky (a black emitter 20 m wide, 1 m up, E = 1), with
// a black box 2 mm tall and open at the bottom standing on a quarter of one patch, and a one-sided
// black table top facing up 0.3 m over another. The box's covered quarter receives no light; the
// rest of its patch sees the sky as any floor point does. A patch that held the mean over its whole
// area, the covered part's darkness included, showed 0.75 of the light to everything that sees it
// (the Cornell box's block faces read 10-14% dark in their bottom row): its radiosity is the mean
// over the uncovered part, rho E F(x -> sky) averaged there, the object's mean the covered part dark.
// The floor under the table sees the table's back, but not in every direction: it is not covered.
TEST(RayFormFactors, ASolidStandingOnAPatchCoversItsShareAndNoMore) {
    const Scene scene = test::sceneFromJson(std::string(kFloorUnderSky) + R"(
        {"name": "box_top", "type": "quad", "material": "black",
         "vertices": [[0.5,0.002,0.5],[0.5,0.002,1.5],[1.5,0.002,1.5],[1.5,0.002,0.5]]},
        {"name": "box_left", "type": "quad", "material": "black",
         "vertices": [[0.5,0,0.5],[0.5,0,1.5],[0.5,0.002,1.5],[0.5,0.002,0.5]]},
        {"name": "box_right", "type": "quad", "material": "black",
         "vertices": [[1.5,0,0.5],[1.5,0.002,0.5],[1.5,0.002,1.5],[1.5,0,1.5]]},
        {"name": "box_front", "type": "quad", "material": "black",
         "vertices": [[0.5,0,0.5],[0.5,0.002,0.5],[1.5,0.002,0.5],[1.5,0,0.5]]},
        {"name": "box_back", "type": "quad", "material": "black",
         "vertices": [[0.5,0,1.5],[1.5,0,1.5],[1.5,0.002,1.5],[0.5,0.002,1.5]]},
        {"name": "table", "type": "quad", "material": "black",
         "vertices": [[-0.8,0.3,-0.8],[-0.8,0.3,-0.2],[-0.2,0.3,-0.2],[-0.2,0.3,-0.8]]}]})");
    const SolveResult r = solveFloorUnderSky(scene, 1024);
    ASSERT_EQ(r.F.exposed.size(), r.patches.size());
    // rho E F(x -> sky) averaged over the floor points of [x0, x1] x [z0, z1] (a 40 x 40 grid) that
    // lie outside the box's footprint [0.5, 1.5]^2.
    auto meanLight = [](double x0, double x1, double z0, double z1, double& uncovered) {
        double sum = 0;
        int open = 0;
        for (int a = 0; a < 40; ++a)
            for (int b = 0; b < 40; ++b) {
                const double x = x0 + (x1 - x0) * (a + 0.5) / 40, z = z0 + (z1 - z0) * (b + 0.5) / 40;
                if (x > 0.5 && z > 0.5) continue;
                sum += 0.5 * test::pointToRectangle(-10 - x, 10 - x, -10 - z, 10 - z, 1);
                ++open;
            }
        uncovered = open / 1600.0;
        return sum / open;
    };
    int seen = 0;
    for (size_t i = 0; i < r.patches.size(); ++i) {
        if (scene.objects[size_t(r.patches.object[i])].name != "floor") continue;
        const Vec3 c = r.patches.centroid[i];
        const double x0 = std::floor(c.x()), z0 = std::floor(c.z());
        if (x0 == 0 && z0 == 0) {
            double uncovered = 0;
            const double exact = meanLight(x0, x0 + 1, z0, z0 + 1, uncovered);
            ++seen;
            EXPECT_NEAR(r.F.exposed[i], 0.75, 0.01) << "the box covers a quarter of this patch";
            EXPECT_NEAR(r.solution.B[i][0], exact, 0.015 * exact) << "the mean over its uncovered part";
            EXPECT_NEAR(litArea(r, i), uncovered * r.patches.area[i], 0.01) << "light leaves and lands there alone";
        } else {
            EXPECT_EQ(r.F.exposed[i], 1.0f) << "nothing stands on the patch at " << c.transpose();
        }
    }
    EXPECT_EQ(seen, 1);
}

TEST(RayFormFactors, APatchWhollyInASolidCastsNoRaysOfItsOwn) {
    // One of the floor's patches wholly under a 2 mm box open at the bottom (a 1 cm rim of it over the
    // two beside it, whose few covered origins are followed as before). The patch is covered
    // (no light reaches it, none leaves it), found by its centre and corners alone (five points, five
    // rays each): without that test it would cast its 1,024 rays and follow each into the box with
    // five more.
    const Scene scene = test::sceneFromJson(std::string(kFloorUnderSky) + R"(
        {"name": "box_top", "type": "quad", "material": "black",
         "vertices": [[-0.01,0.002,-0.01],[-0.01,0.002,1.01],[1.01,0.002,1.01],[1.01,0.002,-0.01]]},
        {"name": "box_left", "type": "quad", "material": "black",
         "vertices": [[-0.01,0,-0.01],[-0.01,0,1.01],[-0.01,0.002,1.01],[-0.01,0.002,-0.01]]},
        {"name": "box_right", "type": "quad", "material": "black",
         "vertices": [[1.01,0,-0.01],[1.01,0.002,-0.01],[1.01,0.002,1.01],[1.01,0,1.01]]},
        {"name": "box_front", "type": "quad", "material": "black",
         "vertices": [[-0.01,0,-0.01],[-0.01,0.002,-0.01],[1.01,0.002,-0.01],[1.01,0,-0.01]]},
        {"name": "box_back", "type": "quad", "material": "black",
         "vertices": [[-0.01,0,1.01],[1.01,0,1.01],[1.01,0.002,1.01],[-0.01,0.002,1.01]]}]})");
    const SolveResult r = solveFloorUnderSky(scene, 1024);
    size_t covered = 0;
    for (size_t i = 0; i < r.patches.size(); ++i) {
        const Vec3 c = r.patches.centroid[i];
        if (r.patches.object[i] != 0 || c.x() < 0 || c.z() < 0) continue;
        ++covered;
        EXPECT_EQ(r.F.exposed[i], 0.0f);
        EXPECT_EQ(r.solution.B[i][0], 0.0);
        EXPECT_EQ(r.F.sparseRow(i).count, 0u);
    }
    ASSERT_EQ(covered, 1u);
    // The others cast 1,024 each, and follow their few origins under the rim and the odd grazing ray
    // that meets a back face: fewer than the covered patch's own 1,024 (with 5 more for each, 6,144)
    // in all. (The box's 2 mm sides, whose rays land on the floor beside them, also ask whether their
    // origins lie in a gap: rays counted apart.)
    EXPECT_LT(r.counters.at("form_factors.cast_rays") - r.counters.at("form_factors.gap_rays"),
              1024 * r.patches.size());
    EXPECT_GT(objectRadiosity(r, scene.objects.size())[0][0], 0.0);
}

// The floor under the sky with a black square facing it `height` over [0.25, 1]^2 (a roof showing
// its back, or a panel its front): at a floor point x, with F_o(x) the factor to the square and F_s(x)
// to the sky (Howell's point-to-rectangle), B(x) = rho E (F_s - F_o), and the scene sees x by
// v(x) = 1 - F_o. Per floor patch, over a grid x grid of points: the share the scene sees, what it
// sees (the mean of B weighted by v) and the plain mean, against the solve's seen share, B and mean.
// The patch under the square must tell the two apart by `apart`, and have its mean row.
void expectSeenAndMeanUnder(const Scene& scene, const SolveResult& r, const std::vector<Rgb>& mean, double height,
                            int grid, double apart) {
    int under = 0;
    for (size_t i = 0; i < r.patches.size(); ++i) {
        if (scene.objects[size_t(r.patches.object[i])].name != "floor") continue;
        const Vec3 c = r.patches.centroid[i];
        const double x0 = std::floor(c.x()), z0 = std::floor(c.z());
        double vB = 0, v = 0, b = 0;
        for (int a = 0; a < grid; ++a)
            for (int d = 0; d < grid; ++d) {
                const double x = x0 + (a + 0.5) / grid, z = z0 + (d + 0.5) / grid;
                const double over = test::pointToRectangle(0.25 - x, 1 - x, 0.25 - z, 1 - z, height);
                const double B = 0.5 * (test::pointToRectangle(-10 - x, 10 - x, -10 - z, 10 - z, 1) - over);
                vB += (1 - over) * B;
                v += 1 - over;
                b += B;
            }
        const double seenExact = vB / v, meanExact = b / (grid * grid), shareExact = v / (grid * grid);
        EXPECT_EQ(r.F.exposed[i], 1.0f) << "an open square covers nothing";
        EXPECT_NEAR(r.F.seen[i], shareExact, 0.03) << "share of the patch the scene sees at " << c.transpose();
        EXPECT_NEAR(r.solution.B[i][0], seenExact, 0.04 * seenExact) << "what the scene sees at " << c.transpose();
        EXPECT_NEAR(mean[i][0], meanExact, 0.04 * meanExact) << "the mean over the patch at " << c.transpose();
        if (x0 == 0 && z0 == 0) {
            ++under;
            EXPECT_GT(seenExact, apart * meanExact) << "the test tells the two apart";
            EXPECT_TRUE(r.F.hasMeanRow(i));
        }
    }
    EXPECT_EQ(under, 1);
}

TEST(RayFormFactors, APatchPartlyHiddenShowsTheSceneWhatItSeesAndKeepsItsMean) {
    // A floor of four 1 m patches under a 20 m sky (E = 1), a one-sided black roof facing up 0.1 m over
    // [0.25, 1]^2, most of one patch: from beneath, the roof shows its back face. Not a solid (its
    // sides are open), so nothing is covered. At a floor point x, with F_r(x) the factor to the roof
    // and F_s(x) to the sky (Howell's point-to-rectangle), the radiosity is B(x) = rho E (F_s - F_r),
    // and the share of its directions that meet no back face, how much the scene sees of it, is
    // v(x) = 1 - F_r. What the scene gathers from the patch is the mean of B weighted by v; what it
    // absorbs and the report shows is the plain mean. Under the roof the two differ by half.
    const Scene scene = test::sceneFromJson(std::string(kFloorUnderSky) + R"(
        {"name": "roof", "type": "quad", "material": "black",
         "vertices": [[0.25,0.1,0.25],[0.25,0.1,1],[1,0.1,1],[1,0.1,0.25]]}]})");
    const SolveResult r = solveFloorUnderSky(scene, 4096);
    ASSERT_EQ(r.F.seen.size(), r.patches.size());
    // The roof's patch: B from a share of about half its 4,096 rays, 1.6% standard error; 4% is 2.5 of them.
    const std::vector<Rgb> mean = meanRadiosity(r.system, r.F, r.solution.B);
    expectSeenAndMeanUnder(scene, r, mean, 0.1, 40, 1.4);
    // The report's floor is the plain mean, and the power adds up with the escaped light counted by rays.
    double meanFloor = 0;
    for (size_t i = 0; i < r.patches.size(); ++i)
        if (scene.objects[size_t(r.patches.object[i])].name == "floor") meanFloor += mean[i][0] / 4;
    EXPECT_NEAR(objectRadiosity(r, scene.objects.size())[0][0], meanFloor, 1e-9);
    test::expectBalanceByRays(scene, r, 5e-3);
}

TEST(RayFormFactors, APatchPartlyInANarrowGapShowsTheSceneItsOpenPart) {
    // The floor under the sky, a black panel facing down 1 cm over [0.25, 1]^2 (its front face to the
    // floor, so no back face is in sight): the floor beneath sees the panel and little else, and the
    // scene sees that part of the floor only through the 1 cm slit. As in the roof's test above, at a
    // floor point B(x) = rho E (F_s - F_p) and the scene sees it by v(x) = 1 - F_p; the origins under
    // the panel (its normal meets the panel within a quarter of the patch's radius) count as unseen.
    const Scene scene = test::sceneFromJson(std::string(kFloorUnderSky) + R"(
        {"name": "panel", "type": "quad", "material": "black",
         "vertices": [[0.25,0.01,0.25],[1,0.01,0.25],[1,0.01,1],[0.25,0.01,1]]}]})");
    const SolveResult r = solveFloorUnderSky(scene, 4096);
    ASSERT_EQ(r.F.seen.size(), r.patches.size());
    const std::vector<Rgb> mean = meanRadiosity(r.system, r.F, r.solution.B);
    expectSeenAndMeanUnder(scene, r, mean, 0.01, 80, 1.8);
    test::expectBalanceByRays(scene, r, 5e-3);
}

TEST(RayFormFactors, AShadowOnALargePatchTakesItsShareOfTheLight) {
    // The lamp over the floor with the black square between them, the floor in four 1 m patches: each
    // patch's corner under the lamp, where it sees the lamp best, lies in the square's shadow. A pair's
    // visibility counted by area (four rays, all of which may miss the shadow) made the lamp's light
    // on the floor too bright; by the light each ray's floor end receives, it is the mean of the exact
    // integral below: rho L_e times the lamp's visible part seen from each floor point, on a 100 x 100
    // grid of floor points and a 16 x 16 grid on the lamp, the shadow found by the square's own
    // geometry (no ray scene).
    SolveOptions o;
    o.meshing.patchSize = 1.0;
    o.formFactors.method = "rays";
    o.formFactors.raysPerPatch = 64;
    o.grading.levels = 0;
    const Scene scene = test::sceneFromJson(test::lampOverFloor(true));
    const SolveResult r = solveScene(scene, o);
    const double solved = objectRadiosity(r, scene.objects.size())[0][0];
    const int floorGrid = 100, lampGrid = 16;
    double exact = 0;
    for (int a = 0; a < floorGrid; ++a)
        for (int b = 0; b < floorGrid; ++b) {
            const Vec3 x(-1 + 2 * (a + 0.5) / floorGrid, -1 + 2 * (b + 0.5) / floorGrid, 0);
            for (int c = 0; c < lampGrid; ++c)
                for (int d = 0; d < lampGrid; ++d) {
                    const Vec3 q(-0.1 + 0.2 * (c + 0.5) / lampGrid, -0.1 + 0.2 * (d + 0.5) / lampGrid, 1);
                    const Vec3 mid = 0.5 * (x + q);  // where the segment crosses the square's plane z = 0.5
                    if (std::abs(mid.x()) < 0.2 && std::abs(mid.y()) < 0.2) continue;
                    const Vec3 v = q - x;
                    exact += v.z() * v.z() / (kPi * v.squaredNorm() * v.squaredNorm());
                }
        }
    exact *= 0.5 * kPi * 10 * (0.04 / (lampGrid * lampGrid)) / (floorGrid * floorGrid);
    EXPECT_NEAR(solved, exact, 0.01 * exact);
}

// The lamp over the floor with the black square between them, the floor in 5 cm patches taken in
// order, each pair's visibility first tested against the patch that blocked the last one's rays (the
// building's rooms behind a wall from another room's lamp): every factor is the same as traced
// afresh, and the shadowed patches cost fewer rays.
TEST(FormFactorMatrix, AKnownBlockerGivesTheSameFactorsForFewerRays) {
    const Scene scene = test::sceneFromJson(test::lampOverFloor(true));
    MeshingOptions m;
    m.patchSize = 0.05;
    const PatchSet p = meshScene(scene, m);
    const auto rays = buildRayScene(scene, p);
    const FormFactorSettings settings;
    std::vector<size_t> lamp;
    for (size_t j = 0; j < p.size(); ++j)
        if (p.object[j] == 1) lamp.push_back(j);
    ASSERT_FALSE(lamp.empty());
    std::vector<Blockers> blockers(lamp.size());
    uint64_t traced = 0, cached = 0;
    int shadowed = 0;
    for (size_t i = 0; i < p.size(); ++i) {
        if (p.object[i] != 0) continue;
        for (size_t a = 0; a < lamp.size(); ++a) {
            const uint64_t before = raysCast();
            const double plain = frontFormFactor(p, *rays, i, lamp[a], settings);
            const uint64_t between = raysCast();
            const double known = frontFormFactor(p, *rays, i, lamp[a], settings, &blockers[a]);
            ASSERT_EQ(plain, known) << "floor patch " << i << ", lamp patch " << lamp[a];
            if (plain > 0) continue;
            ++shadowed;
            traced += between - before, cached += raysCast() - between;
        }
    }
    EXPECT_GT(shadowed, 100);
    EXPECT_LT(double(cached), 0.2 * double(traced));
}

// A small patch 1 cm above a floor whose light rises linearly across it, B(x) = 1 + x, at (x0, z0)
// on an 8 x 8 mesh of a 1 m floor (0.125 m patches): the mean light its rays read, made to read the
// light where they land (readLightWhereRaysLand) and as each patch's mean, wherever they land.
struct LinearFloorReading {
    double whereLanded, patchMean;
};
LinearFloorReading readLinearFloor(double x0, double z0) {
    const double h = 0.01, w = 0.002;
    const Scene scene =
        test::sceneFromJson(cat(R"({"materials": {"m": {"type": "diffuse", "reflectance": 0.5}},
      "objects": [
        {"name": "floor", "type": "quad", "material": "m", "vertices": [[-0.5,0,-0.5],[-0.5,0,0.5],[0.5,0,0.5],[0.5,0,-0.5]]},
        {"name": "receiver", "type": "quad", "material": "m", "vertices": [[)",
                                x0 - w, ",", h, ",", z0 - w, "],[", x0 + w, ",", h, ",", z0 - w, "],[", x0 + w, ",", h,
                                ",", z0 + w, "],[", x0 - w, ",", h, ",", z0 + w, "]]}]}"));
    MeshingOptions meshing;
    meshing.patchSize = 0.125;
    const PatchSet patches = meshScene(scene, meshing);
    EXPECT_EQ(patches.size(), 65u) << "an 8 x 8 floor and the receiver";
    const auto rays = buildRayScene(scene, patches);
    FormFactorSettings settings;
    settings.raysPerPatch = 16384;
    HitReadings readings;
    FormFactorMatrix F = castFormFactors(patches, *rays, settings, {}, {}, &readings);
    std::vector<Rgb> B(patches.size(), Rgb::Zero());
    size_t receiver = 0;
    for (size_t i = 0; i < patches.size(); ++i) {
        if (scene.objects[size_t(patches.object[i])].name == "receiver")
            receiver = i;
        else
            B[i] = Rgb::Constant(1 + patches.centroid[i].x());
    }
    auto read = [&](const FormFactorMatrix& m) {
        double light = 0, share = 0;
        m.forEachInRow(receiver, [&](size_t j, float f) { light += f * B[j][0], share += f; });
        return light / share;
    };
    LinearFloorReading out;
    out.patchMean = read(F);
    const std::vector<double> sums = rowSums(F);
    readLightWhereRaysLand(F, patches, readings, B);
    out.whereLanded = read(F);
    const std::vector<double> after = rowSums(F);
    for (size_t i = 0; i < sums.size(); ++i) EXPECT_NEAR(after[i], sums[i], 1e-5) << "light moves between columns";
    return out;
}

// Over the floor's middle the receiver reads the cosine-weighted mean of B over the floor below it:
// 1 + x0 at its foot x0 (the linear term averages out about the foot; the floor's edges, 0.4 m away
// or more, hold under 0.1% of the kernel). Its foot lies 3.5 cm off the centre of a floor patch,
// whose mean 1 + x_c the rays read without the reading: 2.4% low (ray_form_factors.h).
TEST(RayFormFactors, ARayReadsTheLightWhereItLandsOnAPatch) {
    const double x0 = 0.0975;
    const LinearFloorReading r = readLinearFloor(x0, 0.0625);
    EXPECT_NEAR(r.whereLanded, 1 + x0, 0.002 * (1 + x0)) << "the patches' means read where each ray landed";
    EXPECT_LT(r.patchMean, 1 + x0 - 0.01) << "the setting tells the two apart";
}

// The same 2.75 cm inside the floor's dark edge, over a patch that has no neighbour on its darker
// side (as the floor along a block's foot): the rays that land read the mean of B over the part of
// the kernel that lies on the floor, 1 + x0 + E[t | t > -d] with the kernel's marginal across the
// edge p(t) = h^2 / (2 (t^2 + h^2)^1.5): E = h^2 / (2 sqrt(d^2 + h^2)) / (1 - (1 - d / sqrt(d^2 +
// h^2)) / 2). A limiter that kept every corner within the neighbours' range read the patch's mean,
// 6% bright.
TEST(RayFormFactors, ARayReadsTheLightWhereItLandsBesideAnEdge) {
    const double h = 0.01, d = 0.0275, x0 = -0.5 + d;
    const double s = std::sqrt(d * d + h * h);
    const double expected = 1 + x0 + h * h / (2 * s) / (1 - (1 - d / s) / 2);
    const LinearFloorReading r = readLinearFloor(x0, 0.0625);
    EXPECT_NEAR(r.whereLanded, expected, 0.002 * expected) << "the edge patch's slope read up to the edge";
    EXPECT_GT(r.patchMean, expected + 0.02) << "the setting tells the two apart";
}

// The noise each object's mean carries, as the report states it (relative_error_estimate: the
// multinomial variance of each patch's rays and of the patches they land on), against the spread of
// the means over eight seeds of the Cornell box at the default settings. Pooled over the objects,
// the spread's variance must not pass the stated one (it may fall below: the strata gain is not in
// the estimate; measured, the estimate was 1-2 times the spread), nor fall below a tenth of it.
TEST(RayFormFactorsSlow, EachObjectsStatedNoiseHoldsOverSeeds) {
    const Scene scene = test::sceneFromJson(test::sceneFile("cornell-box.json"));
    const size_t objects = scene.objects.size();
    std::vector<std::vector<double>> means(objects);
    std::vector<double> stated(objects, 0.0);
    const int seeds = 8;
    for (int seed = 1; seed <= seeds; ++seed) {
        SolveOptions o;
        o.formFactors.seed = uint64_t(seed);
        const SolveResult r = solveScene(scene, o);
        ASSERT_EQ(r.objectNoise.size(), objects) << "the default Cornell box solve casts rays";
        const std::vector<Rgb> radiosity = objectRadiosity(r, objects);
        for (size_t k = 0; k < objects; ++k) {
            means[k].push_back(radiosity[k].sum() / 3);
            stated[k] += r.objectNoise[k] / seeds;
        }
    }
    double ratio = 0;
    int counted = 0;
    for (size_t k = 0; k < objects; ++k) {
        if (!(stated[k] > 0)) continue;
        double mean = 0, var = 0;
        for (double m : means[k]) mean += m / seeds;
        for (double m : means[k]) var += (m - mean) * (m - mean) / (seeds - 1);
        const double relative = std::sqrt(var) / mean;
        ratio += relative * relative / (stated[k] * stated[k]);
        ++counted;
        std::printf("%-16s spread %.3f%%  stated %.3f%%\n", scene.objects[k].name.c_str(), 100 * relative,
                    100 * stated[k]);
    }
    ASSERT_GT(counted, 10);
    ratio /= counted;
    EXPECT_LT(ratio, 1.3) << "the spread's variance, pooled, over the stated one";
    EXPECT_GT(ratio, 0.1) << "the stated noise is not far above the spread";
}

// Sixteen rays a patch leave the floor under the sky with about 2% of stated noise (each ray meets
// the sky, the table's underside or escapes at the horizon); past --ff-noise (0.5%) its rows are
// cast again with (2/0.5)^2 times the rays, merged into the matrix in place of the first ones. The
// floor's mean radiosity then holds rho E F(x -> sky) averaged over the floor (Howell's
// point-to-rectangle factor, less the table's), and the stated noise has fallen.
TEST(RayFormFactors, AnObjectAboveTheNoiseTargetCastsAgainAndHoldsItsClosedForm) {
    const Scene scene = test::sceneFromJson(std::string(kFloorUnderSky) + R"(
        {"name": "table", "type": "quad", "material": "black",
         "vertices": [[-0.8,0.3,-0.8],[-0.8,0.3,-0.2],[-0.2,0.3,-0.2],[-0.2,0.3,-0.8]]}]})");
    size_t floor = 0;
    while (scene.objects[floor].name != "floor") ++floor;
    double exact = 0;
    for (int a = 0; a < 80; ++a)
        for (int b = 0; b < 80; ++b) {
            const double x = -1 + 2 * (a + 0.5) / 80, z = -1 + 2 * (b + 0.5) / 80;
            // The table's shadow: points under it see the sky less its back face's share.
            double f = test::pointToRectangle(-10 - x, 10 - x, -10 - z, 10 - z, 1);
            f -= test::pointToRectangle(-0.8 - x, -0.2 - x, -0.8 - z, -0.2 - z, 0.3);
            exact += 0.5 * f / 6400;
        }
    SolveOptions o;
    o.meshing.patchSize = 1.0;
    o.formFactors.method = "rays";
    o.formFactors.raysPerPatch = 16;
    o.grading.levels = 0;
    o.formFactors.objectNoise = 1;
    const SolveResult once = solveScene(scene, o);
    ASSERT_EQ(once.objectNoise.size(), scene.objects.size());
    EXPECT_GT(once.objectNoise[floor], 0.015) << "16 rays a patch state their noise";
    o.formFactors.objectNoise = 0.005;
    const SolveResult again = solveScene(scene, o);
    // Sixteen rays estimate their own variance poorly (all of a patch's rays meet the sky a third of
    // the time, and it reads none): the second pass, 289 rays a patch, states 0.85%, not 0.5%.
    EXPECT_LT(again.objectNoise[floor], 0.5 * once.objectNoise[floor]) << "cast again with more rays";
    const double floorMean = objectRadiosity(again, scene.objects.size())[floor][0];
    EXPECT_NEAR(floorMean, exact, 0.015 * exact) << "the merged rows hold the closed form";
}

// A white table 0.3 m over the floor under the sky, 16 rays a patch: its underside's noise is the
// floor's under it (each floor patch there meets the sky or the table), not its own gather, and the
// floor as a whole is quiet. Past --ff-noise the floor patches it gathers from are cast again
// (Neyman's allocation over what it gathers), not only its own rows: the spread of its mean over 16
// seeds, an independent measure of the noise, falls to the target: 2.9% once, 0.88% cast again;
// casting only the table's own rows again (to bring its own gathers to the target) left 1.68%.
TEST(RayFormFactors, AnObjectNoisyWithWhatItGathersHasThoseRowsCastAgain) {
    const Scene scene = test::sceneFromJson(std::string(kFloorUnderSky) + R"(
        {"name": "table", "type": "quad", "material": "floor",
         "vertices": [[-0.3,0.3,-0.3],[0.3,0.3,-0.3],[0.3,0.3,0.3],[-0.3,0.3,0.3]]}]})");
    const size_t table = scene.objects.size() - 1;
    const double target = 0.01;
    auto spread = [&](double noise) {
        SolveOptions o;
        o.meshing.patchSize = 0.25;
        o.formFactors.method = "rays";
        o.formFactors.raysPerPatch = 16;
        o.grading.levels = 0;
        o.formFactors.objectNoise = noise;
        const int seeds = 16;
        double m1 = 0, m2 = 0;
        for (int seed = 1; seed <= seeds; ++seed) {
            o.formFactors.seed = uint64_t(seed);
            const double m = objectRadiosity(solveScene(scene, o), scene.objects.size())[table][0];
            m1 += m / seeds, m2 += m * m / seeds;
        }
        return std::sqrt(std::max(0.0, m2 - m1 * m1) * seeds / (seeds - 1)) / m1;
    };
    const double once = spread(1);
    ASSERT_GT(once, 2 * target) << "the test's table is noisy at 16 rays";
    EXPECT_LT(spread(target), 1.2 * target) << "cast again where its noise comes from";
}

// The floor under the sky, 64 patches of 16 rays. Asked for 1.05 times the noise it states after one
// pass, it does not cast again for that target; but a surface of more than 14 of the mesh's patches
// is cast again to a tighter one, the target times sqrt(14 patches / its area) (0.47x here), from a
// budget of its own (half the first pass's rays). The spread of its mean over 32 seeds, the
// independent measure: 0.30% after one pass, 0.16% so (0.27% without the tighter target, which
// fails this test; the stated noise 0.26% -> 0.13%, 0.22% without).
TEST(RayFormFactors, ALargeSurfaceIsCastAgainToATighterTarget) {
    std::string json = kFloorUnderSky;
    json.pop_back();  // its trailing comma
    const Scene scene = test::sceneFromJson(json + "]}");
    size_t floor = 0;
    while (scene.objects[floor].name != "floor") ++floor;
    SolveOptions o;
    o.meshing.patchSize = 0.25;
    o.formFactors.method = "rays";
    o.formFactors.raysPerPatch = 16;
    o.grading.levels = 0;
    auto spread = [&](double noise, double* stated) {
        o.formFactors.objectNoise = noise;
        const int seeds = 32;
        double m1 = 0, m2 = 0;
        *stated = 0;
        for (int seed = 1; seed <= seeds; ++seed) {
            o.formFactors.seed = uint64_t(seed);
            const SolveResult r = solveScene(scene, o);
            const double m = objectRadiosity(r, scene.objects.size())[floor][0];
            m1 += m / seeds, m2 += m * m / seeds;
            *stated += r.objectNoise[floor] / seeds;
        }
        return std::sqrt(std::max(0.0, m2 - m1 * m1) * seeds / (seeds - 1)) / m1;
    };
    double statedOnce = 0, statedAgain = 0;
    const double once = spread(1, &statedOnce);
    const double again = spread(1.05 * statedOnce, &statedAgain);
    std::printf("floor: once spread %.3f%% stated %.3f%%; again spread %.3f%% stated %.3f%%\n", 100 * once,
                100 * statedOnce, 100 * again, 100 * statedAgain);
    EXPECT_LT(again, 0.75 * once) << "cast again to the tighter target";
    EXPECT_LT(statedAgain, 0.75 * statedOnce);
}

TEST(RayFormFactors, ASmallObjectAsksAtMostFourTimesTheRays) {
    // A 0.2 m tile facing the floor from 0.3 m up: its rays meet the floor or leave the scene, noisy at
    // 16 rays. Smaller than three of the mesh's 1 m patches, it casts again with at most 4x the rays
    // (its own noise at least half of the first pass's), however far above --ff-noise it is.
    const Scene scene = test::sceneFromJson(std::string(kFloorUnderSky) + R"(
        {"name": "tile", "type": "quad", "material": "floor",
         "vertices": [[0.4,0.3,0.4],[0.6,0.3,0.4],[0.6,0.3,0.6],[0.4,0.3,0.6]]}]})");
    const size_t tile = scene.objects.size() - 1;
    SolveOptions o;
    o.meshing.patchSize = 1.0;
    o.formFactors.method = "rays";
    o.formFactors.raysPerPatch = 16;
    o.grading.levels = 0;
    o.formFactors.objectNoise = 1;
    const SolveResult once = solveScene(scene, o);
    ASSERT_GT(once.objectNoise[tile], 0.05) << "the test's tile is noisy";
    o.formFactors.objectNoise = 0.005;
    const SolveResult again = solveScene(scene, o);
    EXPECT_LT(again.objectNoise[tile], 0.8 * once.objectNoise[tile]) << "it casts again";
    EXPECT_GT(again.objectNoise[tile], 0.4 * once.objectNoise[tile]) << "with at most 4x the rays, not 64x";
}

// A wall meshed into 16 patches between a lamp and the floor: the floor patch under its middle is
// hidden wholly by it (every corner-to-corner segment crosses it), and the visibility rays agree
// (none of 64 gets through). A floor patch whose view of the lamp passes the wall's edge is not, nor
// one on the lamp's side; a ball (not planar) and an object whose patches' hull is larger than they
// are (not convex) hide nothing.
TEST(ConvexOccluder, AWallHidesAPatchWhollyOnlyWhereEveryViewCrossesIt) {
    const Scene scene = test::sceneFromJson(R"({
      "materials": {"m": {"type": "diffuse", "reflectance": 0.5},
                    "lamp": {"type": "diffuse", "reflectance": 0, "emission": 1}},
      "objects": [
        {"name": "wall", "type": "quad", "material": "m", "vertices": [[0,0,1],[2,0,1],[2,2,1],[0,2,1]]},
        {"name": "lamp", "type": "quad", "material": "lamp",
         "vertices": [[0.9,0.9,2],[0.9,1.1,2],[1.1,1.1,2],[1.1,0.9,2]]},
        {"name": "under", "type": "quad", "material": "m",
         "vertices": [[0.8,0.8,0],[1.2,0.8,0],[1.2,1.2,0],[0.8,1.2,0]]},
        {"name": "beside", "type": "quad", "material": "m",
         "vertices": [[2.6,0.8,0],[3.0,0.8,0],[3.0,1.2,0],[2.6,1.2,0]]},
        {"name": "above", "type": "quad", "material": "m",
         "vertices": [[0.8,0.8,1.5],[1.2,0.8,1.5],[1.2,1.2,1.5],[0.8,1.2,1.5]]},
        {"name": "ball", "type": "sphere", "material": "m", "center": [5, 5, 1], "radius": 0.5}]})");
    MeshingOptions m;
    m.patchSize = 0.5;
    m.patchesPerObject = 0;
    const PatchSet p = meshScene(scene, m);
    auto first = [&](int object) {
        size_t i = 0;
        while (p.object[i] != object) ++i;
        return i;
    };
    const std::vector<ConvexOccluder> occluders = convexOccluders(p);
    ASSERT_EQ(occluders.size(), scene.objects.size());
    ASSERT_EQ(occluders[0].edges.size(), 4u) << "the wall's 16 patches make one square";
    EXPECT_TRUE(occluders[5].edges.empty()) << "a ball is not planar";
    const size_t lamp = first(1), under = first(2), beside = first(3), above = first(4);
    EXPECT_TRUE(hidesWholly(occluders[0], p, under, lamp));
    EXPECT_TRUE(hidesWholly(occluders[0], p, lamp, under)) << "either way round";
    EXPECT_FALSE(hidesWholly(occluders[0], p, beside, lamp)) << "its view passes the wall's edge";
    EXPECT_FALSE(hidesWholly(occluders[0], p, above, lamp)) << "on the lamp's side";
    const auto rays = buildRayScene(scene, p);
    EXPECT_EQ(visibleFraction(p, *rays, lamp, under, 1, 1, false, 64, 1).fraction, 0.0) << "the rays agree";
    EXPECT_GT(visibleFraction(p, *rays, lamp, beside, 1, 1, false, 64, 1).fraction, 0.0);

    // Two squares 1.4 m apart in one plane taken as one object's patches: their corners' hull is
    // larger than they are (as an L's or a frame's would be), so they are no occluder.
    PatchSet l = p;
    for (size_t i = 0; i < l.size(); ++i)
        if (l.object[i] == 2 || l.object[i] == 3) l.object[i] = 2;  // under and beside, 1.4 m apart
    EXPECT_TRUE(convexOccluders(l)[2].edges.empty());
}

namespace {
// A floor that sees a small lamp only through a hole in a screen between them, one patch per object.
const char* const kLampThroughAHole = R"({
      "materials": {"m": {"type": "diffuse", "reflectance": 0.5},
                    "lamp": {"type": "diffuse", "reflectance": 0, "emission": 1}},
      "objects": [
        {"name": "floor", "type": "quad", "material": "m", "vertices": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]},
        {"name": "lamp", "type": "quad", "material": "lamp",
         "vertices": [[0.4,0.4,1],[0.4,0.6,1],[0.6,0.6,1],[0.6,0.4,1]]},
        {"name": "left", "type": "quad", "material": "m",
         "vertices": [[-1,-1,0.5],[-1,2,0.5],[0.7,2,0.5],[0.7,-1,0.5]]},
        {"name": "right", "type": "quad", "material": "m",
         "vertices": [[0.9,-1,0.5],[0.9,2,0.5],[2,2,0.5],[2,-1,0.5]]},
        {"name": "below", "type": "quad", "material": "m",
         "vertices": [[0.7,-1,0.5],[0.7,0.4,0.5],[0.9,0.4,0.5],[0.9,-1,0.5]]},
        {"name": "above", "type": "quad", "material": "m",
         "vertices": [[0.7,0.6,0.5],[0.7,2,0.5],[0.9,2,0.5],[0.9,0.6,0.5]]}]})";

struct HoleScene {
    PatchSet patches;
    std::shared_ptr<const RayScene> rays;
    size_t floor, lamp;
};
HoleScene holeScene() {
    const Scene scene = test::sceneFromJson(kLampThroughAHole);
    MeshingOptions m;
    m.patchSize = 5;  // one patch per object
    m.patchesPerObject = 0;
    HoleScene h{meshScene(scene, m), nullptr, 0, 0};
    h.rays = buildRayScene(scene, h.patches);
    h.floor = h.lamp = h.patches.size();
    for (size_t j = 0; j < h.patches.size(); ++j) {
        if (h.patches.object[j] == 0) h.floor = j;
        if (h.patches.object[j] == 1) h.lamp = j;
    }
    return h;
}
}  // namespace

// A floor that sees a small lamp only through a hole in a screen between them (a room's floor, a
// corridor's lamp through the door): 3.9% of the lamp's factor gets through. The pair's visible
// share from visibleFraction (four rays to decide, as by default), averaged over 100,000 seeds
// (0.0383, standard error 0.0003), against 200,000 uniform segments between the two patches, each
// weighted by the kernel between its ends (0.0387): the share of the form factor that gets
// through. When the four deciding rays were kept in the estimate (all blocked: 0), and the strata
// of the two patches paired the same way every time, the mean came to under a quarter of it.
TEST(FormFactorMatrix, APairThatSeesThroughAHoleGetsItsShareOfTheLight) {
    const HoleScene h = holeScene();
    const PatchSet& p = h.patches;
    const size_t floor = h.floor, lamp = h.lamp;
    const auto& rays = h.rays;
    ASSERT_LT(floor, p.size());
    ASSERT_LT(lamp, p.size());

    Rng rng(12345);
    double seen = 0, weights = 0;
    for (int k = 0; k < 200000; ++k) {
        const Vec3 x(rng.uniform(), rng.uniform(), 1e-4);
        const Vec3 y(0.4 + 0.2 * rng.uniform(), 0.4 + 0.2 * rng.uniform(), 1 - 1e-4);
        const Vec3 d = y - x;
        const double w = d.z() * d.z() / (d.squaredNorm() * d.squaredNorm());  // the kernel, cos cos / r^2
        weights += w;
        seen += rays->occluded(x, y) ? 0 : w;
    }
    const double expected = seen / weights;
    ASSERT_GT(expected, 0.02);
    ASSERT_LT(expected, 0.1);

    // The mean's bound: four of its standard errors over the seeds, plus 1% for the reference's own.
    const int seeds = 100000;
    double sum = 0, squares = 0;
    for (int s = 0; s < seeds; ++s) {
        const double f = visibleFraction(p, *rays, floor, lamp, 1, 1, false, 4, uint64_t(s)).fraction;
        sum += f, squares += f * f;
    }
    const double mean = sum / seeds, error = std::sqrt(std::max(0.0, squares / seeds - mean * mean) / seeds);
    EXPECT_NEAR(mean, expected, 4 * error + 0.01 * expected) << "reference share " << expected;
    EXPECT_LT(4 * error, 0.05 * expected) << "too few seeds to tell";
}

// The variance frontFormFactor states for the lamp seen through the hole (v (1 - v) / (m - 1) of its
// measuring rays), averaged over 20,000 seeds, against the spread of its estimates over those seeds,
// the independent measure of the same noise. Binomial, so the gain of the strata is not in it, as in
// the gathers' stated noise: measured, 2.08 times the spread. It must not fall below the spread (a
// variance over m^2, or not scaled by the unoccluded factor, or none: far below) nor pass 3 times it.
TEST(FormFactorMatrix, ALampSeenThroughAHoleStatesTheNoiseItsEstimatesHave) {
    const HoleScene h = holeScene();
    FormFactorSettings settings;
    const int seeds = 20000;
    double sum = 0, squares = 0, stated = 0;
    for (int s = 1; s <= seeds; ++s) {
        settings.seed = uint64_t(s);
        double variance = -1;
        const double f = frontFormFactor(h.patches, *h.rays, h.floor, h.lamp, settings, nullptr, &variance);
        ASSERT_GE(variance, 0.0);
        sum += f, squares += f * f, stated += variance / seeds;
    }
    const double mean = sum / seeds, spread = (squares - seeds * mean * mean) / (seeds - 1);
    ASSERT_GT(mean, 0.0);
    EXPECT_GT(stated / spread, 0.9) << "stated " << stated << ", spread " << spread;
    EXPECT_LT(stated / spread, 3.0) << "stated " << stated << ", spread " << spread;
}

// A row cast again (castMoreRays' pass, raysFor) measures its lamp again with more visibility rays
// (up to 8x, with its gather's share), on rays of its own: the floor's entry for the lamp through the
// hole spreads over 64 seeds at most half as much as the first pass's (8x the rays: about 0.35x),
// and its stated variance falls with it. Reusing the first pass's entries leaves the spread as it was.
TEST(RayFormFactors, ARowCastAgainMeasuresItsLampAgainWithMoreRays) {
    const HoleScene h = holeScene();
    const size_t n = h.patches.size();
    std::vector<char> analytic(n, 0), emitting(n, 0);
    analytic[h.lamp] = emitting[h.lamp] = 1;
    std::vector<int> raysFor(n, 0);
    raysFor[h.floor] = 16 * 144;
    double first[3] = {0, 0, 0}, again[3] = {0, 0, 0};  // sum, squares, stated variance
    const int seeds = 64;
    for (int s = 1; s <= seeds; ++s) {
        FormFactorSettings settings;
        settings.seed = uint64_t(s);
        for (const bool more : {false, true}) {
            const FormFactorMatrix F = castFormFactors(h.patches, *h.rays, settings, analytic, emitting, nullptr,
                                                       more ? raysFor : std::vector<int>());
            const double f = F(h.floor, h.lamp);
            double* m = more ? again : first;
            m[0] += f, m[1] += f * f;
            for (const auto& e : F.entryVariance)
                if (size_t(e.row) == h.floor && size_t(e.column) == h.lamp) m[2] += e.variance;
        }
    }
    auto spread = [&](const double* m) { return std::sqrt((m[1] - m[0] * m[0] / seeds) / (seeds - 1)); };
    ASSERT_GT(first[0], 0.0);
    EXPECT_LT(spread(again), 0.5 * spread(first)) << "first " << spread(first) << ", again " << spread(again);
    EXPECT_LT(again[2], 0.5 * first[2]) << "the stated variance falls with it";
    EXPECT_NEAR(again[0] / seeds, first[0] / seeds, 4 * spread(first) / std::sqrt(seeds)) << "the same mean";
}

// Shaft proofs (solver/shafts.h): where the shaft between two polygons is declared clear, no segment
// between them may meet an occluder (checked segment by segment against every patch and sphere),
// and proofs are made where the occluders stand aside.
namespace {

bool segmentHitsSphere(const Vec3& p, const Vec3& q, const RaySphere& s) {
    const Vec3 d = q - p;
    const double t = std::clamp((s.center - p).dot(d) / d.squaredNorm(), 0.0, 1.0);
    return (p + t * d - s.center).norm() < s.radius;
}

ShaftEnd square(double z, double size, const Vec3& normal) {
    ShaftEnd e;
    e.corner = {Vec3(0, 0, z), Vec3(size, 0, z), Vec3(size, size, z), Vec3(0, size, z)};
    e.normal = normal;
    return e;
}

}  // namespace

TEST(Shafts, ATriangleAcrossTheShaftBlocksItAndBesideItDoesNot) {
    const ShaftEnd low = square(0, 1, Vec3::UnitZ()), high = square(1, 1, -Vec3::UnitZ());
    auto with = [](const Vec3& shift) {
        PatchSet p;
        p.add({Vec3(0.2, 0.2, 0.5) + shift, Vec3(0.6, 0.2, 0.5) + shift, Vec3(0.4, 0.6, 0.5) + shift, Vec3::Zero()}, 3,
              0, {0, 1, 2, 2});
        return p;
    };
    EXPECT_FALSE(ClearShafts(with(Vec3::Zero()), {}, {}).clear(low, high));
    EXPECT_TRUE(ClearShafts(with(Vec3(2, 0, 0)), {}, {}).clear(low, high));
    // Touching the shaft's side (x = 1 at the top edge of the triangle) is no proof.
    EXPECT_FALSE(ClearShafts(with(Vec3(0.4, 0, 0)), {}, {}).clear(low, high));
    // An end partly behind the other is no proof either, whatever the occluders.
    ShaftEnd tilted = high;
    tilted.corner[0].z() = -0.1;
    EXPECT_FALSE(ClearShafts(with(Vec3(2, 0, 0)), {}, {}).clear(low, tilted));
    // The ends' own objects: a patch of the lower square's object, coplanar with it, does not block.
    PatchSet floor;
    floor.add({Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3(2, 1, 0), Vec3(1, 1, 0)}, 4, 0, {0, 1, 2, 3});
    EXPECT_TRUE(ClearShafts(floor, {}, {}).clear(low, high));
}

TEST(Shafts, NoSegmentMeetsAnOccluderOfAClearShaft) {
    Rng rng(7);
    int proofs = 0, blocked = 0;
    for (int scene = 0; scene < 300; ++scene) {
        PatchSet patches;
        std::vector<RaySphere> spheres;
        for (int k = 0; k < 4; ++k) {
            const Vec3 c(2.4 * rng.uniform() - 0.7, 2.4 * rng.uniform() - 0.7, 0.1 + 0.8 * rng.uniform());
            auto jitter = [&]() -> Vec3 {
                return 0.6 * Vec3(rng.uniform() - 0.5, rng.uniform() - 0.5, rng.uniform() - 0.5);
            };
            if (rng.uniform() < 0.5)
                patches.add({c + jitter(), c + jitter(), c + jitter(), Vec3::Zero()}, 3, k + 1, {0, 1, 2, 2});
            else {  // a quad, not quite flat
                const Vec3 u = jitter(), v = jitter();
                patches.add({c, c + u, c + u + v + 0.05 * jitter(), c + v}, 4, k + 1, {0, 1, 2, 3});
            }
        }
        if (rng.uniform() < 0.3)
            spheres.push_back({Vec3(3 * rng.uniform() - 1, 3 * rng.uniform() - 1, 0.2 + 0.6 * rng.uniform()),
                               0.05 + 0.2 * rng.uniform()});
        const ShaftEnd low = square(0, 0.5, Vec3::UnitZ());
        ShaftEnd high = square(1, 0.3, -Vec3::UnitZ());
        const Vec3 shift(0.4 * rng.uniform(), 0.4 * rng.uniform(), 0);
        for (Vec3& c : high.corner) c += shift;
        const bool clear = ClearShafts(patches, spheres, {}).clear(low, high);
        bool hit = false;
        for (int s = 0; s < 4000 && !hit; ++s) {
            const Vec3 p = low.corner[0] + rng.uniform() * (low.corner[1] - low.corner[0]) +
                           rng.uniform() * (low.corner[3] - low.corner[0]);
            const Vec3 q = high.corner[0] + rng.uniform() * (high.corner[1] - high.corner[0]) +
                           rng.uniform() * (high.corner[3] - high.corner[0]);
            for (size_t i = 0; i < patches.size() && !hit; ++i) hit = segmentCrossesPatch(patches, i, p, q, 0);
            for (const RaySphere& sphere : spheres) hit = hit || segmentHitsSphere(p, q, sphere);
        }
        EXPECT_FALSE(clear && hit) << "scene " << scene << ": declared clear, but a segment meets an occluder";
        proofs += clear;
        blocked += hit;
    }
    // Most of these scenes leave the shaft free or block it plainly: proofs are made.
    EXPECT_GT(proofs, 60) << "blocked " << blocked;
    EXPECT_GT(blocked, 60);
    std::printf("shaft proofs: %d of 300 scenes clear, %d with a segment blocked\n", proofs, blocked);
}

TEST(Shafts, ProvedColumnsChangeNoFormFactorAndSpareRays) {
    // A lamp column proved in full view takes no visibility rays; the rays would all have arrived,
    // so every entry, and the solution, stay the same bit for bit.
    for (const char* name : {"cornell-box.json", "cornell-glass.json"}) {
        const Scene scene = test::sceneFromJson(test::sceneFile(name));
        SolveResult r[2];
        uint64_t rays[2];
        for (int proofs = 0; proofs < 2; ++proofs) {
            SolveOptions o;
            o.meshing.targetPatches = 800;
            o.formFactors.method = "rays";
            o.formFactors.clearShafts = proofs == 1;
            r[proofs] = solveScene(scene, o);
            rays[proofs] = r[proofs].counters.at("form_factors.visibility_rays");
        }
        ASSERT_EQ(r[0].solution.B.size(), r[1].solution.B.size());
        for (size_t i = 0; i < r[0].solution.B.size(); ++i)
            ASSERT_TRUE((r[0].solution.B[i] == r[1].solution.B[i]).all()) << name << ": patch " << i;
        EXPECT_LT(double(rays[1]), 0.9 * double(rays[0])) << name << ": " << rays[1] << " against " << rays[0];
    }
}
