#include "render/integrators.h"

#include "core/error.h"
#include "render/path_tracer.h"
#include "render/radiosity_view.h"
#include "solver/tracer.h"

namespace penumbra {
namespace {

std::shared_ptr<const RayScene> raysOf(const RenderInputs& in) {
    return in.rays ? in.rays : buildRayScene(in.scene, in.patches);
}

std::vector<Image> renderFinalGatherViews(const RenderInputs& in, const std::vector<Camera>& cameras, int spp) {
    // The ray scene and the photon map serve every view of an orbit.
    const SolvedScene solved(in.scene, in.patches, in.corners, in.gather, in.photons, in.seed, raysOf(in), in.means,
                             in.indirect ? *in.indirect : CornerValues{});
    std::vector<Image> images;
    for (const Camera& camera : cameras) images.push_back(solved.render(camera, spp, in.seed));
    return images;
}

std::vector<Image> renderPathViews(const RenderInputs& in, const std::vector<Camera>& cameras, int spp) {
    const SceneTracer tracer(in.scene, in.patches, raysOf(in));
    std::vector<Image> images;
    for (const Camera& camera : cameras) images.push_back(renderPath(tracer, camera, spp, in.seed));
    return images;
}

std::vector<Image> renderRadiosityViews(const RenderInputs& in, const std::vector<Camera>& cameras, int spp) {
    const RadiosityView view(in.scene, in.patches, raysOf(in), in.corners, {spp, in.seed});
    std::vector<Image> images;
    for (const Camera& camera : cameras) images.push_back(view.render(camera));
    return images;
}

}  // namespace

const std::vector<IntegratorEntry>& integrators() {
    static const std::vector<IntegratorEntry> table{
        {"final-gather", "the solved radiosity gathered at every visible point, with direct light and caustics", 16,
         true, renderFinalGatherViews},
        {"path", "unbiased path tracing of the scene (needs no solve)", 1024, false, renderPathViews},
        {"radiosity", "the solved radiosity itself, interpolated over the patches", 4, true, renderRadiosityViews},
    };
    return table;
}

const IntegratorEntry& findIntegrator(const std::string& name) {
    for (const IntegratorEntry& e : integrators())
        if (name == e.name) return e;
    throw Error(cat("--integrator: unknown integrator '", name, "' (known: ", integratorNames(", "), ")"));
}

std::string integratorNames(const char* separator) {
    std::string names;
    for (const IntegratorEntry& e : integrators()) names += cat(names.empty() ? "" : separator, e.name);
    return names;
}

}  // namespace penumbra
