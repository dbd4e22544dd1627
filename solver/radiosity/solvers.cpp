#include "solver/radiosity/solvers.h"

#include "core/error.h"
#include "core/log.h"
#include "core/progress.h"
#include "core/timer.h"

namespace penumbra {
namespace {

// Shared bookkeeping: history, progress, stop test.
struct Run {
    const SolverSettings& settings;
    RadiositySolution& out;
    Timer timer;
    Progress progress;
    Run(const SolverSettings& s, RadiositySolution& o, const char* title)
        : settings(s), out(o), progress(title, s.maxIterations) {}
    // Records the residual of iteration k; returns true when the solve should stop.
    bool record(int k, double residual) {
        out.history.push_back({k, residual, timer.seconds()});
        out.iterations = k;
        out.residual = residual;
        out.converged = residual <= settings.tolerance;
        progress.update();
        return out.converged || k >= settings.maxIterations;
    }
    void finish(const char* name) {
        progress.done();
        out.seconds = timer.seconds();
        if (!out.converged)
            logWarning(name, " stopped after ", out.iterations, " iterations with residual ", out.residual,
                       " above the tolerance ", settings.tolerance, ": raise --max-iterations or loosen --tolerance");
    }
};

class JacobiSolver : public RadiositySolver {
public:
    RadiositySolution solve(const FormFactorMatrix& F, const RadiositySystem& s, const SolverSettings& settings,
                            const StepObserver& observer) const override {
        RadiositySolution out;
        Run run(settings, out, "jacobi");
        std::vector<Rgb> B = s.emission, next(s.size());
        for (int k = 0;; ++k) {
            // next = E + rho F B; its difference from B is the residual of B.
            const std::vector<Rgb> H = gatherIrradiance(s, F, B);
            for (size_t i = 0; i < s.size(); ++i) next[i] = s.emission[i] + s.reflectance[i] * H[i];
            const double residual = relativeResidual(s, B, H);
            if (run.record(k, residual)) break;
            std::swap(B, next);
            if (observer) observer(k + 1, B);
        }
        out.B = B;
        out.display = B;
        run.finish("jacobi");
        return out;
    }
};

class GaussSeidelSolver : public RadiositySolver {
public:
    RadiositySolution solve(const FormFactorMatrix& F, const RadiositySystem& s, const SolverSettings& settings,
                            const StepObserver& observer) const override {
        RadiositySolution out;
        Run run(settings, out, "gauss-seidel");
        // One matrix pass per iteration: the pass's change bounds the residual of what it leaves
        // (system.h), so no second pass measures it. The history starts after the first pass.
        std::vector<Rgb> B = s.emission;
        for (int k = 1;; ++k) {
            const double bound = gaussSeidelPass(s, F, B);
            if (observer) observer(k, B);
            if (run.record(k, bound)) break;
        }
        out.B = B;
        out.display = B;
        run.finish("gauss-seidel");
        return out;
    }
};

// Progressive refinement (Cohen et al. 1988): the patch with the most unshot power shoots it to all
// others through row i of F and reciprocity, F(j,i) = A_i F(i,j) / A_j. An iteration is n shots.
class SouthwellSolver : public RadiositySolver {
public:
    RadiositySolution solve(const FormFactorMatrix& F, const RadiositySystem& s, const SolverSettings& settings,
                            const StepObserver& observer) const override {
        RadiositySolution out;
        Run run(settings, out, "southwell");
        const size_t n = s.size();
        std::vector<Rgb> B(n, Rgb::Zero()), unshot = s.emission;
        double emitted = 0, totalArea = 0;
        Rgb meanReflectance = Rgb::Zero();
        for (size_t i = 0; i < n; ++i) {
            emitted += s.area[i] * s.emission[i].sum();
            totalArea += s.area[i];
            meanReflectance += s.area[i] * s.reflectance[i];
        }
        meanReflectance /= std::max(totalArea, 1e-300);
        auto unshotPower = [&](size_t i) { return s.area[i] * unshot[i].sum(); };
        // Without reciprocity (ray-cast rows, rows scaled to a closed scene) what j gathers from a
        // shooter is the shooter's column, read as a row of the transpose.
        const FormFactorMatrix columns = F.reciprocal ? FormFactorMatrix() : F.transposed();
        double remaining = 0;
        for (size_t i = 0; i < n; ++i) remaining += unshotPower(i);
        for (int k = 0;; ++k) {
            if (run.record(k, emitted > 0 ? remaining / emitted : 0)) break;
            for (size_t shot = 0; shot < n; ++shot) {
                size_t best = 0;
                for (size_t i = 1; i < n; ++i)
                    if (unshotPower(i) > unshotPower(best)) best = i;
                const Rgb dB = unshot[best];
                if (unshotPower(best) <= 0) break;
                B[best] += dB;
                unshot[best] = Rgb::Zero();
                if (!F.reciprocal) {
                    columns.forEachInRow(best,
                                         [&](size_t j, float f) { unshot[j] += s.reflectance[j] * double(f) * dB; });
                } else {
                    // Reciprocity, A_j F(j, best) = A_best F(best, j): row best, read contiguously.
                    const float* row = F.row(best);
                    const double ai = s.area[best];
                    for (size_t j = 0; j < n; ++j)
                        if (row[j] != 0) unshot[j] += s.reflectance[j] * (ai * row[j] / s.area[j]) * dB;
                }
                if (!s.transport.empty())
                    for (size_t t = s.transport.outStart[best]; t < s.transport.outStart[best + 1]; ++t) {
                        const size_t j = size_t(s.transport.outTarget[t]);
                        unshot[j] += s.reflectance[j] * s.transport.outWeight[t] * dB;
                    }
            }
            // The unshot vector is the exact residual E + rho F B - B; summing it afresh each round
            // keeps rounding from accumulating in the running total.
            remaining = 0;
            for (size_t i = 0; i < n; ++i) remaining += unshotPower(i);
            if (observer) observer(k + 1, B);
        }
        out.B = B;
        // Ambient term for display: the unshot power spread over the scene, with its interreflection.
        Rgb ambient = Rgb::Zero();
        for (size_t i = 0; i < n; ++i) ambient += s.area[i] * unshot[i];
        ambient = ambient / std::max(totalArea, 1e-300) / (1 - meanReflectance.min(0.999999));
        out.display.resize(n);
        for (size_t i = 0; i < n; ++i) out.display[i] = B[i] + s.reflectance[i] * ambient;
        run.finish("southwell");
        return out;
    }
};

struct SolverEntry {
    const char* name;
    const char* summary;
    std::unique_ptr<RadiositySolver> (*make)();
};

// The matrix solvers: a new one is one entry here (the command line, its help and the solve's
// registry take their names from this table).
const SolverEntry kSolvers[] = {
    {"jacobi", "sweeps that gather from the last sweep's radiosity",
     [] { return std::unique_ptr<RadiositySolver>(new JacobiSolver); }},
    {"gauss-seidel", "sweeps that gather from the radiosity this sweep already updated (about twice Jacobi's pace)",
     [] { return std::unique_ptr<RadiositySolver>(new GaussSeidelSolver); }},
    {"southwell", "progressive shooting of the largest unshot power, with an ambient term for display",
     [] { return std::unique_ptr<RadiositySolver>(new SouthwellSolver); }},
};

}  // namespace

std::vector<std::string> solverNames() {
    std::vector<std::string> names;
    for (const auto& e : kSolvers) names.push_back(e.name);
    return names;
}

std::string solverSummary(const std::string& name) {
    for (const auto& e : kSolvers)
        if (name == e.name) return e.summary;
    return "";
}

std::unique_ptr<RadiositySolver> makeSolver(const std::string& name) {
    std::string known;
    for (const auto& e : kSolvers) {
        if (name == e.name) return e.make();
        known += cat(known.empty() ? "" : ", ", e.name);
    }
    throw Error(cat("--solver: unknown solver '", name, "' (known: ", known, ")"));
}

}  // namespace penumbra
