// Math vocabulary shared by every module: Eigen aliases for points, directions and RGB triples.
// Geometry is in metres (the scene loader applies unit_scale), radiometry in SI units.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace penumbra {

using Vec3 = Eigen::Vector3d;
using Vec3f = Eigen::Vector3f;
using Rgb = Eigen::Array3d;  // one value per colour channel, component-wise arithmetic

constexpr double kPi = 3.14159265358979323846;
constexpr double kInvPi = 1.0 / kPi;

inline double luminance(const Rgb& c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

// An orthonormal basis (t, b, n) around a unit normal n (Duff et al. 2017, branchless).
inline void orthonormalBasis(const Vec3& n, Vec3& t, Vec3& b) {
    const double sign = std::copysign(1.0, n.z());
    const double a = -1.0 / (sign + n.z());
    const double c = n.x() * n.y() * a;
    t = Vec3(1.0 + sign * n.x() * n.x() * a, sign * c, -sign * n.x());
    b = Vec3(c, sign + n.y() * n.y() * a, -n.y());
}

}  // namespace penumbra
