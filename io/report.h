// report.json (the contract's form, plus counters and timings) and convergence.csv.
#pragma once

#include <string>
#include <vector>

#include "mesh/scene.h"
#include "solver/solve.h"

namespace penumbra {

// The cameras of a turntable and their images, each camera in the scene file's form and units (so
// that `render --camera` takes it as it is).
std::string orbitJson(const std::vector<Camera>& cameras, const std::vector<std::string>& images, double unitScale);

// A few lines for the viewer's panel from a report.json text (patches, iterations, residual, power
// balance); empty if the text is not a report.
std::string summariseReport(const std::string& reportText);

std::string reportJson(const Scene& scene, const SolveResult& result, double peakMemoryBytes);
std::string convergenceCsv(const SolveResult& result);

}  // namespace penumbra
