#include "solver/radiosity/refinement.h"

#include <algorithm>
#include <numeric>

#include "core/parallel.h"
#include "solver/radiosity/vertex_radiosity.h"

namespace penumbra {
namespace {

double brightness(const Rgb& b) { return b.sum() / 3; }

// Up to five points of a patch: its centroid and its corners pulled a tenth of the way in.
int samplePoints(const PatchSet& p, size_t i, Vec3* out) {
    out[0] = p.centroid[i];
    for (int k = 0; k < p.cornerCount[i]; ++k)
        out[k + 1] = p.corners[i][size_t(k)] + 0.1 * (p.centroid[i] - p.corners[i][size_t(k)]);
    return 1 + p.cornerCount[i];
}

// Where linear interpolation between exact corner values is farthest from them: the centroid and
// the midpoints of the edges (pulled a tenth of the way in, off the neighbours' edges).
int estimatorPoints(const PatchSet& p, size_t i, Vec3* out) {
    out[0] = p.centroid[i];
    const int n = p.cornerCount[i];
    for (int k = 0; k < n; ++k) {
        const Vec3 mid = 0.5 * (p.corners[i][size_t(k)] + p.corners[i][size_t((k + 1) % n)]);
        out[k + 1] = mid + 0.1 * (p.centroid[i] - mid);
    }
    return 1 + n;
}

}  // namespace

SplitChoice chooseSplits(const PatchSet& p, const RadiositySystem& s, const FormFactorMatrix& F,
                         const std::vector<Rgb>& B, const CornerValues& corners, const RayScene& rays,
                         const RefineSettings& settings, double minArea, size_t maxSplits) {
    const size_t n = p.size();
    double weighted = 0, area = 0;
    for (size_t i = 0; i < n; ++i)
        if (!s.specular[i] && s.emission[i].maxCoeff() <= 0)
            weighted += s.area[i] * brightness(B[i]), area += s.area[i];
    const double floor = 0.1 * (area > 0 ? weighted / area : 0) + 1e-300;
    Rgb channelFloor = Rgb::Zero();
    for (size_t i = 0; i < n; ++i)
        if (!s.specular[i] && s.emission[i].maxCoeff() <= 0) channelFloor += s.area[i] * B[i];
    channelFloor = 0.1 * channelFloor / std::max(area, 1e-300) + 1e-300;
    // The brightest emitters (at most 16) stand for the light whose shadows are looked for.
    std::vector<int> emitters;
    for (size_t i = 0; i < n; ++i)
        if (s.emission[i].maxCoeff() > 0) emitters.push_back(int(i));
    std::sort(emitters.begin(), emitters.end(), [&](int a, int b) {
        return s.area[size_t(a)] * s.emission[size_t(a)].sum() > s.area[size_t(b)] * s.emission[size_t(b)].sum();
    });
    if (emitters.size() > 16) emitters.resize(16);

    // What the display shows (`corners`, interpolated across each patch) is held against the
    // radiosity equation itself at up to five points of the patch (estimatorPoints). Where the two disagree (light that
    // bends near a contact or a corner, or jumps at a shadow) the mesh cannot hold the light.
    std::vector<double> gradient(n, 0), shadow(n, 0);
    parallelFor(
        int64_t(n),
        [&](int64_t begin, int64_t end) {
            prepareTracingThread();
            for (int64_t ii = begin; ii < end; ++ii) {
                const size_t i = size_t(ii);
                if (s.specular[i] || p.area[i] < 4 * minArea) continue;
                Vec3 points[5];
                const int count = estimatorPoints(p, i, points);
                Rgb mean = Rgb::Zero();
                for (int k = 0; k < p.cornerCount[i]; ++k) mean += corners[i][size_t(k)] / double(p.cornerCount[i]);
                Rgb gathered[5];
                // The patches row i sees, in column order (the test of every patch in the scene at each
                // point had made a round quadratic in the patches: 21% of a 34,000-patch round).
                static thread_local std::vector<size_t> sees;
                sees.clear();
                F.forEachInRow(i, [&](size_t j, float) { sees.push_back(j); });
                const double lift = 1e-6 + 1e-4 * p.radius[i];
                for (int k = 0; k < count; ++k)
                    gathered[k] = irradianceAtPoint(p, B, rays, points[k] + lift * p.normal[i], p.normal[i], sees);
                for (int k = 0; k < count; ++k) {
                    const Rgb solved = s.emission[i] + s.reflectance[i] * gathered[k];
                    const int nc = p.cornerCount[i];
                    const Rgb shown =
                        k == 0 ? mean
                               : Rgb(0.45 * (corners[i][size_t(k - 1)] + corners[i][size_t(k % nc)]) + 0.1 * mean);
                    // Per channel: colour bled from a red wall is an error the mean of the channels hides.
                    for (int c = 0; c < 3; ++c)
                        gradient[i] = std::max(gradient[i],
                                               std::abs(shown[c] - solved[c]) / std::max(solved[c], channelFloor[c]));
                }
                Vec3 mine[5], theirs[5];
                const int m = samplePoints(p, i, mine);
                for (int e : emitters) {
                    if (size_t(e) == i) continue;
                    const Vec3 d = p.centroid[size_t(e)] - p.centroid[i];
                    const double r2 = d.squaredNorm(), cosI = p.normal[i].dot(d), cosE = -p.normal[size_t(e)].dot(d);
                    if (cosI <= 0 || cosE <= 0) continue;
                    const int t = samplePoints(p, size_t(e), theirs);
                    int visible = 0, cast = 0;
                    for (int a = 0; a < m; ++a)
                        for (int b = 0; b < t; ++b, ++cast)
                            visible +=
                                !rays.occluded(mine[a] + 1e-6 * p.normal[i], theirs[b] + 1e-6 * p.normal[size_t(e)]);
                    if (visible == 0 || visible == cast) continue;
                    // The emitter's share of the patch's light, by the point-to-disc form factor.
                    const double f = p.area[size_t(e)] * cosI * cosE / (r2 * (kPi * r2 + p.area[size_t(e)]));
                    const double share =
                        brightness(s.reflectance[i] * f * B[size_t(e)]) / std::max(brightness(B[i]), floor);
                    shadow[i] = std::max(shadow[i], share);
                }
            }
        },
        64);

    SplitChoice choice;
    choice.split.assign(n, 0);
    std::vector<double> score(n);
    std::vector<int> order;
    for (size_t i = 0; i < n; ++i) {
        score[i] = std::max(gradient[i], shadow[i]);
        if (score[i] > settings.tolerance) order.push_back(int(i));
    }
    std::sort(order.begin(), order.end(), [&](int a, int b) { return score[size_t(a)] > score[size_t(b)]; });
    if (order.size() > maxSplits) order.resize(maxSplits);
    for (int i : order) {
        choice.split[size_t(i)] = 1;
        choice.byGradient += gradient[size_t(i)] > settings.tolerance;
        choice.byShadow += shadow[size_t(i)] > settings.tolerance;
    }
    return choice;
}

}  // namespace penumbra
