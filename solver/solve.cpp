#include "solver/solve.h"

#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/log.h"
#include "core/timer.h"
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

SolveResult solveScene(const Scene& scene, const SolveOptions& options, const StepObserver& observer) {
    SolveResult r;
    auto solver = makeSolver(options.solver);
    r.solverName = options.solver;

    Timer meshTimer;
    r.patches = meshScene(scene, options.meshing);
    r.secondsMeshing = meshTimer.seconds();
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
    r.rays = std::make_shared<RayScene>(r.patches);
    r.F = computeFormFactors(r.patches, *r.rays, options.formFactors);
    r.secondsFormFactors = ffTimer.seconds();
    const std::vector<double> rows = rowSums(r.F);
    r.rowSumMin = n ? *std::min_element(rows.begin(), rows.end()) : 0;
    r.rowSumMax = n ? *std::max_element(rows.begin(), rows.end()) : 0;

    r.system = buildSystem(scene, r.patches);
    if (scene.hasSpecular()) {
        const SceneTracer tracer(scene, r.patches);
        SpecularSettings specular = options.specular;
        specular.seed = options.formFactors.seed;
        r.system.transport = computeSpecularTransport(scene, r.patches, r.F, tracer, specular);
        r.secondsSpecular = r.system.transport.seconds;
    } else {
        logInfo("no mirrors or glass in the scene: no specular transport");
    }
    checkSteadyState(scene, r.system, rows);
    Timer solveTimer;
    r.solution = solver->solve(r.F, r.system, options.solverSettings, observer);
    r.secondsSolve = solveTimer.seconds();
    logInfo(options.solver, ": ", r.solution.iterations, " iterations, residual ", r.solution.residual, " in ",
            r.secondsSolve, " s");
    r.power = powerBalance(r.system, r.F, r.solution.B);
    return r;
}

}  // namespace penumbra
