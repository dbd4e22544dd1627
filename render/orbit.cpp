#include "render/orbit.h"

#include "core/error.h"

namespace penumbra {

Vec3 patchesCentre(const PatchSet& patches) {
    return patches.size() ? Vec3(patchBounds(patches).center()) : Vec3(Vec3::Zero());
}

std::vector<Camera> orbitCameras(const Camera& start, const Vec3& centre, int count) {
    PENUMBRA_CHECK(count >= 1);
    const Vec3 axis = start.up.normalized();
    if ((start.position - centre).cross(axis).norm() < 1e-9)
        throw Error(
            "--orbit: the camera stands on the vertical axis through the scene's centre, so there is no circle "
            "to move on; move the camera sideways (--camera)");
    std::vector<Camera> cameras;
    for (int k = 0; k < count; ++k) {
        const Eigen::AngleAxisd turn(2 * kPi * k / count, axis);
        Camera c = start;
        c.position = centre + turn * (start.position - centre);
        c.lookAt = centre;
        cameras.push_back(c);
    }
    return cameras;
}

}  // namespace penumbra
