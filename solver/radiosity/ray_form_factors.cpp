#include "solver/radiosity/ray_form_factors.h"

#include <algorithm>
#include <atomic>
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
// How far ray origins are lifted off their patch along its normal: a millionth of the scene's size.
double originLift(const PatchSet& patches) {
    const double diagonal = patches.size() ? patchBounds(patches).diagonal().norm() : 1.0;
    return 1e-6 * std::max(diagonal, 1e-3);
}

// A ray origin on patch i (samplePatchPoint of u1, u2, u3), lifted off it and pulled a thousandth of
// the way in from the edge towards the centroid, as stratifiedPoint (form_factors.cpp) keeps its
// margin: an origin on the line where two walls meet starts on the other wall's plane, and its ray
// slips out through the seam.
Vec3 rayOrigin(const PatchSet& patches, size_t i, double u1, double u2, double u3, double lift) {
    const Vec3 onPatch = samplePatchPoint(patches, i, u1, u2, u3);
    return onPatch + 1e-3 * (patches.centroid[i] - onPatch) + lift * patches.normal[i];
}

// Whether an origin on patch i whose ray met a back face lies inside a solid (under a block whose
// open bottom stands on the patch): its rays along the normal and in four directions 5 degrees above
// the plane meet back faces too. From a point in the open, one-sided geometry may show its back in
// some directions (a table top facing up, seen from the floor beneath), not in all of them.
bool insideSolid(const PatchSet& patches, const RayScene& rays, size_t i, const Vec3& origin, int& cast) {
    const Vec3 n = patches.normal[i];
    Vec3 a, b;
    orthonormalBasis(n, a, b);
    const double up = std::sin(5 * kPi / 180), along = std::cos(5 * kPi / 180);
    for (const Vec3& d : {n, (along * a + up * n).eval(), (up * n - along * a).eval(), (along * b + up * n).eval(),
                          (up * n - along * b).eval()}) {
        const Hit h = rays.intersect(origin, d, 0, 1e30, RayView::Patches);
        ++cast;
        if (h.patch < 0 || patches.normal[size_t(h.patch)].dot(d) < 0) return false;
    }
    return true;
}

}  // namespace

