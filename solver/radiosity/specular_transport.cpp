#include "solver/radiosity/specular_transport.h"

#include <algorithm>
#include <map>

#include "core/counters.h"
#include "core/log.h"
#include "core/optics.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "core/timer.h"

namespace penumbra {
namespace {

const Counter g_transportRays("specular.rays", "rays of the specular transport (first rays and bounces)");

struct Fate {
    int group;   // which specular object the ray met first (index into the row's objects)
    int target;  // patch (delivered) or object (absorbed)
    bool delivered;
    Rgb share;
};

struct RowResult {
    std::vector<std::pair<int, Rgb>> delivered;  // target patch, S(i -> j)
    std::vector<std::pair<int, Rgb>> lost;       // object, share absorbed
    double unresolved = 0;
    int64_t rays = 0;
};

}  // namespace

SpecularTransport computeSpecularTransport(const Scene& scene, const PatchSet& patches, const FormFactorMatrix& F,
                                           const SceneTracer& tracer, const SpecularSettings& settings,
                                           const SpecularTransport* previous, const std::vector<int>& only) {
    SpecularTransport out;
    if (!tracer.hasSpecular()) return out;
    Timer timer;
    const size_t n = patches.size();
    // The specular objects, numbered 0..K-1, and their patches.
    std::vector<int> group(scene.objects.size(), -1);
    std::vector<int> groupObject;
    std::vector<std::pair<size_t, int>> specularPatches;
    for (size_t i = 0; i < n; ++i) {
        const size_t o = size_t(patches.object[i]);
        if (scene.materialOf(scene.objects[o]).type == MaterialType::Diffuse) continue;
        if (group[o] < 0) {
            group[o] = int(groupObject.size());
            groupObject.push_back(int(o));
        }
        specularPatches.emplace_back(i, group[o]);
    }
    const size_t groups = groupObject.size();

    std::vector<RowResult> rows(n);
    Progress progress("specular transport", int64_t(n));
    parallelFor(int64_t(n), [&](int64_t begin, int64_t end) {
        prepareTracingThread();
        std::vector<double> share(groups);
        std::vector<int64_t> hits(groups);
        std::vector<Fate> fates;
        for (int64_t ii = begin; ii < end; ++ii, progress.update()) {
            const size_t i = size_t(ii);
            if (previous && !previous->empty() && only.size() == n && only[i] <= 0) {  // kept
                RowResult& row = rows[i];
                for (size_t k = previous->outStart[i]; k < previous->outStart[i + 1]; ++k) {
                    const size_t j = size_t(previous->outTarget[k]);
                    row.delivered.push_back({int(j), Rgb(previous->outWeight[k] * patches.area[j] / patches.area[i])});
                }
                for (size_t k = previous->lossStart[i]; k < previous->lossStart[i + 1]; ++k)
                    row.lost.push_back({previous->lossObject[k], previous->lossShare[k]});
                row.unresolved = previous->rowUnresolved[i];
                continue;
            }
            const Material& m = scene.materialOf(scene.objects[size_t(patches.object[i])]);
            if (m.type != MaterialType::Diffuse || ((m.reflectance <= 0).all() && !m.emits())) continue;
            std::fill(share.begin(), share.end(), 0.0);
            std::fill(hits.begin(), hits.end(), 0);
            bool any = false;
            for (const auto& [s, g] : specularPatches) {
                share[size_t(g)] += F(i, s);
                any = any || F(i, s) > 0;
            }
            if (!any) continue;
            fates.clear();
            RowResult& row = rows[i];
            Rng rng = streamRng(settings.seed, Stream::SpecularTransport, i);
            const int side = stratumSide(settings.raysPerPatch);
            for (int r = 0; r < side * side; ++r) {
                const double u1 = ((r % side) + rng.uniform()) / side, u2 = ((r / side) + rng.uniform()) / side;
                const Vec3 p = samplePatchPoint(patches, i, u1, u2, rng.uniform());
                const Vec3 d = cosineDirection(patches.normal[i], rng);
                const SurfaceHit h = tracer.trace(p + tracer.epsilon() * patches.normal[i], d);
                ++row.rays;
                if (!h.found || h.material->type == MaterialType::Diffuse || !h.frontFacing(d)) continue;
                const int g = group[size_t(h.object)];
                ++hits[size_t(g)];
                // What a mirror or a glass tint keeps is absorbed there.
                const SpecularWalk w =
                    walkSpecular(tracer, h, d, rng, settings.maxDepth, 0.0, [&](int object, const Rgb& kept) {
                        fates.push_back({g, object, false, kept});
                    });
                row.rays += w.bounces;
                switch (w.end) {
                    case WalkEnd::Escaped:
                        break;  // out of the scene: the remainder of the balance
                    case WalkEnd::Diffuse:
                        if (w.hit.frontFacing(w.dir))
                            fates.push_back({g, w.hit.patch, true, w.throughput});
                        else
                            fates.push_back({g, w.hit.object, false, w.throughput});
                        break;
                    case WalkEnd::Absorbed:
                    case WalkEnd::TooDeep:
                        fates.push_back({g, w.hit.object, false, w.throughput});
                        break;
                }
            }
            // Each ray that met object g first carries F(i, g) / hits(g) of patch i's light.
            std::map<int, Rgb> delivered, lost;
            for (const Fate& f : fates) {
                const double scale = share[size_t(f.group)] / double(hits[size_t(f.group)]);
                auto& into = f.delivered ? delivered : lost;
                auto [it, fresh] = into.emplace(f.target, Rgb::Zero());
                it->second += scale * f.share;
            }
            for (size_t g = 0; g < groups; ++g)
                if (hits[g] == 0 && share[g] > 0) {
                    auto [it, fresh] = lost.emplace(groupObject[g], Rgb::Zero());
                    it->second += share[g];
                    row.unresolved += share[g];
                }
            row.delivered.assign(delivered.begin(), delivered.end());
            row.lost.assign(lost.begin(), lost.end());
        }
    });
    progress.done();

    // Compressed rows by source (outgoing, losses), then by target (incoming).
    out.outStart.assign(n + 1, 0);
    out.lossStart.assign(n + 1, 0);
    std::vector<size_t> inCount(n + 1, 0);
    double area = 0;
    int64_t rays = 0;
    for (size_t i = 0; i < n; ++i) {
        out.outStart[i + 1] = out.outStart[i] + rows[i].delivered.size();
        out.lossStart[i + 1] = out.lossStart[i] + rows[i].lost.size();
        for (const auto& [j, s] : rows[i].delivered) ++inCount[size_t(j) + 1];
        g_transportRays.add(uint64_t(rows[i].rays));
        rays += rows[i].rays;
        out.unresolvedShare += patches.area[i] * rows[i].unresolved;
        out.rowUnresolved.push_back(rows[i].unresolved);
        area += patches.area[i];
    }
    out.unresolvedShare /= std::max(area, 1e-300);
    for (size_t i = 0; i < n; ++i) {
        for (const auto& [j, s] : rows[i].delivered) {
            out.outTarget.push_back(j);
            out.outWeight.push_back(patches.area[i] * s / patches.area[size_t(j)]);
        }
        for (const auto& [o, s] : rows[i].lost) {
            out.lossObject.push_back(o);
            out.lossShare.push_back(s);
        }
    }
    out.inStart.assign(n + 1, 0);
    for (size_t j = 0; j < n; ++j) out.inStart[j + 1] = out.inStart[j] + inCount[j + 1];
    out.inSource.resize(out.outTarget.size());
    out.inWeight.resize(out.outTarget.size());
    std::vector<size_t> fill(out.inStart.begin(), out.inStart.end() - 1);
    for (size_t i = 0; i < n; ++i)
        for (size_t k = out.outStart[i]; k < out.outStart[i + 1]; ++k) {
            const size_t j = size_t(out.outTarget[k]);
            out.inSource[fill[j]] = int(i);
            out.inWeight[fill[j]] = out.outWeight[k];
            ++fill[j];
        }
    out.seconds = timer.seconds();
    logInfo("specular transport: ", groups, " mirror/glass objects, ", rays, " rays, ", out.outTarget.size(),
            " transfers in ", out.seconds, " s");
    return out;
}

}  // namespace penumbra
