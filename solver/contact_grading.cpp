#include "solver/contact_grading.h"

#include <algorithm>
#include <cmath>

#include "core/log.h"
#include "core/parallel.h"
#include "mesh/refine.h"
#include "solver/tracer.h"

namespace penumbra {
namespace {

// The distance from patch i's centroid to the nearest surface in front of it, by 16 rays into `rays`
// (a scene of the same geometry, perhaps of coarser patches).
double nearestSurface(const PatchSet& p, const RayScene& rays, size_t i) {
    const Vec3 n = p.normal[i];
    const Vec3 a = (std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(n).normalized();
    const Vec3 b = n.cross(a);
    const Vec3 origin = p.centroid[i] + (1e-6 + 1e-4 * p.radius[i]) * n;
    double nearest = 1e300;
    for (const double elevation : {15.0, 50.0})
        for (int k = 0; k < 8; ++k) {
            const double phi = kPi / 4 * (k + (elevation > 20 ? 0.5 : 0.0)), theta = elevation * kPi / 180;
            const Vec3 d = std::cos(theta) * (std::cos(phi) * a + std::sin(phi) * b) + std::sin(theta) * n;
            const Hit h = rays.intersect(origin, d, 0, nearest, RayView::Patches);
            if (h.found()) nearest = std::min(nearest, h.t);
        }
    return nearest;
}

}  // namespace

GradedMesh gradeContacts(const Scene& scene, PatchSet patches, const ContactGrading& settings) {
    GradedMesh out;
    const std::shared_ptr<const RayScene> rays = buildRayScene(scene, patches);
    for (int level = 0; level < settings.levels; ++level) {
        const size_t n = patches.size();
        std::vector<char> split(n, 0);
        parallelFor(
            int64_t(n),
            [&](int64_t begin, int64_t end) {
                prepareTracingThread();
                for (int64_t ii = begin; ii < end; ++ii) {
                    const size_t i = size_t(ii);
                    if (patches.area[i] < 4 * settings.minArea) continue;
                    const double width = std::sqrt(patches.area[i]);
                    split[i] = nearestSurface(patches, *rays, i) < settings.closer * width;
                }
            },
            64);
        if (std::find(split.begin(), split.end(), 1) == split.end()) break;
        const size_t asked = size_t(std::count(split.begin(), split.end(), 1));
        patches = splitPatches(patches, split);  // adds to `split` what the 2:1 rule needs
        const size_t made = size_t(std::count(split.begin(), split.end(), 1));
        out.split += made;
        logDebug("contact grading, level ", level + 1, ": ", asked, " patches near another surface split (",
                 made - asked, " more for the 2:1 rule) -> ", patches.size(), " patches");
    }
    if (out.split == 0) out.rays = rays;
    out.patches = std::move(patches);
    return out;
}

}  // namespace penumbra
