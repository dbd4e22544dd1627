// report.json (the contract's form, plus counters and timings) and convergence.csv.
#pragma once

#include <string>

#include "mesh/scene.h"
#include "solver/solve.h"

namespace penumbra {

std::string reportJson(const Scene& scene, const SolveResult& result, double peakMemoryBytes);
std::string convergenceCsv(const SolveResult& result);

}  // namespace penumbra
