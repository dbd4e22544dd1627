// Pinhole camera as the contract fixes it: right = forward x up (gluLookAt), image up = `up` made
// orthogonal to forward, fov_y the full vertical angle; pixel (x, y) counts from the top left.
#pragma once

#include "core/math.h"
#include "mesh/scene.h"

namespace penumbra {

class PinholeCamera {
public:
    explicit PinholeCamera(const Camera& c) : c_(c) {
        forward_ = (c.lookAt - c.position).normalized();
        right_ = forward_.cross(c.up).normalized();
        up_ = right_.cross(forward_);
        tanHalf_ = std::tan(c.fovYDeg * kPi / 360);
    }
    // Direction (unit) through image position (px, py) in pixels, continuous.
    Vec3 direction(double px, double py) const {
        const double aspect = double(c_.width) / c_.height;
        const double sx = (2 * px / c_.width - 1) * tanHalf_ * aspect;
        const double sy = (1 - 2 * py / c_.height) * tanHalf_;
        return (forward_ + sx * right_ + sy * up_).normalized();
    }
    const Vec3& origin() const { return c_.position; }
    int width() const { return c_.width; }
    int height() const { return c_.height; }

private:
    Camera c_;
    Vec3 forward_, right_, up_;
    double tanHalf_;
};

}  // namespace penumbra
