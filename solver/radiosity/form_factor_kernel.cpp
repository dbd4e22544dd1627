#include "solver/radiosity/form_factor_kernel.h"

#include <cmath>

namespace penumbra {

double pointPolygonFormFactor(const Vec3& x, const Vec3& n, const Vec3* poly, int count) {
    // Clip to the half-space n . (p - x) > 0: only what lies in front of x is seen. Most points see
    // the whole polygon, which then needs no copy.
    double height[4];
    bool allInFront = true;
    for (int k = 0; k < count; ++k) {
        height[k] = n.dot(poly[k] - x);
        allInFront = allInFront && height[k] > 0;
    }
    Vec3 clipped[8];
    const Vec3* p = poly;
    int m = count;
    if (!allInFront) {
        m = 0;
        for (int k = 0; k < count; ++k) {
            const int next = k + 1 < count ? k + 1 : 0;
            const double da = height[k], db = height[next];
            if (da > 0) clipped[m++] = poly[k];
            if ((da > 0) != (db > 0)) clipped[m++] = poly[k] + (da / (da - db)) * (poly[next] - poly[k]);
        }
        if (m < 3) return 0;
        p = clipped;
    }
    // Lambert: F = 1/(2 pi) sum_k gamma_k n . (R_k x R_k+1) / |R_k x R_k+1|. Both factors are
    // invariant to the lengths of R_k and R_k+1 (gamma_k = atan2(|R_k x R_k+1|, R_k . R_k+1)), so
    // the vectors need no normalising.
    double sum = 0;
    Vec3 ra = p[0] - x;
    const Vec3 first = ra;
    for (int k = 0; k < m; ++k) {
        const Vec3 rb = k + 1 < m ? Vec3(p[k + 1] - x) : first;
        const Vec3 c = ra.cross(rb);
        const double s = c.norm();
        if (s > 0) sum += n.dot(c) / s * std::atan2(s, ra.dot(rb));  // |n . c| <= s: bounded
        ra = rb;
    }
    return std::abs(sum) / (2 * kPi);
}

double pointPolygonDistance(const Vec3& x, const Vec3* poly, int count) {
    const Vec3 normal = (poly[1] - poly[0]).cross(poly[2] - poly[0]) +
                        (count == 4 ? (poly[2] - poly[0]).cross(poly[3] - poly[0]) : Vec3::Zero());
    const Vec3 nn = normal.normalized();
    const double height = nn.dot(x - poly[0]);
    const Vec3 projected = x - height * nn;
    bool inside = true;
    for (int k = 0; k < count && inside; ++k)
        inside = (poly[(k + 1) % count] - poly[k]).cross(projected - poly[k]).dot(nn) >= 0;
    if (inside) return std::abs(height);
    double best = 1e300;
    for (int k = 0; k < count; ++k) {
        const Vec3& a = poly[k];
        const Vec3 e = poly[(k + 1) % count] - a;
        const double t = std::clamp(e.dot(x - a) / std::max(e.squaredNorm(), 1e-300), 0.0, 1.0);
        best = std::min(best, (x - (a + t * e)).norm());
    }
    return best;
}

namespace {

// Gauss-Legendre nodes and weights on [0, 1] for 1, 2 and 3 points.
constexpr double kG2 = 0.2886751345948129;  // 0.5 / sqrt(3)
constexpr double kG3 = 0.3872983346207417;  // 0.5 * sqrt(3/5)
const double kNodes[3][3] = {{0.5, 0, 0}, {0.5 - kG2, 0.5 + kG2, 0}, {0.5 - kG3, 0.5, 0.5 + kG3}};
const double kWeights[3][3] = {{1, 0, 0}, {0.5, 0.5, 0}, {5.0 / 18, 8.0 / 18, 5.0 / 18}};

struct Cubature {
    const PatchSet& patches;
    size_t s, r;
    const Vec3* poly;
    int count;
    double sourceRadius;
    double tolerance;
    int maxDepth;
    int cutDepth;
    uint64_t evaluations = 0;

    double height(const Vec3& x) const { return patches.normal[r].dot(x - patches.centroid[r]); }

    void cell(double u0, double v0, double size, int depth, AreaFactors& out) {
        const Vec3 centre = patches.pointAt(s, u0 + size / 2, v0 + size / 2);
        const double diameter = 2 * sourceRadius * size;
        const double distance = pointPolygonDistance(centre, poly, count);
        int order = 0;
        if (distance > 0) {
            // The lowest order g with half^(2g) within the tolerance (by products: std::pow was 1.5%
            // of the Cornell box's solve).
            const double square = (diameter / (2 * distance)) * (diameter / (2 * distance));
            double power = square;
            for (int g = 1; g <= 3 && order == 0; ++g, power *= square)
                if (power <= tolerance) order = g;
        }
        // A cell that r's plane cuts holds points that see both of r's faces: split it, down to
        // cutDepth (the cut runs across the whole patch, so deeper splits cost 2^depth cells).
        if (order > 0 && depth < cutDepth && std::abs(height(centre)) < diameter) {
            const double h0 = height(patches.pointAt(s, u0, v0)), h1 = height(patches.pointAt(s, u0 + size, v0)),
                         h2 = height(patches.pointAt(s, u0 + size, v0 + size)),
                         h3 = height(patches.pointAt(s, u0, v0 + size));
            // Corners on the plane (a patch touching r's plane along an edge) do not make a cut.
            const double eps = 1e-9 * diameter;
            if (std::min({h0, h1, h2, h3}) < -eps && std::max({h0, h1, h2, h3}) > eps) order = 0;
        }
        if (order == 0 && depth < maxDepth) {
            const double h = size / 2;
            cell(u0, v0, h, depth + 1, out);
            cell(u0 + h, v0, h, depth + 1, out);
            cell(u0, v0 + h, h, depth + 1, out);
            cell(u0 + h, v0 + h, h, depth + 1, out);
            return;
        }
        if (order == 0) order = 3;
        const Vec3& n = patches.normal[s];
        for (int a = 0; a < order; ++a)
            for (int b = 0; b < order; ++b) {
                const double u = u0 + size * kNodes[order - 1][a], v = v0 + size * kNodes[order - 1][b];
                const double w = kWeights[order - 1][a] * kWeights[order - 1][b] * size * size;
                const Vec3 x = patches.pointAt(s, u, v);
                const double f = w * patches.jacobian(s, u, v) * pointPolygonFormFactor(x, n, poly, count);
                (height(x) >= 0 ? out.front : out.back) += f;
            }
        evaluations += uint64_t(order * order);
    }
};

}  // namespace

AreaFactors unoccludedAreaFactors(const PatchSet& patches, size_t s, size_t r, const CubatureSettings& settings,
                                  uint64_t* evaluations) {
    Cubature c{patches,
               s,
               r,
               patches.corners[r].data(),
               patches.cornerCount[r],
               patches.boundingRadius(s),
               settings.tolerance,
               settings.maxDepth,
               settings.cutDepth};
    AreaFactors out;
    c.cell(0, 0, 1, 0, out);
    if (evaluations) *evaluations += c.evaluations;
    return out;
}

}  // namespace penumbra
