#include "solver/radiosity/ray_form_factors.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <iterator>
#include <map>
#include <mutex>

#include "core/cluster.h"
#include "core/counters.h"
#include "core/error.h"
#include "core/log.h"
#include "core/optics.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "core/timer.h"
#include "mesh/refine.h"
#include "solver/shafts.h"
#include "solver/tracer.h"

namespace penumbra {
namespace {
const Counter g_castRays("form_factors.cast_rays", "rays cast for ray-cast form factors (--form-factors rays)");
const Counter g_gapRays("form_factors.gap_rays",
                        "of form_factors.cast_rays, those along a patch's normal asking whether an origin is in a gap");
// Casts the `wanted` rows (castFor, below), here alone or shared among the ranks. Under mpirun the
// rows go by measured cost, in blocks of kRowBlock neighbours (which cost alike: a room's floor beside
// its lamp): every kProbeStride-th block is cast first, dealt out in turn, and timed (`rowSeconds`,
// filled by the casting); every other block is expected to cost what the probe block before it did,
// and goes to the rank with the least work so far, the costliest first (Graham's
// longest-processing-time rule). Every rank makes the same choice from the same exchanged times;
// which rank casts a row changes nothing in it.
constexpr size_t kRowBlock = 16, kProbeStride = 16;
// Alone, the rows go in segments: castFor(rows, seconds) casts them for at most that long and returns
// those it left, which go first in the next; castSoFar(rows done) after each (for the checkpoint).
// A segment's rows follow the last one's rate, at most doubled; PENUMBRA_TEST_CHECKPOINT_ROWS fixes
// them (tests).
// Under mpirun, each rank casts its rows in rounds of at most kRoundSeconds, after each of which
// exchange(rows cast, more left here) hands every rank's rows to every rank (and the checkpoint
// takes them when due) and says whether any rank has rows left: so a job killed mid-pass loses at
// most a round and the wait for a save.
constexpr double kSegmentSeconds = 5, kRoundSeconds = 10;
template <typename CastFor, typename CastSoFar, typename Exchange>
void castShared(const std::vector<size_t>& wanted, size_t n, const std::vector<float>& rowSeconds,
                const CastFor& castFor, const CastSoFar& castSoFar, const Exchange& exchange) {
    if (!cluster::distributed()) {
        const char* fixed = std::getenv("PENUMBRA_TEST_CHECKPOINT_ROWS");
        size_t segment = fixed ? size_t(std::max(1, std::atoi(fixed))) : 256;
        std::vector<size_t> left;  // of the last segment
        for (size_t at = 0; at < wanted.size() || !left.empty();) {
            std::vector<size_t> list = left;
            const size_t take = std::min(segment > list.size() ? segment - list.size() : 0, wanted.size() - at);
            list.insert(list.end(), wanted.begin() + std::ptrdiff_t(at), wanted.begin() + std::ptrdiff_t(at + take));
            at += take;
            const Timer timer;
            left = castFor(list, fixed ? 1e9 : 2 * kSegmentSeconds);
            castSoFar(at, left);
            const double rate = double(list.size() - left.size()) / std::max(timer.seconds(), 1e-3);
            if (!fixed)
                segment = size_t(std::clamp(std::min(rate * kSegmentSeconds, 2.0 * double(list.size())), 64.0, 1e6));
        }
        return;
    }
    const int ranks = cluster::size(), me = cluster::rank();
    const size_t blocks = (n + kRowBlock - 1) / kRowBlock;
    const CounterValues before = counterValues();
    (void)castSoFar;
    const auto inRounds = [&](std::vector<size_t> rows) {
        for (;;) {
            std::vector<size_t> left = castFor(rows, kRoundSeconds), now;
            std::set_difference(rows.begin(), rows.end(), left.begin(), left.end(), std::back_inserter(now));
            if (!exchange(now, !left.empty())) return;
            rows = std::move(left);
        }
    };
    const auto rowsOf = [&](const std::vector<size_t>& of) {
        std::vector<char> in(blocks, 0);
        for (size_t b : of) in[b] = 1;
        std::vector<size_t> rows;
        for (size_t i : wanted)
            if (in[i / kRowBlock]) rows.push_back(i);
        return rows;
    };
    std::vector<size_t> probes, mine;
    for (size_t b = 0; b < blocks; b += kProbeStride) {
        probes.push_back(b);
        if (int((b / kProbeStride) % size_t(ranks)) == me) mine.push_back(b);
    }
    auto t0 = std::chrono::steady_clock::now();
    inRounds(rowsOf(mine));
    auto t1 = std::chrono::steady_clock::now();
    // The probes' times, every rank's, on every rank.
    std::vector<std::vector<float>> cost(probes.size());
    for (size_t k = 0; k < probes.size(); ++k) {
        if (int(k % size_t(ranks)) != me) continue;
        float sum = 0;
        for (size_t i = probes[k] * kRowBlock; i < std::min(n, (probes[k] + 1) * kRowBlock); ++i) sum += rowSeconds[i];
        cost[k] = {sum};
    }
    cluster::shareChunks(cost);
    std::vector<double> load(static_cast<size_t>(ranks), 0.0);
    for (size_t k = 0; k < probes.size(); ++k) load[k % size_t(ranks)] += double(cost[k].at(0));
    // A block is expected to cost its wanted rows times the probe's cost per wanted row (the mean
    // over all probes where its probe had none: the second pass casts a few rows here and there).
    std::vector<size_t> count(blocks, 0);
    for (size_t i : wanted) ++count[i / kRowBlock];
    double probed = 0, probedRows = 0;
    for (size_t k = 0; k < probes.size(); ++k) probed += double(cost[k].at(0)), probedRows += double(count[probes[k]]);
    const double meanRow = probedRows > 0 ? probed / probedRows : 1.0;
    const auto expected = [&](size_t b) {
        const size_t probe = b / kProbeStride * kProbeStride;
        const double perRow = count[probe] > 0 ? double(cost[b / kProbeStride].at(0)) / double(count[probe]) : meanRow;
        return perRow * double(count[b]);
    };
    std::vector<size_t> rest;
    for (size_t b = 0; b < blocks; ++b)
        if (b % kProbeStride != 0 && count[b] > 0) rest.push_back(b);
    std::stable_sort(rest.begin(), rest.end(), [&](size_t a, size_t b) { return expected(a) > expected(b); });
    mine.clear();
    for (size_t b : rest) {
        const int r = int(std::min_element(load.begin(), load.end()) - load.begin());
        load[size_t(r)] += expected(b);
        if (r == me) mine.push_back(b);
    }
    auto t2 = std::chrono::steady_clock::now();
    inRounds(rowsOf(mine));
    auto t3 = std::chrono::steady_clock::now();
    // What each rank spent, for the log: how well the expected costs shared the work.
    std::vector<std::array<double, 3>> spent(static_cast<size_t>(ranks));
    spent[size_t(me)] = {std::chrono::duration<double>(t1 - t0).count(), std::chrono::duration<double>(t3 - t2).count(),
                         load[size_t(me)]};
    cluster::shareValues(spent);
    cluster::shareCounters(before);
    std::string line;
    for (int r = 0; r < ranks; ++r)
        line += cat(r ? "; " : "", "rank ", r, " ", spent[size_t(r)][0] + spent[size_t(r)][1], " s (expected ",
                    spent[size_t(r)][2], ")");
    logInfo("form factors (rays) under mpirun: ", wanted.size(), " rows shared by measured cost: ", line);
}

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

// A ray that lands within this many of its patch's radii of its origin sees that patch's near part
// more than its far part (HitReadings).
constexpr double kNearRadii = 4;
// Where a ray landed: near its patch (within kNearRadii radii), or farther.
constexpr char kNear = 1, kFar = 2;
// An origin whose patch's normal meets a front face nearer than this many of its patch's radii lies
// in a narrow gap (a wall behind a shelf's back panel): the rest of the scene hardly sees it.
constexpr double kGapRadii = 0.25;
// Origins are tested for a gap where at least 1 in kGapShare of the patch's rays land that near (a
// patch along a corner sends fewer there, a patch partly in a gap more).
constexpr int kGapShare = 8;
// A hit from farther reads the light where it landed only on a patch whose slope moves the light by
// at least this share of its mean across the patch's radius (a patch part of which lies in a narrow
// gap, or deep in a cavity): elsewhere the reading adds the patch's neighbours to every row that
// meets it, for a change smaller than the noise.
constexpr double kSteep = 0.2;

// Rows of (column, value) pairs, columns ascending, compressed (and emptied).
void packRows(std::vector<std::vector<std::pair<int32_t, float>>>& rows, std::vector<uint64_t>& start,
              std::vector<int32_t>& column, std::vector<float>& value) {
    const size_t n = rows.size();
    start.assign(n + 1, 0);
    for (size_t i = 0; i < n; ++i) start[i + 1] = start[i] + rows[i].size();
    column.resize(start[n]);
    value.resize(start[n]);
    for (size_t i = 0; i < n; ++i) {
        for (size_t k = 0; k < rows[i].size(); ++k)
            column[start[i] + k] = rows[i][k].first, value[start[i] + k] = rows[i][k].second;
        std::vector<std::pair<int32_t, float>>().swap(rows[i]);
    }
}

// Back transfers by source, then target.
void sortBackTransfers(std::vector<BackTransfer>& back) {
    std::sort(back.begin(), back.end(), [](const BackTransfer& a, const BackTransfer& b) {
        return a.from != b.from ? a.from < b.from : a.to < b.to;
    });
}

// F with its rows and mean rows made of `rows` and `meanRows` (emptied), its other fields kept.
void replaceRows(FormFactorMatrix& F, std::vector<std::vector<std::pair<int32_t, float>>>& rows,
                 std::vector<std::vector<std::pair<int32_t, float>>>& meanRows) {
    std::vector<uint64_t> start, meanStart;
    std::vector<int32_t> column, meanColumn;
    std::vector<float> value, meanValue;
    packRows(rows, start, column, value);
    packRows(meanRows, meanStart, meanColumn, meanValue);
    FormFactorMatrix out(F.size(), std::move(start), std::move(column), std::move(value));
    out.sampled = F.sampled;
    out.reciprocal = F.reciprocal;
    out.backTransfers = std::move(F.backTransfers);
    out.exposed = std::move(F.exposed);
    out.seen = std::move(F.seen);
    out.setMeanRows(std::move(meanStart), std::move(meanColumn), std::move(meanValue));
    F = std::move(out);
}

// The least-squares slope weights of every patch (HitReadings): its neighbours are the patches of
// the same object that share a corner with it, face within 30 degrees of it, and are not wholly
// inside a solid; centroids are those of the uncovered parts.
void slopeWeights(const PatchSet& p, const std::vector<float>& exposed, HitReadings& h) {
    const size_t n = p.size();
    h.start.assign(n + 1, 0);
    if (p.cornerVertex.size() != n) return;
    const std::vector<std::vector<int>> around = patchesAround(p);
    const double crease = std::cos(30 * kPi / 180);
    std::vector<int> near;
    std::vector<std::array<double, 2>> d;
    for (size_t j = 0; j < n; ++j) {
        near.clear();
        if (exposed[j] > 0)
            for (int c = 0; c < p.cornerCount[j]; ++c)
                for (int k : around[size_t(p.cornerVertex[j][size_t(c)])])
                    if (size_t(k) != j && exposed[size_t(k)] > 0 && p.normal[size_t(k)].dot(p.normal[j]) >= crease)
                        near.push_back(k);
        std::sort(near.begin(), near.end());
        near.erase(std::unique(near.begin(), near.end()), near.end());
        const Vec3 cj = h.uncoveredCentroid(p, j);
        double m00 = 0, m01 = 0, m11 = 0;
        d.resize(near.size());
        for (size_t a = 0; a < near.size(); ++a) {
            const Vec3 offset = h.uncoveredCentroid(p, size_t(near[a])) - cj;
            d[a] = {offset.dot(h.tangentU[j]), offset.dot(h.tangentV[j])};
            m00 += d[a][0] * d[a][0], m01 += d[a][0] * d[a][1], m11 += d[a][1] * d[a][1];
        }
        // A row of patches one wide has no slope across it: a little regularisation keeps M invertible.
        const double lambda = 1e-6 * (m00 + m11) + 1e-300;
        m00 += lambda, m11 += lambda;
        const double det = m00 * m11 - m01 * m01;
        for (size_t a = 0; a < near.size(); ++a) {
            h.neighbour.push_back(near[a]);
            h.qu.push_back(float((m11 * d[a][0] - m01 * d[a][1]) / det));
            h.qv.push_back(float((m00 * d[a][1] - m01 * d[a][0]) / det));
        }
        h.start[j + 1] = uint32_t(h.neighbour.size());
    }
}

// Row `row` with its near hits read where they land: a hit of weight w at offset x from patch j's
// uncovered centroid moves w limit_j (q_k . x) from column j to each neighbour k. Columns ascending.
void foldNearHits(FormFactorMatrix::SparseRow row, const std::vector<HitReadings::Near>& hits,
                  const std::vector<HitReadings::Near>& farHits, const HitReadings& h, const std::vector<float>& limit,
                  const std::vector<char>& steep, double most, std::vector<std::pair<int32_t, float>>& out,
                  size_t& damped) {
    // The moves, sorted and summed per column, then merged with the row (already ascending).
    static thread_local std::vector<std::pair<int32_t, float>> moves;
    moves.clear();
    const size_t nearCount = hits.size();
    for (size_t m = 0; m < nearCount + farHits.size(); ++m) {
        const HitReadings::Near& hit = m < nearCount ? hits[m] : farHits[m - nearCount];
        const size_t j = size_t(hit.patch);
        if (limit[j] <= 0 || (m >= nearCount && !steep[j])) continue;
        const double u = limit[j] * (double(hit.u) - double(hit.weight) * h.shift[j][0]);
        const double v = limit[j] * (double(hit.v) - double(hit.weight) * h.shift[j][1]);
        double moved = 0;
        for (uint32_t a = h.start[j]; a < h.start[j + 1]; ++a) {
            const double w = u * h.qu[a] + v * h.qv[a];
            moves.push_back({h.neighbour[a], float(w)});
            moved += w;
        }
        moves.push_back({hit.patch, float(-moved)});
    }
    out.clear();
    if (moves.empty()) {  // nothing to fold: the row as it is
        for (size_t k = 0; k < row.count; ++k) out.push_back({row.column[k], row.value[k]});
        return;
    }
    std::sort(moves.begin(), moves.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    // Per column of the result: the row's entry and the moves' sum.
    static thread_local std::vector<std::pair<float, float>> parts;
    parts.clear();
    out.reserve(row.count + moves.size());
    size_t k = 0, m = 0;
    while (k < row.count || m < moves.size()) {
        const bool fromRow = m == moves.size() || (k < row.count && row.column[k] <= moves[m].first);
        const int32_t column = fromRow ? row.column[k] : moves[m].first;
        if (out.empty() || out.back().first != column) out.push_back({column, 0.0f}), parts.push_back({0.0f, 0.0f});
        (fromRow ? parts.back().first : parts.back().second) += fromRow ? row.value[k] : moves[m].second;
        fromRow ? ++k : ++m;
    }
    // The moves take weight from some entries and give it to others, so that a row may sum its
    // magnitudes past one. Jacobi and Gauss-Seidel converge where rho_i sum_j |F_ij| < 1 in every
    // row; at rho 0.999 one mesh's folded rows reached 1.41 and Gauss-Seidel diverged. So the moves
    // of a row are scaled down, t in [0, 1], until its magnitudes sum to at most `most`.
    auto magnitude = [&](double t) {
        double a = 0;
        for (const auto& [base, move] : parts) a += std::abs(double(base) + t * double(move));
        return a;
    };
    double t = 1;
    if (magnitude(1) > most) {
        double low = 0, high = 1;  // magnitude is convex in t, and at most `most` at 0
        for (int step = 0; step < 30; ++step) (magnitude(0.5 * (low + high)) > most ? high : low) = 0.5 * (low + high);
        t = low;
        ++damped;
    }
    for (size_t c = 0; c < out.size(); ++c) out[c].second = float(double(parts[c].first) + t * double(parts[c].second));
}

// FormFactorMatrix::entryVariance's order: rows ascending, columns within them.
void sortByRow(std::vector<FormFactorMatrix::EntryVariance>& v) {
    std::sort(v.begin(), v.end(),
              [](const auto& x, const auto& y) { return x.row != y.row ? x.row < y.row : x.column < y.column; });
}

}  // namespace

Vec3 HitReadings::uncoveredCentroid(const PatchSet& p, size_t i) const {
    return p.centroid[i] + double(shift[i][0]) * tangentU[i] + double(shift[i][1]) * tangentV[i];
}

FormFactorMatrix castFormFactors(const PatchSet& patches, const RayScene& rays, const FormFactorSettings& settings,
                                 const std::vector<char>& analyticColumns, const std::vector<char>& emitting,
                                 HitReadings* readings, const std::vector<int>& raysFor) {
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
    // Per row (and mean row), its near hits; per patch, its tangent frame and the offset of its
    // uncovered part's centroid in it.
    HitReadings local;
    HitReadings& read = readings ? *readings : local;
    read = HitReadings();
    const double nearRadii = readings ? kNearRadii : 0;
    read.rows.resize(n), read.meanRows.resize(n), read.farRows.resize(n), read.farMeanRows.resize(n);
    read.tangentU.resize(n), read.tangentV.resize(n);
    for (size_t i = 0; i < n; ++i) orthonormalBasis(patches.normal[i], read.tangentU[i], read.tangentV[i]);
    read.shift.assign(n, {0.0f, 0.0f});
    const size_t columnCount = analytic.size();
    // Objects that are one convex polygon, which may hide a receiver from a source wholly.
    const std::vector<ConvexOccluder> occluders =
        columnCount ? convexOccluders(patches) : std::vector<ConvexOccluder>();
    std::vector<FormFactorMatrix::EntryVariance> entryVariance;
    std::atomic<uint64_t> pairsHidden{0};  // source-receiver pairs an occluder hid without rays
    // Per object of the analytic columns (a lamp), the rectangle in its plane that holds its column
    // patches: where the shaft from a receiver to it is proved clear (solver/shafts.h; occluders the
    // patches and the exact spheres, both views), its columns take no visibility rays.
    struct SourceEnd {
        ShaftEnd end;
        std::vector<size_t> columns;  // indices into `analytic`
    };
    std::vector<SourceEnd> sourceEnds;
    std::unique_ptr<ClearShafts> shafts;
    if (columnCount > 0 && settings.clearShafts) {
        std::map<int, std::vector<size_t>> byObject;
        for (size_t a = 0; a < columnCount; ++a) byObject[patches.object[analytic[a]]].push_back(a);
        for (const auto& [object, columns] : byObject) {
            const size_t first = analytic[columns.front()];
            const Vec3 up = patches.normal[first], c = patches.centroid[first];
            Vec3 u, v;
            orthonormalBasis(up, u, v);
            double uLow = HUGE_VAL, uHigh = -HUGE_VAL, vLow = HUGE_VAL, vHigh = -HUGE_VAL;
            bool flat = true;
            for (size_t a : columns) {
                const size_t j = analytic[a];
                flat = flat && patches.normal[j].dot(up) > 1 - 1e-9;
                for (int k = 0; k < patches.cornerCount[j]; ++k) {
                    const Vec3 d = patches.corners[j][size_t(k)] - c;
                    flat = flat && std::abs(d.dot(up)) <= 1e-9 * (1 + d.norm());
                    uLow = std::min(uLow, d.dot(u)), uHigh = std::max(uHigh, d.dot(u));
                    vLow = std::min(vLow, d.dot(v)), vHigh = std::max(vHigh, d.dot(v));
                }
            }
            if (!flat) continue;  // no proof for a curved or folded source: rays
            SourceEnd e;
            e.end.corner = {c + uLow * u + vLow * v, c + uHigh * u + vLow * v, c + uHigh * u + vHigh * v,
                            c + uLow * u + vHigh * v};
            e.end.normal = up;
            e.columns = columns;
            sourceEnds.push_back(std::move(e));
        }
        // The visibility rays' ends lie off the patches by their lift: an occluder must clear the
        // shaft by more.
        if (!sourceEnds.empty()) {
            double farthest = 0;
            for (size_t i = 0; i < n; ++i) farthest = std::max(farthest, liftDistance(patches, i));
            shafts = std::make_unique<ClearShafts>(patches, rays.spheres(), std::vector<char>(), 2 * farthest);
        }
    }
    std::vector<int> endOf(columnCount, -1);
    for (size_t e = 0; e < sourceEnds.size(); ++e)
        for (size_t a : sourceEnds[e].columns) endOf[a] = int(e);
    std::atomic<uint64_t> pairsProved{0};  // source-receiver pairs proved clear without rays
    const std::vector<Vec3>&tangentU = read.tangentU, &tangentV = read.tangentV;
    const double lift = originLift(patches);
    const int baseSide = stratumSide(settings.raysPerPatch);
    const int baseCount = baseSide * baseSide;
    std::atomic<uint64_t> firstRays{0};  // the rays of the rows' first pass
    std::atomic<size_t> rowsCast{0};
    std::mutex backMutex;
    std::atomic<int64_t> analyticNanos{0};  // thread time in the analytic columns
    std::atomic<size_t> hidden{0};          // patches with a mean row
    std::atomic<size_t> inGaps{0};          // of which part lies in a narrow gap
    // Under mpirun each rank casts its own rows (rowOwners: by measured cost), then all are exchanged.
    std::vector<size_t> wanted;
    for (size_t i = 0; i < n; ++i)
        if (raysFor.empty() || raysFor[i] > 0) wanted.push_back(i);
    std::vector<float> rowSeconds(cluster::distributed() ? n : 0, 0.0f);  // thread time of each row cast
    // Under mpirun rank 0's bar counts every rank's rows, the others' as each round's exchange brings them.
    Progress progress("form factors (rays)", int64_t(wanted.size()));
    std::vector<char> cast(n, 0);  // rows cast by this rank
    const std::chrono::steady_clock::time_point* segmentEnd = nullptr;
    const auto castRows = [&](const std::vector<size_t>& list) {
        parallelFor(
            int64_t(list.size()),
            [&](int64_t begin, int64_t end) {
                prepareTracingThread();
                std::vector<BackTransfer> myBack;
                std::map<int, int> backHits;
                // Front-face hits of the row, per patch: kept per thread across chunks (a chunk may be a
                // few rows, the array n long) and left all zero after each row.
                static thread_local std::vector<int> hits;
                if (hits.size() < n) hits.assign(n, 0);
                std::vector<int32_t> touched;
                int side = baseSide, count = baseCount;  // this row's
                // Each origin and the front patch its ray met (-1: anything else), for the second rays.
                std::vector<Vec3> origins(static_cast<size_t>(count));
                std::vector<int32_t> landed(static_cast<size_t>(count));
                std::vector<int> order;  // the direction stratum of each origin stratum
                // Where each origin's ray landed on its front patch near enough to read the light at that
                // point (kNearRadii), the offset in that patch's frame; and each origin inside a solid.
                std::vector<char> isNear(static_cast<size_t>(count)), isInside(static_cast<size_t>(count));
                // Per origin: its first ray met a front patch within the gap distance, or a back face; the
                // origin lies in a gap.
                constexpr char kCloseHit = 1, kBackHit = 2, kInGap = 4;
                std::vector<char> gapFlags(static_cast<size_t>(count));
                std::vector<std::array<float, 2>> offset(static_cast<size_t>(count));
                static thread_local std::vector<HitReadings::Near> sums;
                if (sums.size() < n) sums.assign(n, HitReadings::Near{-1, 0, 0, 0});
                std::vector<int32_t> nearTouched;
                // Per analytic column, the patch that last blocked a visibility ray to it (rows in patch
                // order: neighbours, often behind the same wall).
                std::vector<Blockers> blockers(analytic.size());
                // Per analytic column, the last object that hid a receiver wholly from it (the wall between
                // the rooms: a receiver beside the last one is likely behind it too), -1 if none.
                std::vector<int> wall(analytic.size(), -1);
                uint64_t myHidden = 0, myProved = 0;
                std::vector<char> proved(sourceEnds.size());
                std::vector<FormFactorMatrix::EntryVariance> myVariance, rowVariance;
                // The near hits among the origins that `counts`, each of weight w.
                auto collectNear = [&](char reach, const auto& counts, double w, std::vector<HitReadings::Near>& out) {
                    out.clear();
                    nearTouched.clear();
                    for (int k = 0; k < count; ++k) {
                        if (isNear[size_t(k)] != reach || !counts(k)) continue;
                        HitReadings::Near& sum = sums[size_t(landed[size_t(k)])];
                        if (sum.patch < 0) sum.patch = landed[size_t(k)], nearTouched.push_back(sum.patch);
                        sum.weight += float(w), sum.u += float(w * offset[size_t(k)][0]),
                            sum.v += float(w * offset[size_t(k)][1]);
                    }
                    for (int32_t j : nearTouched) {
                        out.push_back(sums[size_t(j)]);
                        sums[size_t(j)] = HitReadings::Near{-1, 0, 0, 0};
                    }
                };
                // Each row's time, where the rows are shared by cost: from its start to the next row's.
                size_t timed = n;
                auto since = std::chrono::steady_clock::now();
                const auto settle = [&] {
                    const auto now = std::chrono::steady_clock::now();
                    if (timed < rowSeconds.size())
                        rowSeconds[timed] = std::chrono::duration<float>(now - since).count();
                    since = now;
                };
                for (int64_t ii = begin; ii < end; ++ii, progress.update()) {
                    const size_t i = list[size_t(ii)];
                    // A segment past its time leaves its remaining rows to the next (castShared).
                    if (segmentEnd && std::chrono::steady_clock::now() > *segmentEnd) continue;
                    settle();
                    timed = i;
                    cast[i] = 1;
                    if (!raysFor.empty()) {
                        side = stratumSide(raysFor[i]);
                        count = side * side;
                        if (origins.size() < size_t(count)) {
                            origins.resize(size_t(count)), landed.resize(size_t(count)), offset.resize(size_t(count));
                            isNear.resize(size_t(count)), isInside.resize(size_t(count)),
                                gapFlags.resize(size_t(count));
                        }
                    }
                    firstRays += uint64_t(count);
                    ++rowsCast;
                    Rng rng = streamRng(settings.seed, raysFor.empty() ? Stream::CastFormFactors : Stream::CastMore, i);
                    const Vec3 n0 = patches.normal[i];
                    backHits.clear();
                    touched.clear();
                    int analyticHits = 0, inside = 0, followed = 0, backs = 0, close = 0;
                    const double gap = kGapRadii * patches.radius[i];
                    int wholly = 0;  // the rays cast before the patch was found wholly inside a solid
                    const bool mayBeCovered = !(i < emitting.size() && emitting[i]);
                    shuffledStrata(order, count, rng);
                    const double inverseSide = 1.0 / side;
                    const PatchPointSampler onPatch(patches, i);
                    const CosineSampler around(n0);
                    const Vec3 lifted = lift * n0;
                    for (int k = 0; k < count; ++k) {
                        // Origins in one stratum of the patch, directions in another (a random
                        // permutation of the strata), both jittered.
                        const int a = k, b = order[size_t(k)];
                        const double u1 = ((a % side) + rng.uniform()) * inverseSide;
                        const double u2 = ((a / side) + rng.uniform()) * inverseSide;
                        const double d1 = ((b % side) + rng.uniform()) * inverseSide;
                        const double d2 = ((b / side) + rng.uniform()) * inverseSide;
                        rng.uniform();  // u3 of samplePatchPoint, unused: kept so the stream stays as it was
                        const Vec3 at = onPatch(u1, u2);
                        const Vec3 origin = at + 1e-3 * (patches.centroid[i] - at) + lifted;  // rayOrigin
                        const Vec3 dir = around(d1, d2);
                        const Hit h = rays.intersect(origin, dir, 0, 1e30, RayView::Patches);
                        origins[size_t(k)] = origin;
                        landed[size_t(k)] = -1;
                        isNear[size_t(k)] = isInside[size_t(k)] = gapFlags[size_t(k)] = 0;
                        if (h.patch < 0) continue;  // out of the scene
                        const size_t j = size_t(h.patch);
                        if (patches.normal[j].dot(dir) >= 0) {
                            if (mayBeCovered && insideSolid(patches, rays, i, origin, followed)) {
                                isInside[size_t(k)] = 1;
                                // At the first origin inside a solid, whether the whole patch is.
                                if (++inside == 1 && whollyInside(patches, rays, i, lift, followed)) {
                                    wholly = k + 1;
                                    break;
                                }
                            } else {
                                ++backHits[h.patch];
                                ++backs;
                                gapFlags[size_t(k)] = kBackHit;
                            }
                        } else if (j < analyticColumns.size() && analyticColumns[j]) {
                            ++analyticHits;
                        } else {
                            landed[size_t(k)] = int32_t(j);
                            if (hits[j]++ == 0) touched.push_back(int32_t(j));
                            // A mirror's or glass's sphere close by is no gap: the specular transport
                            // carries what it reflects. (Read as the patch's own light as well, the floor
                            // under cornell-glass's glass ball had its light twice: at --grade-contacts 0,
                            // its quarter of the floor +0.63% over 8 seeds, +0.06% without.)
                            if (h.t < gap && !rays.onExactSphere(j)) gapFlags[size_t(k)] = kCloseHit, ++close;
                            if (readings) {
                                const Vec3 x = origin + h.t * dir - patches.centroid[j];
                                isNear[size_t(k)] = h.t < nearRadii * patches.radius[j] ? kNear : kFar;
                                offset[size_t(k)] = {float(x.dot(tangentU[j])), float(x.dot(tangentV[j]))};
                            }
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
                    if (inside > 0 && open > 0) {  // the centroid of the uncovered part, by its origins
                        Vec3 sum = Vec3::Zero();
                        for (int k = 0; k < count; ++k)
                            if (!isInside[size_t(k)]) sum += origins[size_t(k)] - patches.centroid[i];
                        read.shift[i] = {float(sum.dot(tangentU[i]) / open), float(sum.dot(tangentV[i]) / open)};
                    }
                    // Origins in a narrow gap: where at least 1 in kGapShare of the rays landed within the gap
                    // distance, each origin in the open whose patch normal meets a front face that near. A
                    // patch wholly in a gap (a shelf's back panel, facing the wall 1 cm behind it) holds
                    // the gap's light: what its rays meet within the gap is read as its own, not as the
                    // light the room sees of the far side (which would light the gap from the room).
                    int enclosed = 0;
                    if (close > 0 && close * kGapShare >= open) {
                        const int before = followed;
                        for (int k = 0; k < count; ++k) {
                            if (isInside[size_t(k)] || (gapFlags[size_t(k)] & kBackHit)) continue;
                            const Hit h = rays.intersect(origins[size_t(k)], n0, 0, gap, RayView::Patches);
                            ++followed;
                            if (h.patch >= 0 && !rays.onExactSphere(size_t(h.patch)) &&
                                patches.normal[size_t(h.patch)].dot(n0) < 0)
                                gapFlags[size_t(k)] |= kInGap, ++enclosed;
                        }
                        g_gapRays.add(uint64_t(followed - before));
                        if (enclosed > 0 && open - backs - enclosed <= 0) {
                            for (int k = 0; k < count; ++k) {
                                // What the gap's origins meet within it: their own patch's light.
                                if ((gapFlags[size_t(k)] & (kInGap | kCloseHit)) != (kInGap | kCloseHit)) continue;
                                --hits[size_t(landed[size_t(k)])];
                                if (hits[i]++ == 0) touched.push_back(int32_t(i));
                                landed[size_t(k)] = int32_t(i);
                                const Vec3 x = origins[size_t(k)] - patches.centroid[i];
                                isNear[size_t(k)] = readings ? kNear : 0;
                                offset[size_t(k)] = {float(x.dot(tangentU[i])), float(x.dot(tangentV[i]))};
                            }
                            enclosed = 0;
                            std::fill(gapFlags.begin(), gapFlags.begin() + count, 0);
                        }
                    }
                    std::vector<std::pair<int32_t, float>>& row = entries[i];
                    if (open == 0) {  // wholly inside a solid: no light reaches it
                        g_castRays.add(uint64_t(count + followed));
                        continue;
                    }
                    // The analytic columns, computed as the analytic matrix computes them (over the whole
                    // patch, whose covered part sees no source), then as a mean over the uncovered part.
                    // A row cast again measures them again too, with its share more visibility rays (a
                    // stream of their own): a floor patch in a desk's penumbra reads its lamp through a few
                    // rays, and that noise is what its neighbours gather (EntryVariance).
                    FormFactorSettings visibility = settings;
                    visibility.visibilityRays = settings.visibilityRays * std::clamp(count / baseCount, 1, 8);
                    const Stream stream = raysFor.empty() ? Stream::Visibility : Stream::VisibilityAgain;
                    double exact = 0;
                    rowVariance.clear();
                    const Timer columns;
                    if (shafts) {
                        const ShaftEnd receiver = patchEnd(patches, i);
                        for (size_t e = 0; e < sourceEnds.size(); ++e)
                            proved[e] = shafts->clear(receiver, sourceEnds[e].end);
                    }
                    for (size_t a = 0; a < columnCount; ++a) {
                        const size_t j = analytic[a];
                        double whole, variance = 0;
                        const bool clear = endOf[a] >= 0 && proved[size_t(endOf[a])];
                        if (!clear && wall[a] >= 0 && hidesWholly(occluders[size_t(wall[a])], patches, i, j)) {
                            whole = 0;
                            ++myHidden;
                        } else {
                            myProved += clear;
                            whole = frontFormFactor(patches, rays, i, j, visibility, &blockers[a], &variance, stream,
                                                    clear);
                            const Blockers& by = blockers[a];
                            const int last = by.patch[(size_t(by.next) + by.patch.size() - 1) % by.patch.size()];
                            if (whole == 0 && last >= 0) {
                                const int o = patches.object[size_t(last)];
                                if (o != wall[a] && hidesWholly(occluders[size_t(o)], patches, i, j)) wall[a] = o;
                            }
                        }
                        const double f = whole / exposed[i];
                        if (f > 0) row.push_back({int32_t(j), float(f)});
                        if (variance > 0)
                            rowVariance.push_back(
                                {int32_t(i), int32_t(j), float(variance / (double(exposed[i]) * exposed[i]))});
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
                        if (hits[size_t(j)] > 0) row.push_back({j, float(scale * hits[size_t(j)] / open)});
                        hits[size_t(j)] = 0;
                    }
                    std::sort(row.begin(), row.end());
                    collectNear(
                        kNear, [](int) { return true; }, scale / open, read.rows[i]);
                    collectNear(
                        kFar, [](int) { return true; }, scale / open, read.farRows[i]);
                    // A_i F(i -> back of j), with the light of the uncovered part, exposed[i] A_i.
                    for (const auto& [j, h] : backHits)
                        myBack.push_back({int(i), j, scale * patches.area[i] * double(h) / double(count)});
                    if (backs > 0 || enclosed > 0) {
                        // Part of the patch is hidden: what the rest of the scene sees is the light of each
                        // point weighted by how much of the scene sees it, its share of directions that
                        // meet no back face, and none if it lies in a gap. That weight is a second ray from
                        // the origin, independent of the first: an origin's light counts where its second
                        // ray meets no back face, over the origins whose first ray met none (without back
                        // faces, every origin not in a gap counts). The row above stays as the mean.
                        const int unhidden = open - backs - enclosed;
                        seen[i] = float(unhidden) / float(open);
                        ++hidden;
                        if (enclosed > 0) ++inGaps;
                        meanEntries[i].swap(row);
                        read.meanRows[i].swap(read.rows[i]);
                        read.farMeanRows[i].swap(read.farRows[i]);
                        int second = 0;
                        touched.clear();
                        std::vector<char> counted(static_cast<size_t>(count), 0);
                        for (int k = 0; k < count; ++k) {
                            const int32_t j = landed[size_t(k)];
                            if (j < 0 || (gapFlags[size_t(k)] & kInGap)) continue;
                            if (backs == 0) {
                                counted[size_t(k)] = 1;
                                if (hits[size_t(j)]++ == 0) touched.push_back(j);
                                continue;
                            }
                            const double e1 = rng.uniform();
                            const Vec3 dir = around(e1, rng.uniform());
                            const Hit h = rays.intersect(origins[size_t(k)], dir, 0, 1e30, RayView::Patches);
                            ++second;
                            if (h.patch >= 0 && patches.normal[size_t(h.patch)].dot(dir) >= 0) continue;
                            counted[size_t(k)] = 1;
                            if (hits[size_t(j)]++ == 0) touched.push_back(j);
                        }
                        if (unhidden > 0)
                            for (const char reach : {kNear, kFar})
                                collectNear(
                                    reach, [&](int k) { return counted[size_t(k)] != 0; }, scale / unhidden,
                                    reach == kNear ? read.rows[i] : read.farRows[i]);
                        followed += second;
                        if (unhidden > 0) {
                            // The analytic columns by their mean over the patch, which the hidden part,
                            // seeing little of any source, adds almost nothing to.
                            for (const auto& [j, f] : meanEntries[i])
                                if (j < int32_t(analyticColumns.size()) && analyticColumns[size_t(j)])
                                    row.push_back({j, float(double(f) * open / unhidden)});
                            for (int32_t j : touched) row.push_back({j, float(scale * hits[size_t(j)] / unhidden)});
                            std::sort(row.begin(), row.end());
                            for (auto& e : rowVariance)
                                e.variance *= float(double(open) * open / (double(unhidden) * unhidden));
                        }
                        if (unhidden <= 0) rowVariance.clear();
                        for (int32_t j : touched) hits[size_t(j)] = 0;
                    }
                    myVariance.insert(myVariance.end(), rowVariance.begin(), rowVariance.end());
                    g_castRays.add(uint64_t(count + followed));
                }
                settle();
                pairsHidden += myHidden;
                pairsProved += myProved;
                std::lock_guard<std::mutex> lock(backMutex);
                back.insert(back.end(), myBack.begin(), myBack.end());
                entryVariance.insert(entryVariance.end(), myVariance.begin(), myVariance.end());
            },
            8);
    };
    // Each row's whole product, packed for the other ranks and for the checkpoint: its entries and
    // mean entries, its uncovered and seen shares, its readings, its back transfers and variances.
    const auto packRowsOf = [&](const std::vector<size_t>& list) {
        std::vector<char> in(n, 0);
        for (size_t i : list) in[i] = 1;
        std::vector<BackTransfer> backs;
        std::vector<FormFactorMatrix::EntryVariance> variances;
        for (const BackTransfer& b : back)
            if (in[size_t(b.from)]) backs.push_back(b);
        for (const auto& v : entryVariance)
            if (in[size_t(v.row)]) variances.push_back(v);
        sortBackTransfers(backs);
        sortByRow(variances);
        cluster::Packer p;
        p.put(uint64_t(list.size()));
        size_t b = 0, v = 0;
        for (size_t i : list) {
            p.put(uint64_t(i)), p.put(entries[i]), p.put(meanEntries[i]), p.put(exposed[i]), p.put(seen[i]);
            p.put(read.shift[i]), p.put(read.rows[i]), p.put(read.meanRows[i]);
            p.put(read.farRows[i]), p.put(read.farMeanRows[i]);
            std::vector<BackTransfer> rowBack;
            std::vector<FormFactorMatrix::EntryVariance> rowVariance;
            for (; b < backs.size() && size_t(backs[b].from) <= i; ++b)
                if (size_t(backs[b].from) == i) rowBack.push_back(backs[b]);
            for (; v < variances.size() && size_t(variances[v].row) <= i; ++v)
                if (size_t(variances[v].row) == i) rowVariance.push_back(variances[v]);
            p.put(rowBack), p.put(rowVariance);
        }
        return std::move(p.bytes);
    };
    // The rows packed as above into their places; marks them in `done`.
    const auto unpackRows = [&](const std::string& bytes, std::vector<char>& done) {
        cluster::Unpacker u(bytes);
        uint64_t count = 0;
        u.get(count);
        for (uint64_t k = 0; k < count; ++k) {
            uint64_t i = 0;
            u.get(i);
            PENUMBRA_CHECK(i < n);
            u.get(entries[i]), u.get(meanEntries[i]), u.get(exposed[i]), u.get(seen[i]);
            u.get(read.shift[i]), u.get(read.rows[i]), u.get(read.meanRows[i]);
            u.get(read.farRows[i]), u.get(read.farMeanRows[i]);
            std::vector<BackTransfer> rowBack;
            std::vector<FormFactorMatrix::EntryVariance> rowVariance;
            u.get(rowBack), u.get(rowVariance);
            back.insert(back.end(), rowBack.begin(), rowBack.end());
            entryVariance.insert(entryVariance.end(), rowVariance.begin(), rowVariance.end());
            done[i] = 1;
        }
        PENUMBRA_CHECK(u.done());
    };
    // The rows a killed run of the same solve cast in this pass (solve --resume) are not cast again.
    CastCheckpoint* checkpoint = settings.checkpoint;
    const int pass = checkpoint ? checkpoint->beginPass() : 0;
    std::vector<char> done(n, 0);
    std::vector<size_t> restored;
    if (checkpoint && !checkpoint->savedRows(pass).empty()) {
        unpackRows(checkpoint->savedRows(pass), done);
        for (size_t i = 0; i < n; ++i)
            if (done[i]) restored.push_back(i);
        wanted.erase(std::remove_if(wanted.begin(), wanted.end(), [&](size_t i) { return done[i] != 0; }),
                     wanted.end());
        logInfo("form factors (rays): ", restored.size(), " rows of this pass from the checkpoint, ", wanted.size(),
                " to cast");
        progress.update(int64_t(restored.size()));
    }
    // Alone, the rows cast so far go into the checkpoint every so often (CastCheckpoint::due).
    const auto castSoFar = [&](size_t upTo, const std::vector<size_t>& left) {
        if (!checkpoint || !checkpoint->due()) return;
        std::vector<size_t> list = restored;
        list.insert(list.end(), wanted.begin(), wanted.begin() + std::ptrdiff_t(upTo));
        std::sort(list.begin(), list.end());
        std::vector<size_t> waiting = left;
        std::sort(waiting.begin(), waiting.end());
        list.erase(std::remove_if(list.begin(), list.end(),
                                  [&](size_t i) { return std::binary_search(waiting.begin(), waiting.end(), i); }),
                   list.end());
        checkpoint->save(pass, packRowsOf(list));
    };
    // Alone, rows cast in segments of at most kSegmentSeconds (then the rest of a segment waits for
    // the next), the checkpoint saved between them when due.
    const auto castFor = [&](const std::vector<size_t>& list, double seconds) {
        const auto end =
            std::chrono::steady_clock::now() +
            std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(seconds));
        segmentEnd = &end;
        castRows(list);
        segmentEnd = nullptr;
        std::vector<size_t> left;
        for (size_t i : list)
            if (!cast[i]) left.push_back(i);
        return left;
    };
    // Under mpirun, after each round: every rank's rows on every rank, as one process makes them,
    // and into the checkpoint when due; whether any rank has rows left.
    const auto exchange = [&](const std::vector<size_t>& castNow, bool more) {
        const std::vector<std::string> all = cluster::allGather(packRowsOf(castNow) + char(more ? 1 : 0));
        const auto before = std::count(done.begin(), done.end(), 1);
        bool any = false;
        for (int r = 0; r < cluster::size(); ++r) {
            PENUMBRA_CHECK(!all[size_t(r)].empty());
            any = any || all[size_t(r)].back() != 0;
            if (r != cluster::rank()) unpackRows(all[size_t(r)].substr(0, all[size_t(r)].size() - 1), done);
        }
        progress.update(int64_t(std::count(done.begin(), done.end(), 1) - before));
        for (size_t i : castNow) done[i] = 1;
        if (checkpoint && checkpoint->due()) {
            std::vector<size_t> list;
            for (size_t i = 0; i < n; ++i)
                if (done[i]) list.push_back(i);
            checkpoint->save(pass, packRowsOf(list));
        }
        return any;
    };
    castShared(wanted, n, rowSeconds, castFor, castSoFar, exchange);
    progress.done();
    if (cluster::distributed()) {
        // The tallies for the log, every rank's.
        std::vector<std::array<uint64_t, 7>> tally(size_t(cluster::size()));
        tally[size_t(cluster::rank())] = {pairsHidden, pairsProved, uint64_t(int64_t(analyticNanos)), hidden, inGaps,
                                          firstRays,   rowsCast};
        cluster::shareValues(tally);
        for (int r = 0; r < cluster::size(); ++r) {
            if (r == cluster::rank()) continue;
            const auto& t = tally[size_t(r)];
            pairsHidden += t[0], pairsProved += t[1], analyticNanos += int64_t(t[2]);
            hidden += size_t(t[3]), inGaps += size_t(t[4]), firstRays += t[5], rowsCast += size_t(t[6]);
        }
    }
    // The pass done: all its rows into the checkpoint (a stage boundary).
    if (checkpoint) {
        std::vector<size_t> all;
        for (size_t i = 0; i < n; ++i)
            if (raysFor.empty() || raysFor[i] > 0) all.push_back(i);
        checkpoint->save(pass, packRowsOf(all));
    }
    // The slopes need every patch's uncovered part.
    if (readings) slopeWeights(patches, exposed, read);
    std::vector<uint64_t> start, meanStart;
    std::vector<int32_t> column, meanColumn;
    std::vector<float> value, meanValue;
    packRows(entries, start, column, value);
    packRows(meanEntries, meanStart, meanColumn, meanValue);
    FormFactorMatrix F(n, std::move(start), std::move(column), std::move(value));
    F.sampled = true;
    F.reciprocal = false;
    F.backTransfers = std::move(back);
    F.exposed = std::move(exposed);
    F.seen = std::move(seen);
    F.setMeanRows(std::move(meanStart), std::move(meanColumn), std::move(meanValue));
    sortBackTransfers(F.backTransfers);
    sortByRow(entryVariance);
    F.entryVariance = std::move(entryVariance);
    if (hidden)
        logInfo("form factors (rays): ", size_t(hidden), " patches partly hidden (", size_t(hidden) - size_t(inGaps),
                " behind back faces, ", size_t(inGaps), " in narrow gaps)");
    logInfo("form factors (rays): ", size_t(rowsCast), " patches, ",
            raysFor.empty() ? cat(baseCount, " rays each, ")
                            : cat(double(firstRays) / std::max<size_t>(rowsCast, 1), " rays each on average, "),
            uint64_t(firstRays), " rays in ", timer.seconds(), " s; ", F.entries(), " entries stored, ",
            double(F.bytes()) / (1 << 20), " MiB; ", analytic.size(), " analytic columns (small sources) took ",
            double(analyticNanos) * 1e-9 / threadCount(), " s of it",
            pairsHidden ? cat(" (", uint64_t(pairsHidden), " source-receiver pairs hidden wholly by one convex object)")
                        : "",
            pairsProved ? cat(" (", uint64_t(pairsProved), " in full view of it, proved without rays)") : "",
            F.entryVariance.empty() ? "" : cat("; ", F.entryVariance.size(), " of their entries in a penumbra"));
    return F;
}

void castMoreRays(FormFactorMatrix& F, HitReadings& read, const PatchSet& patches, const RayScene& rays,
                  const FormFactorSettings& settings, const std::vector<char>& analyticColumns,
                  const std::vector<char>& emitting, const std::vector<int>& raysFor) {
    const size_t n = F.size();
    if (!F.isSparse() || raysFor.size() != n || read.rows.size() != n) return;
    HitReadings more;
    FormFactorMatrix part = castFormFactors(patches, rays, settings, analyticColumns, emitting, &more, raysFor);
    std::vector<std::vector<std::pair<int32_t, float>>> rows(n), meanRows(n);
    std::vector<float> exposed = F.exposed, seen = F.seen;
    for (size_t i = 0; i < n; ++i) {
        const bool again = raysFor[i] > 0;
        const FormFactorMatrix& from = again ? part : F;
        const FormFactorMatrix::SparseRow row = from.sparseRow(i);
        for (size_t k = 0; k < row.count; ++k) rows[i].push_back({row.column[k], row.value[k]});
        if (from.hasMeanRow(i)) {
            const FormFactorMatrix::SparseRow mean = from.meanRow(i);
            for (size_t k = 0; k < mean.count; ++k) meanRows[i].push_back({mean.column[k], mean.value[k]});
        }
        if (!again) continue;
        exposed[i] = part.exposed[i], seen[i] = part.seen[i];
        read.rows[i] = std::move(more.rows[i]), read.meanRows[i] = std::move(more.meanRows[i]);
        read.farRows[i] = std::move(more.farRows[i]), read.farMeanRows[i] = std::move(more.farMeanRows[i]);
        read.shift[i] = more.shift[i];
    }
    std::vector<FormFactorMatrix::EntryVariance> variance;
    for (const auto& e : F.entryVariance)
        if (raysFor[size_t(e.row)] <= 0) variance.push_back(e);
    variance.insert(variance.end(), part.entryVariance.begin(), part.entryVariance.end());
    sortByRow(variance);
    F.entryVariance = std::move(variance);
    std::vector<BackTransfer> back;
    for (const BackTransfer& t : F.backTransfers)
        if (raysFor[size_t(t.from)] <= 0) back.push_back(t);
    back.insert(back.end(), part.backTransfers.begin(), part.backTransfers.end());
    sortBackTransfers(back);
    F.backTransfers = std::move(back);
    F.exposed = std::move(exposed);
    F.seen = std::move(seen);
    replaceRows(F, rows, meanRows);
    read.start.clear(), read.neighbour.clear(), read.qu.clear(), read.qv.clear();
    slopeWeights(patches, F.exposed, read);
}

void readLightWhereRaysLand(FormFactorMatrix& F, const PatchSet& patches, const HitReadings& read,
                            const std::vector<Rgb>& B, const std::vector<char>& specular,
                            const std::vector<Rgb>& reflectance) {
    const size_t n = F.size();
    if (!F.isSparse() || read.rows.size() != n || read.start.size() != n + 1 || B.size() != n) return;
    const Timer timer;
    const uint64_t before = F.entries();
    // A limiter after Barth and Jespersen's: the slope, scaled so that the light it reconstructs at
    // the patch's corners differs from the patch's mean by no more than its farthest neighbour's mean
    // does (and stays positive). Their own bound, the neighbours' range, clipped the slopes of the
    // patches along the short block's foot, whose darker side has no neighbour, and the block's
    // front face read the floor there brighter than it is: +0.67% over 8 seeds (+0.33% with this
    // bound, +0.32% with none).
    std::vector<float> limit(n, 0.0f);
    std::vector<char> steep(n, 0);  // kSteep
    parallelFor(
        int64_t(n),
        [&](int64_t begin, int64_t end) {
            for (int64_t jj = begin; jj < end; ++jj) {
                const size_t j = size_t(jj);
                if (read.start[j] == read.start[j + 1]) continue;
                const double bj = B[j].sum() / 3;
                double gu = 0, gv = 0, low = bj, high = bj;
                for (uint32_t a = read.start[j]; a < read.start[j + 1]; ++a) {
                    const double bk = B[size_t(read.neighbour[a])].sum() / 3;
                    gu += read.qu[a] * (bk - bj), gv += read.qv[a] * (bk - bj);
                    low = std::min(low, bk), high = std::max(high, bk);
                }
                // As far from the mean as the farthest neighbour, either way (not below zero).
                const double reach = std::max(high - bj, bj - low);
                low = std::max(0.0, bj - reach), high = bj + reach;
                const Vec3 c = read.uncoveredCentroid(patches, j);
                double phi = 1;
                for (int k = 0; k < patches.cornerCount[j]; ++k) {
                    const Vec3 x = patches.corners[j][size_t(k)] - c;
                    const double delta = gu * x.dot(read.tangentU[j]) + gv * x.dot(read.tangentV[j]);
                    if (delta > 0)
                        phi = std::min(phi, (high - bj) / delta);
                    else if (delta < 0)
                        phi = std::min(phi, (low - bj) / delta);
                }
                limit[j] = j < specular.size() && specular[j] ? 0.0f : float(std::max(phi, 0.0));
                steep[j] = limit[j] * std::sqrt(gu * gu + gv * gv) * patches.radius[j] >= kSteep * bj;
            }
        },
        256);
    std::vector<std::vector<std::pair<int32_t, float>>> rows(n), meanRows(n);
    std::atomic<size_t> damped{0};
    parallelFor(
        int64_t(n),
        [&](int64_t begin, int64_t end) {
            size_t mine = 0;
            for (int64_t ii = begin; ii < end; ++ii) {
                const size_t i = size_t(ii);
                // Half of the row's margin below one kept: rho_i sum |F_ij| <= (1 + rho_i s_i) / 2,
                // s_i its sum (which the moves keep).
                auto most = [&](FormFactorMatrix::SparseRow row) {
                    const double rho = i < reflectance.size() ? reflectance[i].maxCoeff() : 0.0;  // none: no bound
                    double s = 0;
                    for (size_t k = 0; k < row.count; ++k) s += std::abs(double(row.value[k]));
                    return rho > 0 ? std::max(s, (1 + rho * s) / (2 * rho)) : 1e30;
                };
                foldNearHits(F.sparseRow(i), read.rows[i], read.farRows[i], read, limit, steep, most(F.sparseRow(i)),
                             rows[i], mine);
                if (F.hasMeanRow(i))
                    foldNearHits(F.meanRow(i), read.meanRows[i], read.farMeanRows[i], read, limit, steep,
                                 most(F.meanRow(i)), meanRows[i], mine);
            }
            damped += mine;
        },
        64);
    replaceRows(F, rows, meanRows);
    size_t limited = 0;
    for (size_t j = 0; j < n; ++j)
        limited += read.start[j + 1] > read.start[j] && limit[j] < 1 && !(j < specular.size() && specular[j]);
    logInfo("form factors (rays): rays that landed within ", kNearRadii,
            " radii read the light where they landed (slopes of ", limited, " of ", n, " patches limited; moves of ",
            size_t(damped), " rows scaled down to keep them contractive); entries ", before, " -> ", F.entries(), ", ",
            timer.seconds(), " s");
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
