// report.json (the contract's form, plus counters and timings) and convergence.csv.
#pragma once

#include <string>
#include <vector>

#include "mesh/scene.h"
#include "render/object_reference.h"
#include "solver/solve.h"

namespace penumbra {

// The cameras of a turntable and their images, each camera in the scene file's form and units (so
// that `render --camera` takes it as it is).
std::string orbitJson(const std::vector<Camera>& cameras, const std::vector<std::string>& images, double unitScale);

// A few lines for the viewer's panel from a report.json text (patches, iterations, residual, power
// balance); empty if the text is not a report.
std::string summariseReport(const std::string& reportText);

std::string reportJson(const Scene& scene, const SolveResult& result, double peakMemoryBytes);

// `penumbra reference`'s file: each object's path-traced mean radiosity in report.json's form
// ({"objects": {name: {radiosity_mean, area_m2, ...}}}), with its standard error, points and the
// settings that made it.
std::string objectReferenceJson(const Scene& scene, const std::vector<ObjectEstimate>& estimates,
                                const ObjectReferenceSettings& settings, double seconds);

// One object's mean radiosity in two files of report.json's form (a solve's report, a reference).
struct ObjectComparison {
    std::string name;
    double area = 0;
    Rgb value = Rgb::Zero(), reference = Rgb::Zero();
    double ratio = 1;         // of the channel sums, value over reference
    double worstChannel = 0;  // largest |value / reference - 1| over the channels the reference lights
    double z = 0;             // (value - reference) over the reference's standard error, channel sums; 0 without one
};
// Every object both files name and the reference lights, in the reference's order; Error naming
// the file that is not of that form.
std::vector<ObjectComparison> compareObjectRadiosity(const std::string& valueFile, const std::string& referenceFile);
std::string convergenceCsv(const SolveResult& result);

}  // namespace penumbra
