// Iterative solvers for B = E + diag(rho) F B: Jacobi, Gauss-Seidel and Southwell shooting, chosen by
// name from one table. All start from below (B = E, or B = 0 with everything unshot) and never
// over-relax, so the residual stays non-negative and no step gains power.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "solver/radiosity/system.h"

namespace penumbra {

struct SolverSettings {
    double tolerance = 1e-6;    // stop when the relative residual (unshot power fraction) is below
    int maxIterations = 20000;  // sweeps (Jacobi, Gauss-Seidel) or n-shot rounds (Southwell)
};

struct ConvergenceStep {
    int iteration;
    double residual;
    double seconds;
};

struct RadiositySolution {
    std::vector<Rgb> B;        // exitance, W/m^2: what the report and the power balance use
    std::vector<Rgb> display;  // B plus the ambient estimate of light not yet shot (Southwell)
    int iterations = 0;
    double residual = 0;
    bool converged = false;
    std::vector<ConvergenceStep> history;
    double seconds = 0;
};

// Called after every iteration with the current B (tests use it to watch energy at every step).
using StepObserver = std::function<void(int iteration, const std::vector<Rgb>& B)>;

class RadiositySolver {
public:
    virtual ~RadiositySolver() = default;
    virtual RadiositySolution solve(const FormFactorMatrix& F, const RadiositySystem& system,
                                    const SolverSettings& settings, const StepObserver& observer = {}) const = 0;
};

// The matrix solvers' names, in the order shown to users, and what each does.
std::vector<std::string> solverNames();
std::string solverSummary(const std::string& name);
// Throws Error listing the known names when `name` is not one of them.
std::unique_ptr<RadiositySolver> makeSolver(const std::string& name);

}  // namespace penumbra
