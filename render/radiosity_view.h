// The plain view of a solved scene: primary rays through each pixel (stratified, a one-pixel box
// filter) show the interpolated vertex radiosity as radiance B / pi on diffuse front faces; back
// faces are black. A ray that meets a mirror or glass follows both its branches (Fresnel's
// reflection and refraction, total internal reflection), weighted, to the diffuse surfaces they
// reach, which show theirs: mirrors and glass show the solved room in them, without random numbers.
#pragma once

#include <array>
#include <memory>
#include <vector>

#include "mesh/patches.h"
#include "mesh/scene.h"
#include "render/image.h"
#include "solver/visibility.h"

namespace penumbra {

struct ViewSettings {
    int samplesPerPixel = 4;
    uint64_t seed = 1;
    int maxSpecularDepth = 16;    // mirror and glass bounces followed (as the final gather's)
    double minThroughput = 1e-3;  // specular branches carrying less are dropped
};

// A solved scene ready to be seen from any camera: what every view shares (the tracer of mirrors and
// glass, the textures' irradiance) is made once, so a turntable's views pay only for their pixels.
class RadiosityView {
public:
    RadiosityView(const Scene& scene, const PatchSet& patches, std::shared_ptr<const RayScene> rays,
                  const CornerValues& cornerRadiosity, const ViewSettings& settings);
    ~RadiosityView();
    Image render(const Camera& camera) const;

private:
    struct Shared;
    std::unique_ptr<const Shared> shared_;
};

// One view: RadiosityView(...).render(camera).
Image renderRadiosityView(const Scene& scene, const Camera& camera, const PatchSet& patches,
                          const std::shared_ptr<const RayScene>& rays,
                          const std::vector<std::array<Rgb, 4>>& cornerRadiosity, const ViewSettings& settings);

// The irradiance at every patch corner, W m^-2, from the displayed corner radiosity: (B - E) / rho
// with the patch's mean emission and reflectance (0 where it reflects nothing). What a texture
// multiplies (the radiosity view, the exported light). The corners average the irradiance around each
// vertex (vertex_radiosity.cpp), so this is the light at the vertex whatever the patch's reflectance.
CornerValues cornerIrradiance(const Scene& scene, const PatchSet& patches, const CornerValues& cornerRadiosity);

// The radiance leaving a diffuse patch p at Embree's parameters (u, v), from the irradiance at its
// corners (cornerIrradiance): rho(x) E / pi + L_e(x), with the material's texels at the point where
// the object has texture coordinates (else the textures' means).
Rgb radianceFromIrradiance(const Scene& scene, const PatchSet& patches, size_t p, double u, double v,
                           const std::array<Rgb, 4>& cornerIrradiance);

// Radiosity at parameters (u, v) of a patch hit, from its corner values (Embree's quad coordinates;
// barycentric on triangles).
Rgb interpolateAt(const PatchSet& patches, size_t patch, double u, double v, const std::array<Rgb, 4>& corner);

}  // namespace penumbra
