// Where a solved mesh is too coarse for its light: the oracle of adaptive subdivision. After a
// solve, a patch is marked for splitting when its neighbours disagree with it beyond what linear
// interpolation carries (the mean of its displayed corner values, each averaged from the patches
// around the corner, misses its own B: light that bends near a contact or a corner, or jumps at a
// shadow), or when a shadow edge crosses it (the emitters are partly visible from it) and that edge
// carries enough of its light. Patches already at the finest allowed size stay.
#pragma once

#include <vector>

#include "core/math.h"
#include "mesh/patches.h"
#include "solver/radiosity/system.h"
#include "solver/visibility.h"

namespace penumbra {

struct RefineSettings {
    // 0: no refinement. Otherwise split where the interpolated display misses a patch's B by more
    // than this fraction (of B, floored at a tenth of the scene's mean), or where a shadow edge
    // carries more than this fraction of a patch's light.
    double tolerance = 0;
    int maxPatches = 10000;  // the budget: no round goes past it
    int maxRounds = 12;
    int maxLevels = 5;  // patches end at 2^-maxLevels of the first mesh's edge length
};

struct SplitChoice {
    std::vector<char> split;
    size_t byGradient = 0, byShadow = 0;  // a patch marked for both counts under both
};

// Marks the patches to split, best first within the budget (up to `maxSplits` of them).
SplitChoice chooseSplits(const PatchSet& patches, const RadiositySystem& system, const FormFactorMatrix& F,
                         const std::vector<Rgb>& B, const CornerValues& corners, const RayScene& rays,
                         const RefineSettings& settings, double minArea, size_t maxSplits);

}  // namespace penumbra
