// The integrators `render --integrator NAME` runs, in one table: each entry has its name, what it
// shows, its default samples per pixel, whether it reads a solve, and the function that renders a
// list of views. A new integrator is one entry here; the command line's help, its unknown-name error
// and the default sample counts all come from the table.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "mesh/patches.h"
#include "mesh/scene.h"
#include "render/final_gather.h"
#include "render/image.h"
#include "render/photon_map.h"
#include "solver/visibility.h"

namespace penumbra {

// What a render has to work with: the scene, its patches (solved, or meshed for the path tracer) and
// their displayed corner radiosity (empty without a solve), and the settings of every integrator.
struct RenderInputs {
    const Scene& scene;
    const PatchSet& patches;
    const CornerValues& corners;
    std::shared_ptr<const RayScene> rays;  // the mesh's ray scene (buildRayScene); built here if null
    GatherSettings gather;
    PhotonSettings photons;
    uint64_t seed = 1;
    // The displayed radiosity per patch: the final gather reads corners whose mean over each patch
    // is this (meanPreservingCorners); without it, the corners as they are.
    const std::vector<Rgb>* means = nullptr;
    // The solve's indirect irradiance per patch corner (SolveResult::indirect), or null: the final
    // gather then gathers it with rays.
    const CornerValues* indirect = nullptr;
};

struct IntegratorEntry {
    const char* name;
    const char* summary;
    int defaultSpp;      // samples per pixel without --spp
    bool needsSolution;  // reads the radiosity solution (else only the geometry)
    // Renders every camera, sharing what the views have in common (ray scene, photon map).
    std::vector<Image> (*render)(const RenderInputs& in, const std::vector<Camera>& cameras, int spp);
};

const std::vector<IntegratorEntry>& integrators();
// The entry called `name`; Error listing the known names when there is none.
const IntegratorEntry& findIntegrator(const std::string& name);
// "final-gather | path | radiosity", in table order.
std::string integratorNames(const char* separator = " | ");

}  // namespace penumbra
