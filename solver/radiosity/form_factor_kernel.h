// Unoccluded form factors. The inner integral over the receiving polygon is analytic (Lambert's
// contour formula); the outer integral over the sending patch is a Gauss-Legendre cubature whose
// cells are split where the receiver is close compared with the cell's size, so that near and
// touching patches are integrated as accurately as distant ones (docs/form-factors.md).
#pragma once

#include <cstdint>

#include "core/math.h"
#include "mesh/patches.h"

namespace penumbra {

// Form factor from a differential area at x (unit normal n) to the planar convex polygon `poly`
// (3 or 4 vertices, either winding), clipped to the half-space in front of x. Dimensionless.
double pointPolygonFormFactor(const Vec3& x, const Vec3& n, const Vec3* poly, int count);

// The kernel cos cos / r^2 between x (unit normal n) and a point y of a source whose front has unit
// normal m, 0 where either faces away from the other: what a shadow ray to y weighs in a source's
// visible share (directIrradiance, vertex_radiosity.h; DirectLight, render/direct_light.h).
inline double sourceKernel(const Vec3& x, const Vec3& n, const Vec3& y, const Vec3& m) {
    const Vec3 d = y - x;
    const double d2 = d.squaredNorm(), cosX = n.dot(d), cosL = -m.dot(d);
    return cosX > 0 && cosL > 0 && d2 > 0 ? cosX * cosL / (d2 * d2) : 0;
}

// Distance from x to a convex planar polygon (3 or 4 vertices).
double pointPolygonDistance(const Vec3& x, const Vec3* poly, int count);

struct CubatureSettings {
    // Target relative error of one patch-to-patch factor: picks the Gauss order (1, 2 or 3 points per
    // axis) from the cell-size-to-distance ratio q by the bound (q/2)^(2 order), and splits cells for
    // which order 3 is not enough.
    double tolerance = 1e-5;
    int maxDepth = 9;  // cells along a shared edge end at 2^-maxDepth of the patch
    int cutDepth = 5;  // cells cut by the receiver's plane end at 2^-cutDepth of the patch
};

// Unoccluded area factors from patch s's front face to patch r, split by the face of r the light
// arrives at: `front` integrates over the points of s in front of r's plane, `back` over those
// behind it (which see r's back). A_s F(s -> r) = front + back, m^2. `front` is symmetric in exact
// arithmetic (reciprocity), so integrate over the smaller patch for accuracy; `back` needs s to be
// the sending patch. `evaluations` counts kernel calls.
struct AreaFactors {
    double front = 0, back = 0;
};
AreaFactors unoccludedAreaFactors(const PatchSet& patches, size_t s, size_t r, const CubatureSettings& settings,
                                  uint64_t* evaluations = nullptr);

// front + back, for callers that do not care which face receives.
inline double unoccludedAreaFactor(const PatchSet& patches, size_t s, size_t r, const CubatureSettings& settings,
                                   uint64_t* evaluations = nullptr) {
    const AreaFactors f = unoccludedAreaFactors(patches, s, r, settings, evaluations);
    return f.front + f.back;
}

}  // namespace penumbra
