// The displayed radiosity at the patch corners, from the radiosity equation itself: at each vertex,
// E + rho (sum_j F(x->j) B_j + S_i B F(x->spec) / F(i->spec)) with point-to-patch factors (Lambert's
// contour formula) and one visibility ray per patch. S_i B is the light that reaches the vertex's
// patch through mirrors and glass (specular_transport.h), taken in proportion to how much of them the
// vertex sees against its patch; leaving it out darkened cornell-glass's ceiling by 25%. The mean of
// the patches around a vertex (interpolateCorners) is what a patch holds on average, which at a
// room's edge or next to a contact is not the light at the vertex; the equation at the vertex is.
// Costs one point-to-patch factor per vertex and visible patch, a fraction of the form factors
// (docs/adaptive-and-hierarchical.md has the figures).
#pragma once

#include "core/math.h"
#include "mesh/patches.h"
#include "solver/radiosity/form_factor_kernel.h"
#include "solver/radiosity/form_factors.h"
#include "solver/radiosity/system.h"
#include "solver/visibility.h"

namespace penumbra {

// The form factor from the point x (unit normal n) to patch j, 0 where the ray to j's centroid is
// blocked. That ray gives up the last thousandth of its length at each end: the centroid of a patch
// of a non-planar quad (the Cornell box's walls) lies a little off the two triangles Embree traces,
// and must not hide behind its own wall.
inline double visiblePointFactor(const PatchSet& p, const RayScene& rays, const Vec3& x, const Vec3& n, size_t j) {
    const double f = pointPolygonFormFactor(x, n, p.corners[j].data(), p.cornerCount[j]);
    return f > 0 && !rays.occluded(x, p.centroid[j], 1e-3) ? f : 0;
}

// Irradiance at the point x (unit normal n) from the patches j with sees(j), W/m^2.
template <typename Sees>
Rgb irradianceAtPoint(const PatchSet& p, const std::vector<Rgb>& B, const RayScene& rays, const Vec3& x, const Vec3& n,
                      const Sees& sees) {
    Rgb h = Rgb::Zero();
    for (size_t j = 0; j < p.size(); ++j)
        if (sees(j) && B[j].maxCoeff() > 0) h += visiblePointFactor(p, rays, x, n, j) * B[j];
    return h;
}

// The same from the listed patches (ascending, as a row's columns): the cost of the list, not of
// every patch in the scene.
inline Rgb irradianceAtPoint(const PatchSet& p, const std::vector<Rgb>& B, const RayScene& rays, const Vec3& x,
                             const Vec3& n, const std::vector<size_t>& from) {
    Rgb h = Rgb::Zero();
    for (size_t j : from)
        if (B[j].maxCoeff() > 0) h += visiblePointFactor(p, rays, x, n, j) * B[j];
    return h;
}

// Irradiance at the point x (unit normal n) from the listed source patches, W/m^2: the unoccluded
// point-to-patch factors in closed form, times the visibility that about `rayCount` shadow rays find.
// The rays go to the sources in proportion to each one's unoccluded share (by brightness), to the
// centres of a grid on it (no randomness: the display is the same every time), so a point that sees
// all of them (or none) gets the closed form exactly, and a penumbra is resolved in steps of about
// 1 / rayCount.
Rgb directIrradiance(const PatchSet& p, const std::vector<Rgb>& B, const RayScene& rays, const Vec3& x, const Vec3& n,
                     const std::vector<size_t>& sources, int rayCount = 64);

// Corner radiosity by the equation at each vertex (averaged over the patches around it within the
// crease angle, as interpolateCorners does); hanging vertices keep the mean of their coarser edge's
// ends. `F` limits each vertex to what the patches around it see; an empty or sampled F (the
// hierarchy; ray-cast rows, whose zeros may hide what is seen) takes every patch in front of it.
CornerValues gatherCorners(const PatchSet& patches, const RadiositySystem& system, const FormFactorMatrix& F,
                           const std::vector<Rgb>& B, const RayScene& rays, double creaseDeg = 30);

// Corner radiosity as the mean of the patches around each vertex (interpolateCorners), except for the
// direct light of the small sources (smallSources, system.h), which is taken at the vertex itself:
// per patch corner, E + rho (H_i - D_i + D(x)), with D_i the patch's share of that light in the solve
// and D(x) the point-to-patch factors at the corner with one visibility ray per source patch. A
// shadow's penumbra and a lamp's fall-off are then drawn at the vertices rather than smeared over
// the patches; the indirect light, smooth, keeps the patch means. Costs one factor and ray per
// vertex and source patch; without small sources it is the mean around each vertex.
CornerValues directCorners(const PatchSet& patches, const RadiositySystem& system, const FormFactorMatrix& F,
                           const std::vector<Rgb>& B, const RayScene& rays, double creaseDeg = 30);

// The irradiance at each patch corner from everything but the small sources' own emission (their
// reflected light included, and light through mirrors and glass from any diffuse patch): per patch,
// sum_j F(i, j) (B_j - E_j of small sources) plus the transport's share of the same, as the solve found it,
// averaged at the vertices as interpolateCorners does. A view adds the small sources' direct light
// at each point it shades (render/direct_light.h) and the caustics (light from the sources through
// mirrors and glass) from the photon map: each light path counted once. Empty when the scene has
// no small sources or `F` is not the patches' matrix (the hierarchy).
CornerValues indirectCorners(const PatchSet& patches, const RadiositySystem& system, const FormFactorMatrix& F,
                             const std::vector<Rgb>& B, double creaseDeg = 30);

}  // namespace penumbra
