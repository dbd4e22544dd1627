// Hierarchical radiosity against the matrix solve and the closed forms: the same radiosity per
// object, links that grow about linearly with the elements, refinement along partial visibility,
// the closed form away from it, and the choice `--solver auto` makes.
#include <gtest/gtest.h>

#include <map>

#include "fixtures.h"

namespace penumbra {
namespace {

using test::sceneFile;

std::map<int, Rgb> objectMeans(const SolveResult& r) {
    std::map<int, Rgb> sum;
    std::map<int, double> area;
    for (size_t i = 0; i < r.patches.size(); ++i) {
        sum.try_emplace(r.patches.object[i], Rgb::Zero()).first->second += r.patches.area[i] * r.solution.B[i];
        area[r.patches.object[i]] += r.patches.area[i];
    }
    for (auto& [o, s] : sum) s /= area[o];
    return sum;
}

TEST(HierarchySlow, ReachesTheMatrixSolvesRadiosityPerObject) {
    const std::string box = sceneFile("cornell-box.json");
    // The matrix in its accurate mode (analytic form factors): the default's ray-cast rows carry a few
    // percent of noise on a block face of 25 patches at this size.
    SolveOptions accurate;
    accurate.meshing.targetPatches = 1500;
    accurate.formFactors.method = "analytic";
    // On the uniform mesh, as the hierarchy's leaves: the default mesh graded towards contacts moves
    // the block faces by up to 3.4% towards the 13,056-patch reference, which the hierarchy does not.
    accurate.grading.levels = 0;
    const SolveResult matrix = solveScene(test::sceneFromJson(box), accurate);
    const SolveResult hierarchy = test::solve(box, 1500, "hierarchical");
    EXPECT_EQ(hierarchy.solverName, "hierarchical");
    EXPECT_EQ(hierarchy.F.size(), 0u) << "no matrix";
    const auto a = objectMeans(matrix), b = objectMeans(hierarchy);
    ASSERT_EQ(a.size(), b.size());
    for (const auto& [o, m] : a)
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(b.at(o)[c], m[c], 0.05 * m[c]) << "object " << o << " channel " << c;
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(hierarchy.power.totalAbsorbed[c], matrix.power.totalAbsorbed[c],
                    0.01 * matrix.power.totalAbsorbed[c]);
    }
    test::expectBalanceByRays(box, hierarchy, 2e-3, 256, "hierarchical");
}

TEST(HierarchySlow, LinksGrowAboutLinearlyWithTheElements) {
    const std::string box = sceneFile("cornell-box.json");
    SolveOptions o;
    o.solver = "hierarchical";
    o.hierarchyRoots = 64;
    o.meshing.targetPatches = 1000;
    const SolveResult coarse = solveScene(test::sceneFromJson(box), o);
    o.meshing.targetPatches = 16000;
    const SolveResult fine = solveScene(test::sceneFromJson(box), o);
    const double nc = double(coarse.hierarchy.leaves), nf = double(fine.hierarchy.leaves);
    ASSERT_GT(nf, 3 * nc);
    const double perLeafCoarse = double(coarse.hierarchy.links) / nc, perLeafFine = double(fine.hierarchy.links) / nf;
    // Linear: the links per leaf barely change while the leaves grow; the matrix's grow as n.
    EXPECT_LT(perLeafFine, 1.5 * perLeafCoarse)
        << perLeafCoarse << " links per leaf at " << nc << " leaves, " << perLeafFine << " at " << nf;
    EXPECT_LT(double(fine.hierarchy.links), 0.1 * nf * nf);
    EXPECT_LT(fine.hierarchy.bytes, 0.5 * double(formFactorMatrixBytes(size_t(nf))));
}

using test::pointToRectangle;

TEST(Hierarchy, RefinesAlongThePenumbraAndMeetsTheClosedFormAwayFromIt) {
    SolveOptions o;
    o.solver = "hierarchical";
    o.meshing.targetPatches = 200000;  // the finest elements allowed: far below what the light needs
    o.hierarchyRoots = 16;
    const SolveResult r = solveScene(test::sceneFromJson(test::lampOverFloor(true)), o);
    // Roots of 0.5 m: the floor's outer twelve (off the axis by more than 0.5 m) lie wholly
    // outside the penumbra, and every link landing there stays there, so push-pull keeps the power
    // they receive: it must be the closed form's, integrated over them (a fine midpoint rule).
    double bandArea = 0, farArea = 0, farPower = 0;
    int band = 0, far = 0;
    const double peak = 0.5 * kPi * 10 * pointToRectangle(-0.1, 0.1, -0.1, 0.1, 1);
    for (size_t i = 0; i < r.patches.size(); ++i) {
        if (r.patches.object[i] != 0) continue;
        const double d = r.patches.centroid[i].head<2>().cwiseAbs().maxCoeff();
        if (d > 0.3 && d < 0.5) bandArea += r.patches.area[i], ++band;
        if (d > 0.5) farArea += r.patches.area[i], ++far, farPower += r.patches.area[i] * r.solution.B[i][0];
        if (d < 0.25) {
            EXPECT_LT(r.solution.B[i][0], 1e-3 * peak) << "umbra";
        }
    }
    double exact = 0;
    const int grid = 400;
    for (int a = 0; a < grid; ++a)
        for (int b = 0; b < grid; ++b) {
            const double x = -1 + (a + 0.5) * 2.0 / grid, y = -1 + (b + 0.5) * 2.0 / grid;
            if (std::max(std::abs(x), std::abs(y)) <= 0.5) continue;
            exact += 0.5 * kPi * 10 * pointToRectangle(-0.1 - x, 0.1 - x, -0.1 - y, 0.1 - y, 1) * (4.0 / grid / grid);
        }
    EXPECT_NEAR(farPower, exact, 5e-3 * exact);
    ASSERT_GT(band, 0);
    ASSERT_GT(far, 0);
    EXPECT_LT(bandArea / band, farArea / far) << band << " leaves in the penumbra, " << far << " far off";
    EXPECT_GT(r.hierarchy.partlyVisibleLinks, 0u);
    // The same floor without the square: what the band gets without partial visibility.
    const SolveResult unshadowed = solveScene(test::sceneFromJson(test::lampOverFloor(false), "open.json"), o);
    double openArea = 0;
    int openBand = 0;
    for (size_t i = 0; i < unshadowed.patches.size(); ++i) {
        const double d = unshadowed.patches.centroid[i].head<2>().cwiseAbs().maxCoeff();
        if (unshadowed.patches.object[i] == 0 && d > 0.3 && d < 0.5) openArea += unshadowed.patches.area[i], ++openBand;
    }
    ASSERT_GT(openBand, 0);
    // One more level over half the band at least (the flag refines until a link carries a tenth of
    // the tolerance: 2.9x smaller leaves here, measured).
    EXPECT_LT(bandArea / band, 0.5 * openArea / openBand) << "the penumbra's leaves against the same floor unshadowed";
}

TEST(Hierarchy, RefusesMirrorsAndGlassByName) {
    try {
        test::solve(sceneFile("cornell-glass.json"), 300, "hierarchical");
        FAIL() << "expected an error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("mirror or glass"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("object '"), std::string::npos) << e.what();
    }
}

TEST(Hierarchy, AutoPicksTheMatrixWhenItFitsAndTheHierarchyWhenNot) {
    SolveOptions o;  // solver "auto" by default
    o.meshing.targetPatches = 100;
    o.formFactors.method = "rays";  // the choice is under test, not the form factors: the fast ones
    const Scene box = test::sceneFromJson(sceneFile("cornell-box.json"));
    const SolveResult small = solveScene(box, o);
    EXPECT_EQ(small.solverName, "gauss-seidel");
    EXPECT_NE(small.solverReason.find("MiB"), std::string::npos) << small.solverReason;
    // 100 patches' ray-cast rows need 374 kB: over half of this, which the hierarchy's elements and
    // links fit in (it stops, refused, past its budget too).
    o.maxMemoryBytes = 700e3;
    const SolveResult tight = solveScene(box, o);
    EXPECT_EQ(tight.solverName, "hierarchical");
    EXPECT_NE(tight.solverReason.find("hierarchy"), std::string::npos) << tight.solverReason;
    o.maxMemoryBytes = 0;
    o.specular.pathsPerPatch = 256;  // the choice, not the caustic, is under test
    const SolveResult glass = solveScene(test::sceneFromJson(sceneFile("cornell-glass.json"), "glass.json"), o);
    EXPECT_EQ(glass.solverName, "gauss-seidel") << "mirrors and glass need the matrix";
}

}  // namespace
}  // namespace penumbra
