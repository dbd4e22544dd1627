// The power that leaves an open scene, measured by rays instead of by the balance: rays leave every
// patch in proportion to its exitance (uniform points, cosine directions), follow mirrors and glass
// (walkSpecular), and count when they leave the scene. The solver's escaped power is defined as what
// leaves the surfaces less what arrives at them, so `emitted = absorbed + escaped` holds for it by
// construction once the solver has converged; held against this estimate it tests the form factors'
// row sums, the transport's fates and the convergence together.
#pragma once

#include <cstdint>
#include <vector>

#include "core/math.h"
#include "mesh/patches.h"
#include "solver/tracer.h"

namespace penumbra {

struct EscapeEstimate {
    Rgb escaped = Rgb::Zero();        // W per channel
    Rgb standardError = Rgb::Zero();  // of `escaped`, from the per-patch sample variances
    int64_t rays = 0;
};

// Escaped power for exitance B (W/m^2 per patch of the tracer's patches), with `raysPerPatch`
// stratified rays from every patch that sends light.
EscapeEstimate estimateEscapedPower(const SceneTracer& tracer, const std::vector<Rgb>& B, int raysPerPatch,
                                    uint64_t seed, int maxBounces = 64);

}  // namespace penumbra
