#include "solver/solve.h"

#include <cmath>
#include <fstream>
#include <numeric>
#include <sstream>

#include "core/error.h"
#include "core/log.h"
#include "core/timer.h"
#include "mesh/refine.h"
#include "solver/radiosity/vertex_radiosity.h"
#include "solver/tracer.h"
#include "solver/visibility.h"

namespace penumbra {
namespace {

double procKilobytes(const char* file, const char* key) {
    std::ifstream in(file);
    std::string line;
    while (std::getline(in, line))
        if (line.rfind(key, 0) == 0) {
            std::istringstream fields(line.substr(std::string(key).size()));
            double kb = 0;
            fields >> kb;
            return kb * 1024;
        }
    return 0;
}

// A closed scene whose surfaces all reflect everything in some channel, with emission in it, has no
// steady state: the light grows without bound. Refuse it rather than iterate forever.
void checkSteadyState(const Scene& scene, const RadiositySystem& s, const std::vector<double>& rows) {
    double area = 0, loss = 0;
    for (size_t i = 0; i < s.size(); ++i) {
        area += s.area[i];
        loss += s.area[i] * std::max(0.0, 1 - rows[i]);
    }
    const double escapeFraction = area > 0 ? loss / area : 1;
    for (int c = 0; c < 3; ++c) {
        bool allOne = true, emits = false;
        for (size_t i = 0; i < s.size(); ++i) {
            allOne = allOne && s.reflectance[i][c] >= 1;
            emits = emits || s.emission[i][c] > 0;
        }
        if (allOne && emits && escapeFraction < 1e-4)
            throw Error(cat(scene.path, ": no steady state: the scene is closed (", escapeFraction,
                            " of the light escapes) and every surface has reflectance 1 in channel ", c,
                            ", so light emitted there is never absorbed; give some surface a reflectance below 1"));
    }
}

}  // namespace

double availableMemoryBytes() { return procKilobytes("/proc/meminfo", "MemAvailable:"); }
double peakMemoryBytes() { return procKilobytes("/proc/self/status", "VmHWM:"); }

bool resetPeakMemory() {
    std::ofstream clear("/proc/self/clear_refs");
    clear << "5";   // 5: reset the peak resident set size to the current one
    clear.flush();
    return bool(clear);
}

namespace {

// One solve of the matrix system on the patches in `r`: form factors, specular transport, the
// iterative solve and the power balance. Stage times add to those already in `r`.
void solveMatrix(const Scene& scene, const SolveOptions& options, const StepObserver& observer, SolveResult& r) {
    auto solver = makeSolver(options.solver);
    const size_t n = r.patches.size();
    const double budget = options.maxMemoryBytes > 0 ? options.maxMemoryBytes : availableMemoryBytes();
    const double need = double(formFactorMatrixBytes(n)) + 400.0 * double(n);
    if (budget > 0 && need > budget) {
        const size_t fit = size_t(std::sqrt(budget / sizeof(float)));
        throw Error(cat("the form-factor matrix of ", n, " patches needs ", need / (1 << 20), " MiB, more than the ",
                        budget / (1 << 20), " MiB allowed (--max-memory): about ", fit,
                        " patches fit; lower --patches or raise --max-memory"));
    }
    logInfo("form-factor matrix: ", n, " x ", n, " floats, ", double(formFactorMatrixBytes(n)) / (1 << 20), " MiB");

    Timer ffTimer;
    r.F = FormFactorMatrix();   // the previous round's matrix goes before the next one is made
    r.rays = std::make_shared<RayScene>(r.patches);
    r.F = computeFormFactors(r.patches, *r.rays, options.formFactors);
    r.secondsFormFactors += ffTimer.seconds();
    const std::vector<double> rows = rowSums(r.F);
    r.rowSumMin = n ? *std::min_element(rows.begin(), rows.end()) : 0;
    r.rowSumMax = n ? *std::max_element(rows.begin(), rows.end()) : 0;

    r.system = buildSystem(scene, r.patches);
    if (scene.hasSpecular()) {
        const SceneTracer tracer(scene, r.patches);
        SpecularSettings specular = options.specular;
        specular.seed = options.formFactors.seed;
        r.system.transport = computeSpecularTransport(scene, r.patches, r.F, tracer, specular);
        r.secondsSpecular += r.system.transport.seconds;
    } else {
        logInfo("no mirrors or glass in the scene: no specular transport");
    }
    checkSteadyState(scene, r.system, rows);
    Timer solveTimer;
    r.solution = solver->solve(r.F, r.system, options.solverSettings, observer);
    r.secondsSolve += solveTimer.seconds();
    logInfo(options.solver, ": ", r.solution.iterations, " iterations, residual ", r.solution.residual, " in ",
            solveTimer.seconds(), " s");
    r.power = powerBalance(r.system, r.F, r.solution.B);
    Timer vertexTimer;
    r.corners = options.gatherVertices ? gatherCorners(r.patches, r.system, r.F, r.solution.display, *r.rays)
                                       : interpolateCorners(r.patches, r.solution.display);
    r.secondsVertices += vertexTimer.seconds();
}

}  // namespace

SolveResult solveScene(const Scene& scene, const SolveOptions& options, const StepObserver& observer) {
    SolveResult r;
    makeSolver(options.solver);   // an unknown name fails before any work
    r.solverName = options.solver;

    Timer meshTimer;
    r.patches = meshScene(scene, options.meshing);
    r.secondsMeshing = meshTimer.seconds();
    solveMatrix(scene, options, observer, r);

    const RefineSettings& refine = options.refine;
    if (!(refine.tolerance > 0)) return r;
    // The finest patches allowed: maxLevels halvings of the first mesh's edge length.
    const double firstArea = std::accumulate(r.patches.area.begin(), r.patches.area.end(), 0.0) / double(r.patches.size());
    const double minArea = firstArea / std::pow(4.0, refine.maxLevels);
    r.refinement.push_back({r.patches.size(), 0, 0, 0, r.secondsMeshing + r.secondsFormFactors + r.secondsSpecular + r.secondsSolve + r.secondsVertices});
    for (int round = 1; round <= refine.maxRounds; ++round) {
        Timer timer;
        const size_t n = r.patches.size();
        // At most a quarter of the patches per round, the worst first: each round's solve then
        // judges the patches that the last one left, so that the budget goes where light changes.
        const size_t budgetRoom = size_t(refine.maxPatches) > n ? (size_t(refine.maxPatches) - n) / 3 : 0;
        const size_t room = std::min(budgetRoom, std::max<size_t>(1, n / 4));
        SplitChoice choice = chooseSplits(r.patches, r.system, r.F, r.solution.B, r.corners, *r.rays, refine, minArea, room);
        const size_t chosen = size_t(std::count(choice.split.begin(), choice.split.end(), 1));
        if (chosen == 0) {
            logInfo("refinement: converged after ", round - 1, " rounds: no patch differs from its neighbours by more than ",
                    refine.tolerance, (budgetRoom == 0 ? " or the patch budget is spent" : ""));
            break;
        }
        PatchSet finer = splitPatches(r.patches, choice.split);
        // Splits the 2:1 rule adds can overrun the budget: keep the strongest half until it fits.
        for (size_t want = chosen / 2; finer.size() > size_t(refine.maxPatches) && want > 0; want /= 2) {
            choice = chooseSplits(r.patches, r.system, r.F, r.solution.B, r.corners, *r.rays, refine, minArea, want);
            finer = splitPatches(r.patches, choice.split);
        }
        if (finer.size() > size_t(refine.maxPatches)) {
            logInfo("refinement: stopped: the next round would pass the budget of ", refine.maxPatches, " patches");
            break;
        }
        const size_t made = size_t(std::count(choice.split.begin(), choice.split.end(), 1));
        logInfo("refinement round ", round, ": split ", made, " of ", n, " patches (", choice.byGradient, " by gradient, ",
                choice.byShadow, " by shadow edges, ", made - std::min(made, chosen), " more for the 2:1 rule) -> ",
                finer.size(), " patches");
        r.patches = std::move(finer);
        r.secondsMeshing += timer.seconds();
        solveMatrix(scene, options, observer, r);
        r.refinement.push_back({r.patches.size(), choice.byGradient, choice.byShadow, made,
                                r.secondsMeshing + r.secondsFormFactors + r.secondsSpecular + r.secondsSolve + r.secondsVertices});
    }
    return r;
}

}  // namespace penumbra
