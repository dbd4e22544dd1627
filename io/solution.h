// The solved scene on disk (DIR/solution.bin): patches, their radiosity and the display values, so
// that render and view reopen it without solving again. Binary, versioned, tied to the scene file
// by its fingerprint.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "mesh/patches.h"
#include "mesh/scene.h"

namespace penumbra {

struct StoredSolution {
    uint64_t sceneFingerprint = 0;
    PatchSet patches;
    std::vector<Rgb> radiosity;  // B, W/m^2
    std::vector<Rgb> display;    // B plus any ambient estimate
    CornerValues corners;        // the displayed radiosity at each patch corner, W/m^2
};

void writeSolution(const std::string& path, const StoredSolution& solution);
// Throws Error naming the path when it is missing, not a solution, or damaged.
StoredSolution readSolution(const std::string& path);

}  // namespace penumbra