FormFactorMatrix castFormFactors(const PatchSet& patches, const RayScene& rays, const FormFactorSettings& settings,
                                 const std::vector<char>& analyticColumns, const std::vector<char>& emitting) {
    Timer timer;
    const size_t n = patches.size();
    std::vector<size_t> analytic;
    for (size_t j = 0; j < analyticColumns.size() && j < n; ++j)
        if (analyticColumns[j]) analytic.push_back(j);
    std::vector<BackTransfer> back;
    // Each row's entries (column, value), columns ascending, until they are packed into one matrix.
    std::vector<std::vector<std::pair<int32_t, float>>> entries(n);
    std::vector<float> exposed(n, 1.0f);
    const double lift = originLift(patches);
    const int side = stratumSide(settings.raysPerPatch);
    const int count = side * side;
    std::mutex backMutex;
    std::atomic<int64_t> analyticNanos{0};  // thread time in the analytic columns
    Progress progress("form factors (rays)", int64_t(n));
    parallelFor(
        int64_t(n),
        [&](int64_t begin, int64_t end) {
            prepareTracingThread();
            std::vector<BackTransfer> myBack;
            std::map<int, int> backHits;
            // Front-face hits of the row, per patch: kept per thread across chunks (a chunk may be a
            // few rows, the array n long) and left all zero after each row.
            static thread_local std::vector<int> hits;
            if (hits.size() < n) hits.assign(n, 0);
            std::vector<int32_t> touched;
            for (int64_t ii = begin; ii < end; ++ii, progress.update()) {
                const size_t i = size_t(ii);
                Rng rng = streamRng(settings.seed, Stream::CastFormFactors, i);
                const Vec3 n0 = patches.normal[i];
                backHits.clear();
                touched.clear();
                int analyticHits = 0, inside = 0, followed = 0;
                const bool mayBeCovered = !(i < emitting.size() && emitting[i]);
                for (int k = 0; k < count; ++k) {
                    // Origins in one stratum of the patch, directions in another (a decorrelated
                    // permutation of the strata), both jittered.
                    const int a = k, b = decorrelatedStratum(k, count);
                    const double u1 = ((a % side) + rng.uniform()) / side, u2 = ((a / side) + rng.uniform()) / side;
                    const double d1 = ((b % side) + rng.uniform()) / side, d2 = ((b / side) + rng.uniform()) / side;
                    const Vec3 origin = rayOrigin(patches, i, u1, u2, rng.uniform(), lift);
                    const Vec3 dir = cosineDirection(n0, d1, d2);
                    const Hit h = rays.intersect(origin, dir, 0, 1e30, RayView::Patches);
                    if (h.patch < 0) continue;  // out of the scene
                    const size_t j = size_t(h.patch);
                    if (patches.normal[j].dot(dir) >= 0) {
                        if (mayBeCovered && insideSolid(patches, rays, i, origin, followed))
                            ++inside;
                        else
                            ++backHits[h.patch];
                    } else if (j < analyticColumns.size() && analyticColumns[j])
                        ++analyticHits;
                    else if (hits[j]++ == 0)
                        touched.push_back(int32_t(j));
                }
                g_castRays.add(uint64_t(count + followed));
                // The origins in the open, and their share of the patch (all of them but in a solid).
                const int open = count - inside;
                exposed[i] = float(open) / float(count);
                std::vector<std::pair<int32_t, float>>& row = entries[i];
                if (open == 0) continue;  // wholly inside a solid: no light reaches it
                // The analytic columns, computed as the analytic matrix computes them (over the whole
                // patch, whose covered part sees no source), then as a mean over the uncovered part.
                double exact = 0;
                const Timer columns;
                for (size_t j : analytic) {
                    const double f = frontFormFactor(patches, rays, i, j, settings) / exposed[i];
                    if (f > 0) row.push_back({int32_t(j), float(f)});
                    exact += f;
                }
                if (!analytic.empty()) analyticNanos += int64_t(columns.seconds() * 1e9);
                // Scale the rays' other fates so that all fates sum to one; should every ray have met an
                // analytic column (no other fate to scale), those columns take the whole row.
                const double rayShare = double(analyticHits) / open;
                double scale = 1;
                if (!analytic.empty() && rayShare < 1)
                    scale = std::max(0.0, 1 - exact) / (1 - rayShare);
                else if (!analytic.empty() && exact > 0)
                    for (auto& e : row) e.second = float(e.second / exact);
                for (int32_t j : touched) {
                    row.push_back({j, float(scale * hits[size_t(j)] / open)});
                    hits[size_t(j)] = 0;
                }
                std::sort(row.begin(), row.end());
                // A_i F(i -> back of j), with the light of the uncovered part, exposed[i] A_i.
                for (const auto& [j, h] : backHits)
                    myBack.push_back({int(i), j, scale * patches.area[i] * double(h) / double(count)});
            }
            std::lock_guard<std::mutex> lock(backMutex);
            back.insert(back.end(), myBack.begin(), myBack.end());
        },
        8);
    progress.done();
    std::vector<uint64_t> start(n + 1, 0);
    for (size_t i = 0; i < n; ++i) start[i + 1] = start[i] + entries[i].size();
    std::vector<int32_t> column(start[n]);
    std::vector<float> value(start[n]);
    for (size_t i = 0; i < n; ++i) {
        for (size_t k = 0; k < entries[i].size(); ++k)
            column[start[i] + k] = entries[i][k].first, value[start[i] + k] = entries[i][k].second;
        std::vector<std::pair<int32_t, float>>().swap(entries[i]);
    }
    FormFactorMatrix F(n, std::move(start), std::move(column), std::move(value));
    F.sampled = true;
    F.reciprocal = false;
    F.backTransfers = std::move(back);
    F.exposed = std::move(exposed);
    std::sort(F.backTransfers.begin(), F.backTransfers.end(), [](const BackTransfer& a, const BackTransfer& b) {
        return a.from != b.from ? a.from < b.from : a.to < b.to;
    });
    logInfo("form factors (rays): ", n, " patches, ", count, " rays each, ", uint64_t(count) * n, " rays in ",
            timer.seconds(), " s; ", F.entries(), " entries stored, ", double(F.bytes()) / (1 << 20), " MiB; ",
            analytic.size(), " analytic columns (small sources) took ", double(analyticNanos) * 1e-9 / threadCount(),
            " s of it");
    return F;
}

Closure sceneClosure(const PatchSet& patches, const RayScene& rays, int raysPerPatch, uint64_t seed) {
    const size_t n = patches.size();
    const double lift = originLift(patches);
    std::atomic<bool> open{false}, back{false};
    parallelFor(
        int64_t(n),
        [&](int64_t begin, int64_t end) {
            prepareTracingThread();
            for (int64_t ii = begin; ii < end && !open.load(std::memory_order_relaxed); ++ii) {
                const size_t i = size_t(ii);
                Rng rng = streamRng(seed, Stream::Closure, i);
                for (int k = 0; k < raysPerPatch; ++k) {
                    double u[5];
                    for (double& x : u) x = rng.uniform();
                    const Vec3 origin = rayOrigin(patches, i, u[0], u[1], u[2], lift);
                    const Vec3 dir = cosineDirection(patches.normal[i], u[3], u[4]);
                    const Hit h = rays.intersect(origin, dir, 0, 1e30, RayView::Patches);
                    if (h.patch < 0) {
                        open = true;
                        break;
                    }
                    if (patches.normal[size_t(h.patch)].dot(dir) >= 0) back = true;
                }
            }
        },
        16);
    Closure c;
    c.sealed = n > 0 && !open;
    c.frontOnly = c.sealed && !back;
    return c;
}

}  // namespace penumbra
