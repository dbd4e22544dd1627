#include "render/orbit.h"

#include "core/error.h"

namespace penumbra {

Vec3 patchesCentre(const PatchSet& patches) {
    Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
    for (size_t i = 0; i < patches.size(); ++i)
        for (const Vec3& p : patches.corners[i]) {
            lo = lo.cwiseMin(p);
            hi = hi.cwiseMax(p);
        }
    return patches.size() ? Vec3(0.5 * (lo + hi)) : Vec3(Vec3::Zero());
}

std::vector<Camera> orbitCameras(const Camera& start, const Vec3& centre, int count) {
    PENUMBRA_CHECK(count >= 1);
    const Vec3 axis = start.up.normalized();
    if ((start.position - centre).cross(axis).norm() < 1e-9)
        throw Error("--orbit: the camera stands on the vertical axis through the scene's centre, so there is no circle "
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
