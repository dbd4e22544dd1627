// The view-independent solve, end to end: mesh the scene, build the ray scene, compute the form
// factors, solve, and account for the power. Stage timings and counters go into the report.
#pragma once

#include <memory>
#include <string>
#include <variant>
#include <vector>

#include "core/counters.h"
#include "mesh/patches.h"
#include "mesh/scene.h"
#include "solver/caustic_grading.h"
#include "solver/contact_grading.h"
#include "solver/radiosity/form_factors.h"
#include "solver/radiosity/hierarchy.h"
#include "solver/radiosity/refinement.h"
#include "solver/radiosity/solvers.h"
#include "solver/radiosity/system.h"
#include "solver/visibility.h"

namespace penumbra {

struct SolveOptions {
    MeshingOptions meshing;
    FormFactorSettings formFactors;
    SpecularSettings specular;
    std::string solver = "auto";  // auto: the matrix when it fits and the scene is small, else the hierarchy
    HierarchySettings hierarchy;  // --solver hierarchical (its minArea follows from `meshing`)
    int hierarchyRoots = 256;     // the hierarchy's roots: the scene meshed this coarsely
    SolverSettings solverSettings;
    RefineSettings refine;  // adaptive subdivision after the first solve (off by default)
    // The first mesh split towards contacts, once (contact_grading.h; --grade-contacts 0: off).
    ContactGrading grading{1};
    // Then split where mirrors and glass focus the lamps' light (caustic_grading.h; --grade-caustics 0: off).
    CausticGrading causticGrading;
    // Displayed corner radiosity (vertex_radiosity.h): gather (the equation at each vertex), direct (the
    // mean around it with the small sources' direct light at the vertex) or average (the mean around it).
    std::string vertexRadiosity = "direct";
    // The solution is for a final gather that reads its indirect light from it (GatherSettings::
    // solvedIndirect). Where the scene has small sources, that gather shades every point it sees from
    // the solve's indirect corners and the small sources' direct light, and reads no displayed corner
    // (FinalGather::reflected): the solve then makes the cheapest ones, "average", whatever
    // vertexRadiosity says. `render` without --solution (and without --vertex-radiosity) sets it.
    bool forSolvedIndirectGather = false;
    double maxMemoryBytes = 0;  // 0: what the machine has available
    // Rays per patch where the per-object floor sets the default mesh (a scene of many objects, the
    // building's desks, shelves and books): its large surfaces keep the target size, finer and with
    // fewer rays each (solve.cpp, manyObjects); 0, or an --ff-rays given: formFactors.raysPerPatch.
    int manyObjectsRays = 64;
};

// One round of adaptive subdivision: the mesh it solved and what it cost so far.
struct RefineRound {
    size_t patches = 0;
    size_t byGradient = 0, byShadow = 0, split = 0;  // patches marked by each test, and split in all
    double secondsSoFar = 0;                         // meshing, form factors and solves, all rounds to here
};

struct SolveResult {
    SolveOptions options;           // the settings (and seed, options.formFactors.seed) that made this result
    uint64_t sceneFingerprint = 0;  // of the scene file solved (Scene::fingerprint)
    std::string solverName;         // the solver that ran (auto resolved)
    std::string solverReason;       // why auto chose it (empty when named)
    std::string formFactorMethod;   // the form factors that ran (auto resolved; empty for the hierarchy)
    std::string formFactorReason;   // why auto chose them (empty when named)
    HierarchyStats hierarchy;       // --solver hierarchical only
    PatchSet patches;
    std::shared_ptr<const RayScene> rays;  // the mesh's one ray scene (buildRayScene), shared by all that trace it
    FormFactorMatrix F;
    RadiositySystem system;
    RadiositySolution solution;
    CornerValues corners;  // the displayed radiosity at each patch corner
    // The irradiance at each patch corner from all but the small sources' emission (indirectCorners,
    // vertex_radiosity.h), W/m^2: what the final gather reads at the points it shades. Empty without
    // small sources or a matrix (the hierarchy).
    CornerValues indirect;
    PowerBalance power;  // in the scene's inside unit: W = power x metresPerUnit^2 (1 but at extreme sizes)
    double secondsMeshing = 0, secondsFormFactors = 0, secondsSpecular = 0, secondsSolve = 0, secondsVertices = 0;
    double rowSumMin = 0, rowSumMax = 0;  // front-face row sums as made (closed scenes: 1 within error)
    bool closedScene = false;             // no ray from any front face leaves the scene (sceneClosure)
    // --form-factors rays: each object's estimated relative standard error (objectNoise, solve.cpp);
    // else empty.
    std::vector<double> objectNoise;
    std::vector<RefineRound> refinement;  // empty without --refine; else the first solve, then each round
    CounterValues counters;               // what this solve did: every named counter's change over it
    double metresPerUnit = 1;             // the scene's inside unit (Scene::metresPerUnit): lengths here are in it
};

SolveResult solveScene(const Scene& scene, const SolveOptions& options, const StepObserver& observer = {});

// The area of patch i that light reaches and leaves, m^2, what its radiosity is the mean over: its
// whole area, less any part covered by a solid resting on it (RadiositySystem::area).
inline double litArea(const SolveResult& r, size_t i) {
    return r.system.size() == r.patches.size() ? r.system.area[i] : r.patches.area[i];
}

// Each of the scene's `objects` mean radiosity over its whole area, W/m^2: sum(litArea B) / sum(area)
// over its patches, a part covered by a solid resting on it counted dark (0 for no patches).
std::vector<Rgb> objectRadiosity(const SolveResult& r, size_t objects);

// The tail of every matrix solve, on the system `r` holds (form factors, specular transport): the
// iterations of `options.solver` (a matrix solver's name) to `options.solverSettings`, the power
// balance and the displayed corners; its seconds add to r's. The bench solves one matrix to several
// tolerances with it.
void solveBuiltMatrix(const SolveOptions& options, const StepObserver& observer, SolveResult& r);

// One numeric setting of a solve, written once: its key in report.json's "settings", its command-line
// flag and help, the range it accepts, and where it lives in SolveOptions. The solve's command-line
// options and the report's settings both come from solveSettings(); what is not a plain number (the
// solver's name, the vertex radiosity mode, the memory budget in GiB, the seed) is added by each.
struct SolveSetting {
    const char* key;   // report.json "settings" key
    const char* flag;  // command-line flag
    const char* help;
    double min, max;   // accepted, inclusive; (0, infinity) for any positive number
    bool showDefault;  // the help shows the default (not for settings whose default means "off")
    std::variant<int*, double*> value;
};
// The table, its values pointing into `o`.
std::vector<SolveSetting> solveSettings(SolveOptions& o);

// Every solver --solver accepts, in the order shown to users: auto, the matrix solvers
// (solvers.h), the hierarchy; with what each does.
struct SolverInfo {
    std::string name, summary;
};
std::vector<SolverInfo> solverRegistry();
std::vector<std::string> allSolverNames();

// Bytes of memory available to this process (MemAvailable), or 0 if unknown.
double availableMemoryBytes();
// What the matrix may take on this rank: --max-memory, else what the host has available over the
// ranks started on it; under mpirun the least of every rank's (all ranks then choose alike).
double matrixBudget(const SolveOptions& options);
// Peak resident memory of this process so far, bytes.
double peakMemoryBytes();
// Starts the peak over from the current resident memory (Linux clear_refs), so that the peak of one
// stage can be read on its own; returns false where the kernel does not allow it.
bool resetPeakMemory();

}  // namespace penumbra
