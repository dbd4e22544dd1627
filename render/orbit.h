// Turntable views of a solved scene: cameras on a circle about the scene's centre, around the
// start camera's up axis, each looking at the centre; the first stands where the start camera is.
#pragma once

#include <vector>

#include "mesh/patches.h"
#include "mesh/scene.h"

namespace penumbra {

// The centre of the patches' bounding box, metres.
Vec3 patchesCentre(const PatchSet& patches);

std::vector<Camera> orbitCameras(const Camera& start, const Vec3& centre, int count);

}  // namespace penumbra
