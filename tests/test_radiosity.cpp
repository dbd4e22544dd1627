// The radiosity solve against physics: the white furnace B = E / (1 - rho) (up to rho = 0.999),
// closed-form energy exchange between two squares, power balance, energy at every step, and the
// convergence behaviour of the three solvers.
#include <gtest/gtest.h>

#include <cmath>

#include "core/parallel.h"
#include "fixtures.h"

using namespace penumbra;

namespace {

using test::sceneFile;
using test::solve;

std::string cornellBox() { return sceneFile("cornell-box.json"); }

}  // namespace

class Furnace : public ::testing::TestWithParam<std::tuple<double, std::string>> {};

TEST_P(Furnace, EveryPatchReachesEOverOneMinusRho) {
    const auto [rho, solver] = GetParam();
    const double Le = 1.0;  // radiance: exitance E = pi
    const std::string material = cat(R"({"type": "diffuse", "reflectance": )", rho, R"(, "emission": )", Le, "}");
    const SolveResult r = solve(test::closedCube(material), 150, solver, 1e-7);
    const double expected = kPi * Le / (1 - rho);
    ASSERT_TRUE(r.solution.converged);
    for (size_t i = 0; i < r.patches.size(); ++i)
        for (int c = 0; c < 3; ++c)
            ASSERT_NEAR(r.solution.B[i][c], expected, 0.005 * expected) << "patch " << i << ", rho " << rho;
}

TEST(Furnace, SceneFileReachesItsClosedForm) {
    const SolveResult r = solve(sceneFile("white-furnace.json"), 200);
    const double expected = kPi * 1.0 / (1 - 0.9);
    for (size_t i = 0; i < r.patches.size(); ++i) ASSERT_NEAR(r.solution.B[i][1], expected, 0.005 * expected);
}

INSTANTIATE_TEST_SUITE_P(Extremes, Furnace,
                         ::testing::Combine(::testing::Values(0.5, 0.9, 0.99, 0.999),
                                            ::testing::Values("jacobi", "gauss-seidel", "southwell", "hierarchical")));

class TwoSquares : public ::testing::TestWithParam<std::string> {};

TEST_P(TwoSquares, ExchangeTheClosedFormPower) {
    // scenes/parallel-squares.json: a black emitter and a black receiver, unit squares 1 apart; the
    // receiver absorbs pi L_e A F = pi * 2 * 0.19982 W; the rest escapes.
    const SolveResult r = solve(sceneFile("parallel-squares.json"), 200, GetParam());
    Rgb receiver = Rgb::Zero();
    for (size_t i = 0; i < r.patches.size(); ++i)
        if (r.patches.object[i] == 1) receiver += r.power.absorbed[i];
    const double expected = kPi * 2 * 0.19982;
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(receiver[c], expected, 0.005 * expected);
        EXPECT_NEAR(r.power.escaped[c], kPi * 2 - expected, 0.005 * expected);
    }
}

INSTANTIATE_TEST_SUITE_P(Energy, TwoSquares, ::testing::Values("gauss-seidel", "hierarchical"));

TEST(Energy, OpenScenePowerBalances) {
    const std::string json = R"({"materials": {"lamp": {"type": "diffuse", "reflectance": 0.3, "emission": [3, 2, 1]},
                                              "grey": {"type": "diffuse", "reflectance": [0.9, 0.5, 0.1]}},
      "objects": [
        {"name": "lamp", "type": "quad", "material": "lamp", "vertices": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]},
        {"name": "wall", "type": "quad", "material": "grey", "vertices": [[0,0,0],[0,0,1],[0,1,1],[0,1,0]]},
        {"name": "card", "type": "triangle", "material": "grey", "vertices": [[0,0,1],[0,1,1],[1,1,1]]}]})";
    const SolveResult r = solve(json, 300);
    for (int c = 0; c < 3; ++c) {
        const double e = r.power.totalEmitted[c];
        EXPECT_NEAR(e, kPi * (c == 0 ? 3 : c == 1 ? 2 : 1), 1e-9 * e);
        EXPECT_GT(r.power.escaped[c], 0.3 * e);  // an open scene loses most of its light
    }
    test::expectBalanceByRays(json, r);
}

class CornellPower : public ::testing::TestWithParam<std::string> {};

TEST_P(CornellPower, Balances) {
    const SolveResult r = solve(cornellBox(), 200, GetParam());
    for (int c = 0; c < 3; ++c) {
        const double e = r.power.totalEmitted[c];
        // The lamp's area is 0.13 x 0.105 m^2 and its exitance pi L_e.
        const double lamp = kPi * Rgb(17, 12, 4)[c] * 0.130 * 0.105;
        EXPECT_NEAR(e, lamp, 1e-9 * lamp);
        EXPECT_GT(r.power.escaped[c], 0);
    }
    test::expectBalanceByRays(cornellBox(), r, 2e-3, 1024, GetParam());
}

INSTANTIATE_TEST_SUITE_P(Energy, CornellPower, ::testing::Values("gauss-seidel", "hierarchical"));

