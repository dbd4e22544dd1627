// The solved scene on disk (DIR/solution.bin): of a SolveResult, what views and export read (the
// patches, their radiosity, the display values and corners), so that render, view and export reopen
// it without solving again. Binary, versioned, tied to the scene file by its fingerprint.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "solver/solve.h"

namespace penumbra {

void writeSolution(const std::string& path, const SolveResult& solved);
// The solve as written: sceneFingerprint, patches, solution.B and .display, corners (no matrix,
// system or ray scene: whoever traces it builds the mesh's ray scene). Throws Error naming the path
// when it is missing, not a solution, or damaged.
SolveResult readSolution(const std::string& path);

// The same as bytes in memory (what writeSolution writes; the solve a render makes, sent to the other
// ranks of an MPI job), and back; `path` names them in errors.
std::string solutionBytes(const SolveResult& solved);
SolveResult solutionFromBytes(const std::string& bytes, const std::string& path);

}  // namespace penumbra
