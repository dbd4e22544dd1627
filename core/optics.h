// Smooth-surface optics and the sampling of diffuse directions, shared by the specular transport of
// the solve, the photon pass and both integrators. Directions are unit vectors; a normal points to
// the side the light arrives from unless said otherwise.
#pragma once

#include <cmath>
#include <optional>

#include "core/math.h"
#include "core/rng.h"

namespace penumbra {

// Mirror direction of `d` (travelling towards the surface) about the normal n.
inline Vec3 reflect(const Vec3& d, const Vec3& n) { return d - 2 * d.dot(n) * n; }

// Unpolarised Fresnel reflectance of a smooth dielectric interface, for light arriving with cosine
// `cosIncident` (> 0) to the normal from a medium of index `etaFrom` into one of index `etaTo`.
// Returns 1 beyond the critical angle (total internal reflection).
inline double fresnelDielectric(double cosIncident, double etaFrom, double etaTo) {
    cosIncident = std::min(1.0, std::abs(cosIncident));
    const double sinT = etaFrom / etaTo * std::sqrt(std::max(0.0, 1 - cosIncident * cosIncident));
    if (sinT >= 1) return 1;
    const double cosT = std::sqrt(std::max(0.0, 1 - sinT * sinT));
    const double rs = (etaFrom * cosIncident - etaTo * cosT) / (etaFrom * cosIncident + etaTo * cosT);
    const double rp = (etaTo * cosIncident - etaFrom * cosT) / (etaTo * cosIncident + etaFrom * cosT);
    return 0.5 * (rs * rs + rp * rp);
}

// Snell refraction of `d` through a surface whose normal n faces the incoming side, from index
// etaFrom to etaTo. Empty beyond the critical angle.
inline std::optional<Vec3> refract(const Vec3& d, const Vec3& n, double etaFrom, double etaTo) {
    const double eta = etaFrom / etaTo;
    const double cosI = -d.dot(n);
    const double sin2T = eta * eta * std::max(0.0, 1 - cosI * cosI);
    if (sin2T >= 1) return std::nullopt;
    const double cosT = std::sqrt(1 - sin2T);
    return Vec3((eta * d + (eta * cosI - cosT) * n).normalized());
}

// Cosine-distributed direction about the unit normal n (pdf cos(theta) / pi), from two uniforms.
inline Vec3 cosineDirection(const Vec3& n, double u1, double u2) {
    const double r = std::sqrt(u1), phi = 2 * kPi * u2;
    Vec3 t, b;
    orthonormalBasis(n, t, b);
    return (r * std::cos(phi) * t + r * std::sin(phi) * b + std::sqrt(std::max(0.0, 1 - u1)) * n).normalized();
}
// cosineDirection for many directions about one normal, its tangent frame found once: the form-factor
// stage's rays. Its angle in float (rays are traced in float) and no normalisation (the direction is
// a unit vector by construction, to rounding): the two had taken a fifth of the stage's own time.
struct CosineSampler {
    explicit CosineSampler(const Vec3& normal) : n(normal) { orthonormalBasis(n, t, b); }
    Vec3 operator()(double u1, double u2) const {
        const double r = std::sqrt(u1);
        const float phi = float(2 * kPi * u2);
        const double c = std::cos(phi), s = std::sin(phi);
        return r * c * t + r * s * b + std::sqrt(std::max(0.0, 1 - u1)) * n;
    }
    Vec3 n, t, b;
};
// From an Rng or a PixelSampler.
template <typename Generator>
Vec3 cosineDirection(const Vec3& n, Generator& g) {
    const double u1 = g.uniform();
    return cosineDirection(n, u1, g.uniform());
}

}  // namespace penumbra