class EnergyEveryStep : public ::testing::TestWithParam<std::string> {};

TEST_P(EnergyEveryStep, NoSolverEverGainsPower) {
    // From below, without over-relaxation, B only grows towards the solution: at no step may the
    // absorbed power exceed the emitted power, nor any radiosity fall.
    std::vector<std::vector<Rgb>> steps;
    const SolveResult r =
        solve(cornellBox(), 150, GetParam(), 1e-6, [&](int, const std::vector<Rgb>& B) { steps.push_back(B); });
    ASSERT_GT(steps.size(), 3u);
    std::vector<Rgb> previous(r.patches.size(), Rgb::Zero());
    for (const auto& B : steps) {
        const PowerBalance p = powerBalance(r.system, r.F, B);
        for (int c = 0; c < 3; ++c) ASSERT_LE(p.totalAbsorbed[c], p.totalEmitted[c] * (1 + 1e-9));
        for (size_t i = 0; i < B.size(); ++i)
            for (int c = 0; c < 3; ++c) ASSERT_GE(B[i][c], previous[i][c] * (1 - 1e-12)) << "patch " << i;
        previous = B;
    }
}

INSTANTIATE_TEST_SUITE_P(Solvers, EnergyEveryStep, ::testing::Values("jacobi", "gauss-seidel", "southwell"));

// One matrix for all three solvers, so they are compared on exactly the same system.
class Convergence : public ::testing::Test {
protected:
    static void SetUpTestSuite() { box_ = new SolveResult(solve(cornellBox(), 300, "gauss-seidel", 1e-10)); }
    static void TearDownTestSuite() { delete box_; }
    static RadiositySolution run(const std::string& name) {
        SolverSettings settings;
        settings.tolerance = 1e-10;
        settings.maxIterations = 200000;
        return makeSolver(name)->solve(box_->F, box_->system, settings);
    }
    static SolveResult* box_;
};
SolveResult* Convergence::box_ = nullptr;

TEST_F(Convergence, AllSolversReachTheSameSolution) {
    const std::vector<Rgb>& gs = box_->solution.B;
    for (const char* name : {"jacobi", "southwell"}) {
        const RadiositySolution other = run(name);
        ASSERT_TRUE(other.converged) << name;
        for (size_t i = 0; i < gs.size(); ++i)
            for (int c = 0; c < 3; ++c)
                ASSERT_NEAR(other.B[i][c], gs[i][c], 1e-5 * std::max(gs[i][c], 1e-3)) << name << ", patch " << i;
    }
}

TEST_F(Convergence, ResidualFallsMonotonicallyAndGaussSeidelIsFaster) {
    const RadiositySolution jacobi = run("jacobi"), gs = run("gauss-seidel");
    for (const RadiositySolution* r : {&jacobi, &gs}) {
        ASSERT_TRUE(r->converged);
        for (size_t k = 1; k < r->history.size(); ++k)
            EXPECT_LT(r->history[k].residual, r->history[k - 1].residual) << "step " << k;
    }
    EXPECT_LT(gs.iterations, jacobi.iterations);
}

TEST_F(Convergence, GaussSeidelsResidualBoundsTheTrueOne) {
    // Gauss-Seidel reports each pass's change, not a second matrix pass: that change must bound the
    // residual of what the pass left, measured afresh from the equation (system.h says why).
    for (double tolerance : {1e-2, 1e-4, 1e-6}) {
        SolverSettings settings;
        settings.tolerance = tolerance;
        const RadiositySolution gs = makeSolver("gauss-seidel")->solve(box_->F, box_->system, settings);
        ASSERT_TRUE(gs.converged);
        const double truth = relativeResidual(box_->system, gs.B, gatherIrradiance(box_->system, box_->F, gs.B));
        EXPECT_LE(truth, gs.residual) << "tolerance " << tolerance;
        EXPECT_LE(truth, tolerance);
        // And not so loose that it wastes passes: within the reflectance of the true residual's order.
        EXPECT_GT(truth, 0.05 * gs.residual) << "tolerance " << tolerance;
    }
}

class Determinism : public ::testing::TestWithParam<std::string> {};

TEST_P(Determinism, ResultsDoNotDependOnTheThreadCount) {
    // Randomness is seeded per patch pair (or link), never per thread: one thread and two give the
    // same bits.
    const int patches = test::kSanitized ? 100 : 600;
    setThreadCount(1);
    const SolveResult one = solve(cornellBox(), patches, GetParam());
    setThreadCount(2);
    const SolveResult two = solve(cornellBox(), patches, GetParam());
    setThreadCount(0);
    ASSERT_EQ(one.patches.size(), two.patches.size());
    for (size_t i = 0; i < one.patches.size(); ++i)
        for (int c = 0; c < 3; ++c) ASSERT_EQ(one.solution.B[i][c], two.solution.B[i][c]) << "patch " << i;
}

INSTANTIATE_TEST_SUITE_P(Solvers, Determinism, ::testing::Values("gauss-seidel", "hierarchical"));
