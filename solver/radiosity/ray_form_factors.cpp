#include "solver/radiosity/ray_form_factors.h"

#include <algorithm>
#include <map>
#include <mutex>

#include "core/counters.h"
#include "core/log.h"
#include "core/optics.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "core/timer.h"
#include "solver/tracer.h"

namespace penumbra {
namespace {
const Counter g_castRays("form_factors.cast_rays", "rays cast for ray-cast form factors (--form-factors rays)");
}  // namespace

FormFactorMatrix castFormFactors(const PatchSet& patches, const RayScene& rays, const FormFactorSettings& settings,
                                 const std::vector<char>& analyticColumns) {
    Timer timer;
    const size_t n = patches.size();
    std::vector<size_t> analytic;
    for (size_t j = 0; j < analyticColumns.size() && j < n; ++j)
        if (analyticColumns[j]) analytic.push_back(j);
    FormFactorMatrix F(n);
    F.sampled = true;
    const double diagonal = n ? patchBounds(patches).diagonal().norm() : 1.0;
    const double lift = 1e-6 * std::max(diagonal, 1e-3);
    int side = 1;
    while (side * side < settings.raysPerPatch) ++side;
    const int count = side * side;
    std::mutex backMutex;
    Progress progress("form factors (rays)", int64_t(n));
    parallelFor(
        int64_t(n),
        [&](int64_t begin, int64_t end) {
            prepareTracingThread();
            std::vector<BackTransfer> myBack;
            std::map<int, int> backHits;
            for (int64_t ii = begin; ii < end; ++ii, progress.update()) {
                const size_t i = size_t(ii);
                Rng rng = streamRng(settings.seed, Stream::CastFormFactors, i);
                const Vec3 n0 = patches.normal[i];
                float* row = &F(i, 0);
                const float share = 1.0f / float(count);
                backHits.clear();
                int analyticHits = 0;
                for (int k = 0; k < count; ++k) {
                    // Origins in one stratum of the patch, directions in another (a decorrelated
                    // permutation of the strata), both jittered.
                    const int a = k, b = decorrelatedStratum(k, count);
                    const double u1 = ((a % side) + rng.uniform()) / side, u2 = ((a / side) + rng.uniform()) / side;
                    const double d1 = ((b % side) + rng.uniform()) / side, d2 = ((b / side) + rng.uniform()) / side;
                    const Vec3 origin = samplePatchPoint(patches, i, u1, u2, rng.uniform()) + lift * n0;
                    const Vec3 dir = cosineDirection(n0, d1, d2);
                    const Hit h = rays.intersect(origin, dir, 0, 1e30, RayView::Patches);
                    if (h.patch < 0) continue;  // out of the scene
                    const size_t j = size_t(h.patch);
                    if (patches.normal[j].dot(dir) >= 0)
                        ++backHits[h.patch];
                    else if (j < analyticColumns.size() && analyticColumns[j])
                        ++analyticHits;
                    else
                        row[j] += share;
                }
                g_castRays.add(uint64_t(count));
                // The analytic columns, computed as the analytic matrix computes them.
                double exact = 0;
                for (size_t j : analytic) {
                    const double f = frontFormFactor(patches, rays, i, j, settings);
                    row[j] = float(f);
                    exact += f;
                }
                // Scale the rays' other fates so that all fates sum to one; should every ray have met an
                // analytic column (no other fate to scale), those columns take the whole row.
                const double rayShare = double(analyticHits) / count;
                double scale = 1;
                if (!analytic.empty() && rayShare < 1) {
                    scale = std::max(0.0, 1 - exact) / (1 - rayShare);
                    for (size_t j = 0; j < n; ++j)
                        if (!(j < analyticColumns.size() && analyticColumns[j])) row[j] = float(row[j] * scale);
                } else if (!analytic.empty() && exact > 0) {
                    for (size_t j : analytic) row[j] = float(row[j] / exact);
                }
                for (const auto& [j, hits] : backHits)
                    myBack.push_back({int(i), j, scale * patches.area[i] * double(hits) / double(count)});
            }
            std::lock_guard<std::mutex> lock(backMutex);
            F.backTransfers.insert(F.backTransfers.end(), myBack.begin(), myBack.end());
        },
        8);
    progress.done();
    std::sort(F.backTransfers.begin(), F.backTransfers.end(), [](const BackTransfer& a, const BackTransfer& b) {
        return a.from != b.from ? a.from < b.from : a.to < b.to;
    });
    logInfo("form factors (rays): ", n, " patches, ", count, " rays each, ", uint64_t(count) * n, " rays in ",
            timer.seconds(), " s");
    return F;
}

}  // namespace penumbra
