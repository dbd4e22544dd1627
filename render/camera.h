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
    // The direction through (px, py) before it is normalised, corner + px perX + py perY: linear in
    // the image position (as `direction` makes it, but for rounding); `forward` is the view axis.
    struct ImagePlane {
        Vec3 corner, perX, perY, forward;
    };
    ImagePlane imagePlane() const {
        const double aspect = double(c_.width) / c_.height;
        return {forward_ - tanHalf_ * aspect * right_ + tanHalf_ * up_, (2 * tanHalf_ * aspect / c_.width) * right_,
                (-2 * tanHalf_ / c_.height) * up_, forward_};
    }
    // Where the line from the eye to `p` crosses the image, in pixels (continuous, as `direction`
    // takes them), and the cosine of its angle to the view axis; false if `p` is not in front of
    // the eye within the image.
    bool project(const Vec3& p, double& px, double& py, double& cosAxis) const {
        const Vec3 v = p - c_.position;
        const double z = v.dot(forward_);
        if (!(z > 0)) return false;
        const double aspect = double(c_.width) / c_.height;
        px = (v.dot(right_) / (z * tanHalf_ * aspect) + 1) * 0.5 * c_.width;
        py = (1 - v.dot(up_) / (z * tanHalf_)) * 0.5 * c_.height;
        cosAxis = z / v.norm();
        return px >= 0 && px < c_.width && py >= 0 && py < c_.height;
    }
    // The area of one pixel on the image plane at unit distance from the eye.
    double pixelArea() const {
        const double aspect = double(c_.width) / c_.height;
        return 4 * tanHalf_ * tanHalf_ * aspect / (double(c_.width) * c_.height);
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
