#include "solver/contact_grading.h"

#include <algorithm>
#include <cmath>

#include "core/log.h"
#include "core/parallel.h"
#include "mesh/refine.h"
#include "solver/tracer.h"

namespace penumbra {
namespace {

constexpr double kStraddle = 2;

// The distance from a point of patch i to the nearest surface in front of it, by 16 rays into `rays`
// (a scene of the same geometry, perhaps of coarser patches).
double nearestSurface(const PatchSet& p, const RayScene& rays, size_t i, const Vec3& point) {
    const Vec3 n = p.normal[i];
    const Vec3 a = (std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(n).normalized();
    const Vec3 b = n.cross(a);
    const Vec3 origin = point + (1e-6 + 1e-4 * p.radius[i]) * n;
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

// Whether the light may change across patch i faster than a constant patch holds: another surface
// comes closer than `closer` patch widths to some of its points (its centroid and its corners,
// pulled a tenth towards the centroid), and the nearest surface is not as near to all of them (a
// patch wholly in a narrow gap, behind a shelf's back panel, sees the same all over: splitting it
// adds patches and nothing else).
bool nearAContact(const PatchSet& p, const RayScene& rays, size_t i, double closer) {
    const double width = std::sqrt(p.area[i]);
    double nearest = nearestSurface(p, rays, i, p.centroid[i]), farthest = nearest;
    // No corner lies farther than a width from the centroid (nor its surfaces nearer by more).
    if (nearest >= (closer + 1) * width) return false;
    for (int k = 0; k < 4; ++k) {
        const Vec3 corner = p.pointAt(i, k == 1 || k == 2 ? 0.95 : 0.05, k >= 2 ? 0.95 : 0.05);
        const double d = nearestSurface(p, rays, i, corner);
        nearest = std::min(nearest, d), farthest = std::max(farthest, d);
    }
    return nearest < closer * width && farthest > kStraddle * nearest;
}

}  // namespace

GradedMesh gradeContacts(const Scene& scene, PatchSet patches, const ContactGrading& settings,
                         std::shared_ptr<const RayScene> measure) {
    GradedMesh out;
    const bool own = !measure;
    const std::shared_ptr<const RayScene> rays = own ? buildRayScene(scene, patches) : std::move(measure);
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
                    split[i] = nearAContact(patches, *rays, i, settings.closer);
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
    if (out.split == 0 && own) out.rays = rays;
    out.patches = std::move(patches);
    return out;
}

}  // namespace penumbra
