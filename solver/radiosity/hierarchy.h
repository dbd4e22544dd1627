// Hierarchical radiosity (Hanrahan, Salzman and Aupperle 1991, with BF refinement): every coarse
// root patch is the top of a quadtree of elements, and light moves along links between elements
// at whatever level the oracle allows. A link from source s to receiver r is split (the larger of
// the two elements into its four children) while the power it carries, F(r->s) B_s A_r with F by
// the point-to-disc estimate (BFA refinement), exceeds `linkTolerance` of the emitted power, or
// while Embree rays find s partly hidden from r and the link carries a tenth of that. Gathering along the links
// then push-pull (irradiance pushed down to the leaves, radiosity pulled up as area means) iterate
// to the solution. Storage is the elements and the links: about linear in the element count, not
// the matrix's n^2. Diffuse surfaces only: mirrors and glass need the matrix solve.
#pragma once

#include <cstdint>
#include <vector>

#include "core/math.h"
#include "mesh/patches.h"
#include "mesh/scene.h"
#include "solver/radiosity/form_factor_kernel.h"
#include "solver/radiosity/solvers.h"
#include "solver/visibility.h"

namespace penumbra {

struct HierarchySettings {
    double linkTolerance = 1e-5;  // BFA oracle: refine links carrying more than this share of the emitted power
    double minArea = 0;           // elements are not split below this area, m^2 (0: roots / 4^8)
    int visibilityRays = 4;       // per link; partly visible links get four times as many more
    CubatureSettings cubature{1e-3, 9, 5};
    int maxRounds = 12;  // refine-then-solve rounds
    // Elements and links may take at most this many bytes (--max-memory; 0: no bound): past it after
    // a refinement the solve stops with an Error saying what it took.
    double maxBytes = 0;
    // The scene is closed, with no back face in sight (sceneClosure, ray_form_factors.h): each leaf's links, its own
    // and its ancestors', are scaled to carry all of its light, as every row of a closed scene does.
    bool closedScene = false;
    SolverSettings solver;
    uint64_t seed = 1;
};

struct HierarchyStats {
    size_t roots = 0, elements = 0, leaves = 0, links = 0;
    uint64_t partlyVisibleLinks = 0;
    double leafSumMin = 0, leafSumMax = 0;  // over the leaves: the form factors of the links that serve each
    int rounds = 0;
    double bytes = 0;  // elements and links as stored
    double secondsLinks = 0, secondsSolve = 0;
};

struct HierarchyResult {
    PatchSet leaves;             // the finest elements, as patches (display vertices shared)
    std::vector<Rgb> B;          // exitance per leaf, W/m^2
    PowerBalance power;          // per leaf: emitted and absorbed; escaped: what reaches no surface, W
    RadiositySolution solution;  // iterations, residual and history of the last round
    HierarchyStats stats;
};

// Solves the diffuse scene on the hierarchy over `roots` (the coarse patches; `rays` traces them).
HierarchyResult solveHierarchy(const Scene& scene, const PatchSet& roots, const RayScene& rays,
                               const HierarchySettings& settings);

// Bytes per element and per link as the hierarchy stores them (for the memory estimate).
double hierarchyBytes(size_t elements, size_t links);

}  // namespace penumbra
