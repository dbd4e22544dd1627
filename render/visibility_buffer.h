// The first surface seen at a grid of points of the image, found without rays: what a camera ray
// through each point would hit first (the Exact view: a patch, or an exact sphere in place of its
// facets), for a view that then reads the solved light there. Each patch is drawn as Embree's two
// triangles of a quad and tested at every point of its image by the planes through the eye and its
// edges (homogeneous rasterisation, Olano and Greer 1997): nothing is projected or clipped at the
// eye, the distance and Embree's (u, v) come from the same three numbers, and two triangles that
// share an edge test a point by the same plane with opposite signs, so no point falls between them.
#pragma once

#include <memory>
#include <vector>

#include "mesh/patches.h"
#include "render/camera.h"
#include "render/film.h"
#include "solver/visibility.h"

namespace penumbra {

struct BufferHit {
    int patch = -1;       // the patch seen, or -1
    int sphere = -1;      // or the exact sphere seen (RayScene::spheres()), or -1
    double t = HUGE_VAL;  // along the unnormalised direction of PinholeCamera::imagePlane
    double u = 0, v = 0;  // Embree's parameters on the patch (barycentric on triangles)
};

class VisibilityBuffer {
public:
    // The patches and exact spheres as this camera sees them. With exact spheres, the eye must be
    // outside them (eyeInsideSphere).
    VisibilityBuffer(const PatchSet& patches, const RayScene& rays, const Camera& camera);
    ~VisibilityBuffer();
    // The first hit along the ray from the eye through each sample's image position.
    std::vector<BufferHit> firstHits(const std::vector<CameraSample>& samples) const;
    // Whether the camera stands inside an exact sphere, which the buffer cannot draw.
    static bool eyeInsideSphere(const RayScene& rays, const Camera& camera);

private:
    struct Shapes;
    std::unique_ptr<const Shapes> shapes_;
};

}  // namespace penumbra
