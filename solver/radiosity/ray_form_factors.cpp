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

// Whether all of patch i lies inside one solid (the floor under the middle of a block): its centre and
// its corners (pulled in from the edge as ray origins are) all do, by insideSolid. Asked at a patch's
// first origin found inside a solid; a patch wholly inside then costs about 30 rays instead of its
// rays' six each. Exact for convex solids (every box of a scene); a notch in a
// solid narrower than the patch, none of whose corners it reaches, would be taken as covered too.
bool whollyInside(const PatchSet& patches, const RayScene& rays, size_t i, double lift, int& cast) {
    const Vec3 lifted = lift * patches.normal[i];
    if (!insideSolid(patches, rays, i, patches.centroid[i] + lifted, cast)) return false;
    for (int k = 0; k < patches.cornerCount[i]; ++k) {
        const Vec3& c = patches.corners[i][size_t(k)];
        if (!insideSolid(patches, rays, i, c + 1e-3 * (patches.centroid[i] - c) + lifted, cast)) return false;
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
    // Each row's entries (column, value), columns ascending, until they are packed into one matrix;
    // the mean rows likewise, for the patches part of which is hidden.
    std::vector<std::vector<std::pair<int32_t, float>>> entries(n), meanEntries(n);
    std::vector<float> exposed(n, 1.0f), seen(n, 1.0f);
    const double lift = originLift(patches);
    const int side = stratumSide(settings.raysPerPatch);
    const int count = side * side;
    std::mutex backMutex;
    std::atomic<int64_t> analyticNanos{0};  // thread time in the analytic columns
    std::atomic<size_t> hidden{0};          // patches with a mean row
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
            // Each origin and the front patch its ray met (-1: anything else), for the second rays.
            std::vector<Vec3> origins(static_cast<size_t>(count));
            std::vector<int32_t> landed(static_cast<size_t>(count));
            std::vector<int> order;  // the direction stratum of each origin stratum
            for (int64_t ii = begin; ii < end; ++ii, progress.update()) {
                const size_t i = size_t(ii);
                Rng rng = streamRng(settings.seed, Stream::CastFormFactors, i);
                const Vec3 n0 = patches.normal[i];
                backHits.clear();
                touched.clear();
                int analyticHits = 0, inside = 0, followed = 0, backs = 0;
                int wholly = 0;  // the rays cast before the patch was found wholly inside a solid
                const bool mayBeCovered = !(i < emitting.size() && emitting[i]);
                shuffledStrata(order, count, rng);
                for (int k = 0; k < count; ++k) {
                    // Origins in one stratum of the patch, directions in another (a random
                    // permutation of the strata), both jittered.
                    const int a = k, b = order[size_t(k)];
                    const double u1 = ((a % side) + rng.uniform()) / side, u2 = ((a / side) + rng.uniform()) / side;
                    const double d1 = ((b % side) + rng.uniform()) / side, d2 = ((b / side) + rng.uniform()) / side;
                    const Vec3 origin = rayOrigin(patches, i, u1, u2, rng.uniform(), lift);
                    const Vec3 dir = cosineDirection(n0, d1, d2);
                    const Hit h = rays.intersect(origin, dir, 0, 1e30, RayView::Patches);
                    origins[size_t(k)] = origin;
                    landed[size_t(k)] = -1;
                    if (h.patch < 0) continue;  // out of the scene
                    const size_t j = size_t(h.patch);
                    if (patches.normal[j].dot(dir) >= 0) {
                        if (mayBeCovered && insideSolid(patches, rays, i, origin, followed)) {
                            // At the first origin inside a solid, whether the whole patch is.
                            if (++inside == 1 && whollyInside(patches, rays, i, lift, followed)) {
                                wholly = k + 1;
                                break;
                            }
                        } else {
                            ++backHits[h.patch];
                            ++backs;
                        }
                    } else if (j < analyticColumns.size() && analyticColumns[j]) {
                        ++analyticHits;
                    } else {
                        landed[size_t(k)] = int32_t(j);
                        if (hits[j]++ == 0) touched.push_back(int32_t(j));
                    }
                }
                if (wholly) {  // no light reaches it, none leaves it
                    for (int32_t j : touched) hits[size_t(j)] = 0;
                    exposed[i] = 0;
                    g_castRays.add(uint64_t(wholly + followed));
                    continue;
                }
                // The origins in the open, and their share of the patch (all of them but in a solid).
                const int open = count - inside;
                exposed[i] = float(open) / float(count);
                std::vector<std::pair<int32_t, float>>& row = entries[i];
                if (open == 0) {  // wholly inside a solid: no light reaches it
                    g_castRays.add(uint64_t(count + followed));
                    continue;
                }
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
                if (backs > 0) {
                    // Part of the patch is hidden: what the rest of the scene sees is the light of each
                    // point weighted by how much of the scene sees it, its share of directions that
                    // meet no back face. That weight is a second ray from the origin, independent of
                    // the first: an origin's light counts where its second ray meets no back face,
                    // over the origins whose first ray met none. The row above stays as the mean.
                    const int unhidden = open - backs;
                    seen[i] = float(unhidden) / float(open);
                    ++hidden;
                    meanEntries[i].swap(row);
                    int second = 0;
                    touched.clear();
                    for (int k = 0; k < count; ++k) {
                        const int32_t j = landed[size_t(k)];
                        if (j < 0) continue;
                        const Vec3 dir = cosineDirection(n0, rng.uniform(), rng.uniform());
                        const Hit h = rays.intersect(origins[size_t(k)], dir, 0, 1e30, RayView::Patches);
                        ++second;
                        if (h.patch >= 0 && patches.normal[size_t(h.patch)].dot(dir) >= 0) continue;
                        if (hits[size_t(j)]++ == 0) touched.push_back(j);
                    }
                    followed += second;
                    if (unhidden > 0) {
                        // The analytic columns by their mean over the patch, which the hidden part,
                        // seeing little of any source, adds almost nothing to.
                        for (const auto& [j, f] : meanEntries[i])
                            if (j < int32_t(analyticColumns.size()) && analyticColumns[size_t(j)])
                                row.push_back({j, float(double(f) * open / unhidden)});
                        for (int32_t j : touched) row.push_back({j, float(scale * hits[size_t(j)] / unhidden)});
                        std::sort(row.begin(), row.end());
                    }
                    for (int32_t j : touched) hits[size_t(j)] = 0;
                }
                g_castRays.add(uint64_t(count + followed));
            }
            std::lock_guard<std::mutex> lock(backMutex);
            back.insert(back.end(), myBack.begin(), myBack.end());
        },
        8);
    progress.done();
    auto pack = [n](std::vector<std::vector<std::pair<int32_t, float>>>& rows, std::vector<uint64_t>& start,
                    std::vector<int32_t>& column, std::vector<float>& value) {
        start.assign(n + 1, 0);
        for (size_t i = 0; i < n; ++i) start[i + 1] = start[i] + rows[i].size();
        column.resize(start[n]);
        value.resize(start[n]);
        for (size_t i = 0; i < n; ++i) {
            for (size_t k = 0; k < rows[i].size(); ++k)
                column[start[i] + k] = rows[i][k].first, value[start[i] + k] = rows[i][k].second;
            std::vector<std::pair<int32_t, float>>().swap(rows[i]);
        }
    };
    std::vector<uint64_t> start, meanStart;
    std::vector<int32_t> column, meanColumn;
    std::vector<float> value, meanValue;
    pack(entries, start, column, value);
    pack(meanEntries, meanStart, meanColumn, meanValue);
    FormFactorMatrix F(n, std::move(start), std::move(column), std::move(value));
    F.sampled = true;
    F.reciprocal = false;
    F.backTransfers = std::move(back);
    F.exposed = std::move(exposed);
    F.seen = std::move(seen);
    F.setMeanRows(std::move(meanStart), std::move(meanColumn), std::move(meanValue));
    std::sort(F.backTransfers.begin(), F.backTransfers.end(), [](const BackTransfer& a, const BackTransfer& b) {
        return a.from != b.from ? a.from < b.from : a.to < b.to;
    });
    if (hidden) logInfo("form factors (rays): ", size_t(hidden), " patches partly hidden behind back faces");
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
