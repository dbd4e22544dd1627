#include "solver/radiosity/vertex_radiosity.h"

#include <cstring>
#include <functional>

#include "core/cluster.h"
#include "core/error.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "mesh/refine.h"

namespace penumbra {
namespace {

// The radiosity at every patch corner, E + rho H, H one irradiance per vertex and normal group: the
// area-weighted mean of what the patches around it found there (`own`, per patch and corner);
// hanging vertices take their coarser edge's. Averaging the irradiance, not the radiosity, keeps each
// patch's own reflectance at its corners: a textured floor's dark tiles took their bright neighbours'
// radiosity otherwise (untextured, a vertex's patches share one reflectance and the two agree).
CornerValues radiosityAtVertices(const PatchSet& p, const RadiositySystem& s,
                                 const std::vector<std::vector<int>>& around, const CornerValues& own,
                                 double creaseDeg) {
    const double cosCrease = std::cos(creaseDeg * kPi / 180);
    CornerValues out(p.size());
    for (size_t i = 0; i < p.size(); ++i)
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
    for (size_t i = 0; i < p.size(); ++i)
        for (Rgb& value : out[i]) value = s.emission[i] + s.reflectance[i] * value;
    return out;
}

// Where patch i evaluates its corner k: the vertex lifted off the face and pulled a hair into it.
Vec3 cornerPoint(const PatchSet& p, size_t i, int k) {
    const Vec3& v = p.vertices[size_t(p.cornerVertex[i][size_t(k)])];
    return v + 1e-3 * (p.centroid[i] - v) + (1e-6 + 1e-4 * p.radius[i]) * p.normal[i];
}

// A value at a vertex that depends only on the point and the face's plane is the same for every
// coplanar patch around it: one patch of each such group (the lowest index) evaluates it, the others
// read its value. A flat grid's vertex is then evaluated once, not four times.
size_t sharerOf(const PatchSet& p, const std::vector<char>& specular, const std::vector<std::vector<int>>& around,
                size_t i, int v) {
    size_t best = i;
    for (int a : around[size_t(v)])
        if (size_t(a) < best && !specular[size_t(a)] && p.normal[size_t(a)].dot(p.normal[i]) > 1 - 1e-6)
            best = size_t(a);
    return best;
}

int cornerOf(const PatchSet& p, size_t i, int v) {
    for (int k = 0; k < p.cornerCount[i]; ++k)
        if (p.cornerVertex[i][size_t(k)] == v) return k;
    return -1;
}

// A value of type T at every patch corner, evaluated (in parallel, with a progress bar) once per
// coplanar group of patches around each vertex (sharerOf); `at` reads it for any patch's corner.
template <typename T>
class SharedCorners {
public:
    using Evaluate = std::function<T(size_t i, int k)>;  // at patch i's corner k; called from many threads
    SharedCorners(const PatchSet& p, const std::vector<char>& specular, const std::vector<std::vector<int>>& around,
                  Evaluate evaluate)
        : p_(p),
          specular_(specular),
          around_(around),
          evaluate_(std::move(evaluate)),
          value_(p.size()),
          done_(p.size(), {0, 0, 0, 0}) {
        Progress progress("vertex radiosity", int64_t(p.size()));
        parallelFor(
            int64_t(p.size()),
            [&](int64_t begin, int64_t end) {
                prepareTracingThread();
                for (int64_t ii = begin; ii < end; ++ii, progress.update()) {
                    const size_t i = size_t(ii);
                    if (specular_[i]) continue;
                    for (int k = 0; k < p_.cornerCount[i]; ++k)
                        if (sharerOf(p_, specular_, around_, i, p_.cornerVertex[i][size_t(k)]) == i) {
                            value_[i][size_t(k)] = evaluate_(i, k);
                            done_[i][size_t(k)] = 1;
                        }
                }
            },
            16);
        progress.done();
    }
    T at(size_t i, int k) const {
        const int v = p_.cornerVertex[i][size_t(k)];
        const size_t a = sharerOf(p_, specular_, around_, i, v);
        const size_t c = size_t(cornerOf(p_, a, v));
        // Near-coplanarity is not transitive: a sharer that deferred to another is redone here.
        return done_[a][c] ? value_[a][c] : evaluate_(i, k);
    }

private:
    const PatchSet& p_;
    const std::vector<char>& specular_;
    const std::vector<std::vector<int>>& around_;
    Evaluate evaluate_;
    std::vector<std::array<T, 4>> value_;
    std::vector<std::array<char, 4>> done_;
};

}  // namespace

Rgb directIrradiance(const PatchSet& p, const std::vector<Rgb>& B, const RayScene& rays, const Vec3& x, const Vec3& n,
                     const std::vector<size_t>& sources, int rayCount) {
    // Each source's unoccluded irradiance at x, in closed form.
    thread_local std::vector<Rgb> full;
    full.resize(sources.size());
    double total = 0;
    for (size_t k = 0; k < sources.size(); ++k) {
        const size_t j = sources[k];
        // Only a source's front lights x: a ceiling above a lamp hung 1 cm below it sees the lamp's
        // back, which the point-to-polygon factor alone counts as nearly a hemisphere of light.
        const bool front = p.normal[j].dot(x - p.centroid[j]) > 0;
        const double f = front ? pointPolygonFormFactor(x, n, p.corners[j].data(), p.cornerCount[j]) : 0;
        full[k] = f > 0 ? Rgb(f * B[j]) : Rgb::Zero();
        total += full[k].sum();
    }
    if (!(total > 0)) return Rgb::Zero();
    // Source k's visible fraction from the centres of a g x g grid on it, g^2 about its share of
    // rayCount (at least one): exact where x sees all of it or none. (The R2 sequence, tried first,
    // put 6 of 17 points in the first quarter of one axis: 11% off across a straight shadow edge.)
    Rgb h = Rgb::Zero();
    for (size_t k = 0; k < sources.size(); ++k) {
        if (!(full[k].sum() > 0)) continue;
        const int g = std::max(1, int(std::lround(std::sqrt(rayCount * full[k].sum() / total))));
        // Each point weighed by the kernel cos cos / r^2 of the closed form, and only the points in
        // front of x (the closed form leaves out the part of a source behind x's plane, and rays to it
        // meet x's own surface): counted plainly, the Cornell box's tall block's front face, whose
        // plane cuts the lamp, read 12% dark in the final gather that took the same share.
        double front = 0, arrived = 0;
        const Vec3& nj = p.normal[sources[k]];
        for (int a = 0; a < g; ++a)
            for (int b = 0; b < g; ++b) {
                const Vec3 y = p.pointAt(sources[k], (a + 0.5) / g, (b + 0.5) / g);
                const double w = sourceKernel(x, n, y, nj);
                if (!(w > 0)) continue;
                front += w;
                if (!rays.occluded(x, y, 1e-3)) arrived += w;
            }
        if (front > 0) h += full[k] * (arrived / front);
    }
    return h;
}

CornerValues gatherCorners(const PatchSet& p, const RadiositySystem& s, const FormFactorMatrix& F,
                           const std::vector<Rgb>& B, const RayScene& rays, double creaseDeg) {
    const size_t n = p.size();
    const auto around = patchesAround(p);
    std::vector<size_t> specularPatches;
    if (!s.transport.empty())
        for (size_t j = 0; j < n; ++j)
            if (s.specular[j]) specularPatches.push_back(j);
    // Per vertex (lifted off its face and pulled a hair into it), once per coplanar group: the
    // irradiance from the diffuse patches, and the share of the mirrors and glass in view
    // (point-to-patch factors).
    struct AtVertex {
        Rgb diffuse;
        double specularShare;
    };
    const SharedCorners<AtVertex> atVertex(p, s.specular, around, [&](size_t i, int k) {
        thread_local std::vector<char> sees;
        sees.resize(n);
        AtVertex out;
        const int v = p.cornerVertex[i][size_t(k)];
        const Vec3 x = cornerPoint(p, i, k);
        if (F.inRowBlocks()) {
            // Row blocks: this rank's rows alone, those that see a patch around the vertex (F(j, a)
            // is not zero exactly when F(a, j) is not: the analytic pairs are set together); the
            // ranks' sums are added below.
            std::fill(sees.begin(), sees.end(), 0);
            for (size_t j = F.firstRow(); j < F.endRow(); ++j)
                for (int a : around[size_t(v)])
                    if (p.normal[size_t(a)].dot(p.normal[i]) > 0.999 && F(j, size_t(a)) != 0) sees[j] = 1;
            out.diffuse = irradianceAtPoint(p, B, rays, x, p.normal[i], [&](size_t j) { return sees[j] != 0; });
        } else if (F.size() == p.size() && !F.sampled) {
            std::fill(sees.begin(), sees.end(), 0);
            for (int a : around[size_t(v)])
                if (p.normal[size_t(a)].dot(p.normal[i]) > 0.999) {
                    F.forEachInRow(size_t(a), [&](size_t j, float) { sees[j] = 1; });
                }
            out.diffuse = irradianceAtPoint(p, B, rays, x, p.normal[i], [&](size_t j) { return sees[j] != 0; });
        } else {
            out.diffuse = irradianceAtPoint(p, B, rays, x, p.normal[i], [&](size_t j) {
                return p.normal[j].dot(x - p.centroid[j]) > 0 && p.normal[i].dot(p.centroid[j] - x) > 0;
            });
        }
        out.specularShare = 0;
        for (size_t j : specularPatches) out.specularShare += visiblePointFactor(p, rays, x, p.normal[i], j);
        return out;
    });
    // Per (patch, corner): E + rho (diffuse + light through mirrors and glass). The latter is known per
    // patch (the transport's rays land anywhere on it): a corner takes it in proportion to how much of
    // the mirrors and glass it sees against the patch as a whole, F(x -> specular) / F(i -> specular).
    CornerValues own(n);
    parallelFor(
        int64_t(n),
        [&](int64_t begin, int64_t end) {
            prepareTracingThread();
            for (int64_t ii = begin; ii < end; ++ii) {
                const size_t i = size_t(ii);
                for (int k = 0; k < 4; ++k) own[i][size_t(k)] = Rgb::Zero();
                if (s.specular[i]) continue;
                const Rgb viaSpecular = s.transport.incoming(i, B);
                double patchShare = 0;
                if (F.size() == n)
                    for (size_t j : specularPatches) patchShare += F(i, j);
                for (int k = 0; k < p.cornerCount[i]; ++k) {
                    const AtVertex at = atVertex.at(i, k);
                    const Rgb specular =
                        patchShare > 0 ? Rgb(viaSpecular * (at.specularShare / patchShare)) : Rgb::Zero();
                    own[i][size_t(k)] = at.diffuse + specular;
                }
                if (p.isTriangle(i)) own[i][3] = own[i][2];
            }
        },
        16);
    if (F.inRowBlocks() && cluster::distributed()) {
        // Each rank gathered from its rows: the sums added in rank order (so within rounding of one
        // process's, which adds the patches in one sum: 1e-16 relative).
        const std::vector<std::string> all =
            cluster::allGather(std::string(reinterpret_cast<const char*>(own.data()), own.size() * sizeof(own[0])));
        for (size_t r = 0; r < all.size(); ++r) {
            PENUMBRA_CHECK(all[r].size() == own.size() * sizeof(own[0]));
            CornerValues theirs(n);
            std::memcpy(static_cast<void*>(theirs.data()), all[r].data(), all[r].size());
            for (size_t i = 0; i < n; ++i)
                for (size_t k = 0; k < 4; ++k) own[i][k] = r == 0 ? theirs[i][k] : Rgb(own[i][k] + theirs[i][k]);
        }
    }
    return radiosityAtVertices(p, s, around, own, creaseDeg);
}

CornerValues directCorners(const PatchSet& p, const RadiositySystem& s, const FormFactorMatrix& F,
                           const std::vector<Rgb>& B, const RayScene& rays, double creaseDeg) {
    const size_t n = p.size();
    const std::vector<char> small = smallSources(s);
    std::vector<size_t> sources;
    for (size_t j = 0; j < small.size(); ++j)
        if (small[j] && B[j].maxCoeff() > 0) sources.push_back(j);
    const std::vector<Rgb> H = gatherIrradiance(s, F, B);
    const auto around = patchesAround(p);
    // The small sources' light at each vertex, once per coplanar group.
    const SharedCorners<Rgb> directAt(p, s.specular, around, [&](size_t i, int k) {
        return directIrradiance(p, B, rays, cornerPoint(p, i, k), p.normal[i], sources);
    });
    CornerValues own(n);
    const int64_t first = int64_t(F.firstRow());  // in row blocks, this rank's rows; then shared
    parallelFor(
        int64_t(F.endRow()) - first,
        [&](int64_t begin, int64_t end) {
            prepareTracingThread();
            for (int64_t ii = first + begin; ii < first + end; ++ii) {
                const size_t i = size_t(ii);
                for (int k = 0; k < 4; ++k) own[i][size_t(k)] = Rgb::Zero();
                if (s.specular[i]) continue;
                // What the patch gathers from elsewhere than the small sources, as the solve found it.
                Rgb direct = Rgb::Zero();
                for (size_t j : sources) direct += double(F(i, j)) * B[j];
                const Rgb rest = H[i] - direct;
                for (int k = 0; k < p.cornerCount[i]; ++k) {
                    const Rgb atVertex = directAt.at(i, k);
                    own[i][size_t(k)] = (rest + atVertex).max(0.0);
                }
                if (p.isTriangle(i)) own[i][3] = own[i][2];
            }
        },
        16);
    shareRowValues(F, own);
    return radiosityAtVertices(p, s, around, own, creaseDeg);
}

CornerValues indirectCorners(const PatchSet& p, const RadiositySystem& s, const FormFactorMatrix& F,
                             const std::vector<Rgb>& B, double creaseDeg) {
    const std::vector<char> small = smallSources(s);
    if (small.empty() || F.size() != p.size() || B.size() != p.size()) return {};
    std::vector<Rgb> rest = B;
    for (size_t j = 0; j < small.size(); ++j)
        if (small[j]) rest[j] = (rest[j] - s.emission[j]).max(0.0);
    return interpolateCorners(p, gatherIrradiance(s, F, rest, true), creaseDeg);
}

}  // namespace penumbra
