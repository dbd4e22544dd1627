#include "solver/radiosity/vertex_radiosity.h"

#include "core/parallel.h"
#include "core/progress.h"
#include "mesh/refine.h"

namespace penumbra {

CornerValues gatherCorners(const PatchSet& p, const RadiositySystem& s, const FormFactorMatrix& F,
                           const std::vector<Rgb>& B, const RayScene& rays, double creaseDeg) {
    const size_t n = p.size();
    const auto around = patchesAround(p);
    const double cosCrease = std::cos(creaseDeg * kPi / 180);
    // Per (patch, corner): the equation at the vertex, lifted off the patch and pulled a hair into it.
    CornerValues own(n);
    std::vector<size_t> specularPatches;
    if (!s.transport.empty())
        for (size_t j = 0; j < n; ++j)
            if (s.specular[j]) specularPatches.push_back(j);
    Progress progress("vertex radiosity", int64_t(n));
    parallelFor(
        int64_t(n),
        [&](int64_t begin, int64_t end) {
            prepareTracingThread();
            std::vector<char> sees(n);
            for (int64_t ii = begin; ii < end; ++ii) {
                const size_t i = size_t(ii);
                for (int k = 0; k < 4; ++k) own[i][size_t(k)] = s.emission[i];
                progress.update(1);
                if (s.specular[i]) continue;
                // Light arriving through mirrors and glass is known per patch (the transport's rays land
                // anywhere on it): a corner takes it in proportion to how much of the mirrors and glass
                // it sees against the patch as a whole, F(x -> specular) / F(i -> specular).
                const Rgb viaSpecular = s.transport.incoming(i, B);
                double patchShare = 0;
                if (F.size() == n)
                    for (size_t j : specularPatches) patchShare += F(i, j);
                for (int k = 0; k < p.cornerCount[i]; ++k) {
                    const int v = p.cornerVertex[i][size_t(k)];
                    const double lift = 1e-6 + 1e-4 * p.radius[i];
                    const Vec3 x =
                        p.vertices[size_t(v)] + 1e-3 * (p.centroid[i] - p.vertices[size_t(v)]) + lift * p.normal[i];
                    Rgb h;
                    if (F.size() == p.size() && !F.sampled) {
                        std::fill(sees.begin(), sees.end(), 0);
                        for (int a : around[size_t(v)])
                            if (p.normal[size_t(a)].dot(p.normal[i]) > 0.999) {
                                const float* row = F.row(size_t(a));
                                for (size_t j = 0; j < n; ++j) sees[j] |= row[j] > 0;
                            }
                        h = irradianceAtPoint(p, B, rays, x, p.normal[i], [&](size_t j) { return sees[j] != 0; });
                    } else {
                        h = irradianceAtPoint(p, B, rays, x, p.normal[i], [&](size_t j) {
                            return p.normal[j].dot(x - p.centroid[j]) > 0 && p.normal[i].dot(p.centroid[j] - x) > 0;
                        });
                    }
                    Rgb specular = Rgb::Zero();
                    if (patchShare > 0) {
                        double pointShare = 0;
                        for (size_t j : specularPatches) pointShare += visiblePointFactor(p, rays, x, p.normal[i], j);
                        specular = viaSpecular * (pointShare / patchShare);
                    }
                    own[i][size_t(k)] = s.emission[i] + s.reflectance[i] * (h + specular);
                }
                if (p.isTriangle(i)) own[i][3] = own[i][2];
            }
        },
        16);
    progress.done();
    // One value per vertex and normal group: the area-weighted mean of what the patches found there.
    CornerValues out(n);
    for (size_t i = 0; i < n; ++i)
        for (int k = 0; k < 4; ++k) {
            const int v = p.cornerVertex[i][size_t(k)];
            Rgb sum = Rgb::Zero();
            double weight = 0;
            for (int j : around[size_t(v)])
                if (p.normal[size_t(j)].dot(p.normal[i]) >= cosCrease)
                    for (int c = 0; c < p.cornerCount[size_t(j)]; ++c)
                        if (p.cornerVertex[size_t(j)][size_t(c)] == v) {
                            sum += p.area[size_t(j)] * own[size_t(j)][size_t(c)];
                            weight += p.area[size_t(j)];
                            break;
                        }
            out[i][size_t(k)] = weight > 0 ? Rgb(sum / weight) : own[i][size_t(k)];
        }
    joinHangingVertices(p, around, out, creaseDeg);
    return out;
}

}  // namespace penumbra
