#include "solver/radiosity/form_factors.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <numeric>

#include "core/cluster.h"
#include "core/counters.h"
#include "core/error.h"
#include "core/log.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "core/rng.h"
#include "core/timer.h"

namespace penumbra {
namespace {

const Counter g_facingPairs("form_factors.facing_pairs", "patch pairs that face each other (front or back)");
const Counter g_occludedPairs("form_factors.occluded_pairs", "facing pairs whose visibility rays all were blocked");
const Counter g_partlyVisible("form_factors.partly_visible_pairs", "facing pairs whose visibility rays disagreed");
const Counter g_visibilityRays("form_factors.visibility_rays", "visibility rays between patch pairs");
const Counter g_kernelEvaluations("form_factors.kernel_evaluations", "point-to-polygon kernel evaluations");

// A point of patch i in stratum k of a side x side grid, jittered. Points keep a margin of 1e-3 of
// the patch from its edges: a segment from a point exactly on an edge can graze along a seam (the
// top edge of a wall, a wall-ceiling joint) in float precision and slip past a thin occluder.
Vec3 stratifiedPoint(const PatchSet& p, size_t i, int k, int side, Rng& rng) {
    constexpr double kMargin = 1e-3;
    auto inset = [](double t) { return kMargin + (1 - 2 * kMargin) * t; };
    const double u = ((k % side) + rng.uniform()) / side, v = ((k / side) + rng.uniform()) / side;
    // Sample by area: on triangles the collapsed map needs u = sqrt(.) to be uniform.
    if (p.isTriangle(i)) return p.pointAt(i, inset(std::sqrt(u)), inset(v));
    // Quads are near-parallelograms, where the bilinear map is area-uniform.
    return p.pointAt(i, inset(u), inset(v));
}

// The part of patch b on the `side` of patch a's plane, as a convex polygon (up to 8 corners)
// pulled 1e-3 of the way towards its centroid, like the inset of `stratifiedPoint`.
struct ClippedPolygon {
    Vec3 v[8];
    int count = 0;
    double area = 0;
};
ClippedPolygon clipToSide(const PatchSet& p, size_t b, size_t a, const Vec3& sideNormal) {
    ClippedPolygon out;
    const int n = p.cornerCount[b];
    for (int k = 0; k < n; ++k) {
        const Vec3& u = p.corners[b][size_t(k)];
        const Vec3& w = p.corners[b][size_t((k + 1) % n)];
        const double du = sideNormal.dot(u - p.centroid[a]), dw = sideNormal.dot(w - p.centroid[a]);
        if (du > 0) out.v[out.count++] = u;
        if ((du > 0) != (dw > 0)) out.v[out.count++] = u + (du / (du - dw)) * (w - u);
    }
    if (out.count < 3) return out;
    Vec3 centre = Vec3::Zero();
    for (int k = 0; k < out.count; ++k) centre += out.v[k];
    centre /= out.count;
    for (int k = 0; k < out.count; ++k) out.v[k] = centre + (1 - 2e-3) * (out.v[k] - centre);
    for (int k = 1; k + 1 < out.count; ++k)
        out.area += 0.5 * (out.v[k] - out.v[0]).cross(out.v[k + 1] - out.v[0]).norm();
    return out;
}

// A uniform point of a convex polygon: a fan triangle chosen by area, then a uniform point in it.
Vec3 uniformPoint(const ClippedPolygon& c, Rng& rng) {
    double pick = rng.uniform() * c.area;
    int k = 1;
    for (; k + 2 < c.count; ++k) {
        const double a = 0.5 * (c.v[k] - c.v[0]).cross(c.v[k + 1] - c.v[0]).norm();
        if (pick < a) break;
        pick -= a;
    }
    double s = rng.uniform(), t = rng.uniform();
    if (s + t > 1) s = 1 - s, t = 1 - t;
    return c.v[0] + s * (c.v[k] - c.v[0]) + t * (c.v[k + 1] - c.v[0]);
}

}  // namespace

bool segmentCrossesPatch(const PatchSet& p, size_t k, const Vec3& from, const Vec3& to, double trim) {
    const Vec3 d = to - from;
    auto crosses = [&](const Vec3& a, const Vec3& b, const Vec3& c) {
        const Vec3 e1 = b - a, e2 = c - a, pv = d.cross(e2);
        const double det = e1.dot(pv);
        if (!(std::abs(det) > 0)) return false;
        const Vec3 tv = from - a;
        const double u = tv.dot(pv) / det;
        if (u < 0 || u > 1) return false;
        const Vec3 qv = tv.cross(e1);
        const double v = d.dot(qv) / det;
        if (v < 0 || u + v > 1) return false;
        const double t = e2.dot(qv) / det;
        return t > trim && t < 1 - trim;
    };
    const auto& c = p.corners[k];
    if (p.cornerCount[k] == 3) return crosses(c[0], c[1], c[2]);
    return crosses(c[0], c[1], c[3]) || crosses(c[2], c[3], c[1]);
}

// A quad that is not flat (a patch of the Cornell box's non-planar walls) is traced as two
// triangles while its points lie on the bilinear surface, up to its warp away from them: the lift
// clears that too, or the patch's own triangles hide half its points.
double liftDistance(const PatchSet& p, size_t i) {
    double warp = 0;
    if (!p.isTriangle(i)) {
        const auto& c = p.corners[i];
        const Vec3 n = (c[1] - c[0]).cross(c[3] - c[0]);
        const double len = n.norm();
        if (len > 0) warp = std::abs(n.dot(c[2] - c[0])) / len;
    }
    return 1e-4 * p.boundingRadius(i) + 1e-6 * p.centroid[i].cwiseAbs().maxCoeff() + warp;
}

PlaneSides planeSides(const PatchSet& p, size_t a, size_t b) {
    const double eps = 1e-9 * (p.boundingRadius(a) + p.boundingRadius(b));
    PlaneSides sides;
    for (int k = 0; k < p.cornerCount[b]; ++k) {
        const double h = p.normal[a].dot(p.corners[b][size_t(k)] - p.centroid[a]);
        sides.front = sides.front || h > eps;
        sides.behind = sides.behind || h < -eps;
    }
    return sides;
}

// Measuring segments per deciding one where those disagree. The penumbrae are where a pair's
// visibility is noisy, and that noise is not in the ray-cast matrix's stated noise (its analytic
// lamp columns count as exact): the Cornell box's face beside the short block, lit by the floor
// in the block's half-shadow, spread 0.53% over 8 seeds at 4, 0.42% at 16 (0.30% with 16 deciding
// rays, for 4x the visibility rays); its visibility rays 0.30 -> 0.38 M.
constexpr int kEdgeRays = 16;

Visibility visibleFraction(const PatchSet& p, const RayScene& scene, size_t a, size_t b, int sideA, int sideB,
                           bool clipped, int base, uint64_t seed, Stream stream, Blockers* blockers) {
    Rng rng = pairRng(seed, stream, a, b);
    const RayView view = scene.viewBetween(a, b);
    const Vec3 na = sideA * p.normal[a], nb = sideB * p.normal[b];
    const Vec3 liftA = liftDistance(p, a) * na, liftB = liftDistance(p, b) * nb;
    // The part of a in front of b's receiving face, and of b in front of a's sending face.
    const ClippedPolygon partA = clipped ? clipToSide(p, a, b, nb) : ClippedPolygon{};
    const ClippedPolygon partB = clipped ? clipToSide(p, b, a, na) : ClippedPolygon{};
    if (clipped && (partA.count < 3 || partB.count < 3 || !(partA.area > 0) || !(partB.area > 0))) return {0.0, 0, 0};
    // Each segment counts with the kernel between its ends, cos cos / r^2: a shadow that falls where
    // the patches see each other best (a desk under a lamp, the floor under the desk) takes its share
    // of the factor, not of the area; and the part of the other patch a point sees past an edge,
    // its share of what that point receives (weighing each point by its factor to the whole other
    // patch instead read the lamp over a shadowed floor 0.7% dark). The weights count only where the
    // measuring rays disagree.
    thread_local std::vector<std::pair<double, bool>> ends;
    ends.clear();
    int visible = 0, rays = 0;
    // `count` segments whose ends cover both patches evenly: the largest full grid of strata that
    // `count` fills, and uniform points for the rest (a grid only partly filled would leave the same
    // band of every patch unsampled, and bias every penumbra it crosses).
    auto cast = [&](int count) {
        const int side = std::max(1, int(std::sqrt(double(count) + 0.5))), strata = side * side;
        // Strata of a paired with those of b in a random order: a fixed pairing samples the same
        // few cell pairs of the two patches every time, and is biased wherever visibility depends on
        // both ends (the floor seeing a lamp through a door).
        thread_local std::vector<int> order;
        shuffledStrata(order, strata, rng);
        for (int k = 0; k < count; ++k) {
            const bool gridded = k < strata;
            const int sa = gridded ? k : 0, sb = gridded ? order[size_t(k)] : 0;
            const int sideOf = gridded ? side : 1;
            const Vec3 from = clipped ? uniformPoint(partA, rng) : stratifiedPoint(p, a, sa, sideOf, rng);
            const Vec3 to = clipped ? uniformPoint(partB, rng) : stratifiedPoint(p, b, sb, sideOf, rng);
            ++rays;
            bool open;
            if (!blockers) {
                open = !scene.occluded(from + liftA, to + liftB, 1e-5, view);
            } else if (std::any_of(blockers->patch.begin(), blockers->patch.end(), [&](int known) {
                           return known >= 0 && segmentCrossesPatch(p, size_t(known), from + liftA, to + liftB, 1e-5);
                       })) {
                open = false;
            } else {
                const int by = scene.occluder(from + liftA, to + liftB, 1e-5, view);
                open = by == -1;
                if (by >= 0) {
                    blockers->patch[size_t(blockers->next)] = by;
                    blockers->next = (blockers->next + 1) % int(blockers->patch.size());
                }
            }
            visible += open;
            const Vec3 d = to - from;
            const double r2 = d.squaredNorm();
            ends.emplace_back(std::max(0.0, na.dot(d)) * std::max(0.0, -nb.dot(d)) / std::max(r2 * r2, 1e-300), open);
        }
    };
    // The share of the segments that are open, each weighted by its kernel (where the rays disagree:
    // otherwise 0 or 1).
    auto weightedFraction = [&](int open, int count) {
        if (open == 0 || open == count) return double(open) / count;
        double seen = 0, weights = 0;
        for (const auto& [w, isOpen] : ends) {
            weights += w;
            seen += isOpen ? w : 0;
        }
        return weights > 0 ? seen / weights : double(open) / count;
    };
    // The first rays only decide how to sample; the estimate is made of the rays cast after them: where
    // the first disagree (a shadow edge crosses the pair), kEdgeRays times as many, else as many again. Had the
    // first rays been kept (all blocked: 0, else refined together with them), a pair whose patches see
    // each other through a narrow opening (the floor of a room, a corridor's lamp through the door)
    // would lose most of its light: at a visible share v and four independent rays, the mean came to
    // about 0.2 v + 3.2 v^2 (v = 0.1: 0.048), since the four that decide are mostly all blocked and
    // otherwise hold more open rays than their share; and a pair whose first rays all pass, a small
    // shadow, would read wholly open.
    cast(base);
    const int decided = rays;
    const bool edge = visible > 0 && visible < rays;
    ends.clear(), visible = 0, rays = 0;
    cast(edge ? kEdgeRays * base : base);
    return {weightedFraction(visible, rays), rays + decided, rays};
}

namespace {

// Rows i < j pair up once, row i holding its n - 1 - i pairs: blocks of consecutive rows with about
// equal pairs, so that each is about one unit of work (the first row costs n times the last).
// Block k is rows [start[k], start[k + 1]).
std::vector<size_t> pairBlocks(size_t n) {
    const size_t blocks = std::clamp<size_t>(n / 4, 1, 1024);
    const double pairs = double(n) * double(n - 1) / 2, each = pairs / double(blocks);
    std::vector<size_t> start{0};
    double sum = 0;
    for (size_t i = 0; i < n; ++i) {
        sum += double(n - 1 - i);
        if (sum >= each * double(start.size()) && start.size() < blocks) start.push_back(i + 1);
    }
    if (start.back() != n) start.push_back(n);
    return start;
}

// Blocks of rows, as bytes: the blocks' numbers, the back transfers given, and each row i's pairs
// F(i, j > i) and F(j > i, i). What the ranks exchange and the checkpoint keeps.
std::string packBlocks(const FormFactorMatrix& F, const std::vector<size_t>& start, const std::vector<int64_t>& blocks,
                       const std::vector<BackTransfer>& back) {
    const size_t n = F.size();
    cluster::Packer packed;
    packed.put(blocks);
    packed.put(back);
    std::vector<float> row, column;
    for (int64_t k : blocks)
        for (size_t i = start[size_t(k)]; i < start[size_t(k) + 1]; ++i) {
            row.assign(F.row(i) + i + 1, F.row(i) + n);
            column.resize(n - 1 - i);
            for (size_t j = i + 1; j < n; ++j) column[j - i - 1] = F(j, i);
            packed.put(row);
            packed.put(column);
        }
    return packed.bytes;
}

// The blocks of `bytes` into F (their back transfers appended); marks them in `done`. Throws Error
// when the bytes do not fit these blocks (a checkpoint's are checked against the solve before).
void unpackBlocks(FormFactorMatrix& F, const std::vector<size_t>& start, const std::string& bytes,
                  std::vector<char>& done) {
    const size_t n = F.size();
    cluster::Unpacker from(bytes);
    std::vector<int64_t> blocks;
    std::vector<BackTransfer> back;
    std::vector<float> row, column;
    from.get(blocks);
    from.get(back);
    F.backTransfers.insert(F.backTransfers.end(), back.begin(), back.end());
    for (int64_t k : blocks) {
        PENUMBRA_CHECK(k >= 0 && size_t(k) + 1 < start.size());
        for (size_t i = start[size_t(k)]; i < start[size_t(k) + 1]; ++i) {
            from.get(row);
            from.get(column);
            PENUMBRA_CHECK(row.size() == n - 1 - i && column.size() == n - 1 - i);
            for (size_t j = i + 1; j < n; ++j) F(i, j) = row[j - i - 1], F(j, i) = column[j - i - 1];
        }
        done[size_t(k)] = 1;
    }
    PENUMBRA_CHECK(from.done());
}

// Row blocks (FormFactorMatrix::inRowBlocks): a block of rows' pairs as computed, row i's F(i, j > i)
// then F(j > i, i), for each row of the block in order.
struct ComputedBlock {
    int64_t block;
    std::vector<float> pairs;
};

// The values of `computed` sent to the ranks that hold them: row i's part to row i's rank, the column
// part F(j > i, i) split among the ranks holding the rows j. Each message: row, 0 (row) or 1
// (column), first column (row) or row (column), values.
std::vector<std::string> routeBlocks(const FormFactorMatrix& F, const std::vector<size_t>& start,
                                     const std::vector<ComputedBlock>& computed) {
    const size_t n = F.size();
    const std::vector<size_t>& owners = F.rowBlocks();
    std::vector<cluster::Packer> to(owners.size() - 1);
    for (const ComputedBlock& c : computed) {
        const float* at = c.pairs.data();
        for (size_t i = start[size_t(c.block)]; i < start[size_t(c.block) + 1]; ++i) {
            const size_t count = n - 1 - i;
            cluster::Packer& rowRank = to[size_t(F.rowOwner(i))];
            rowRank.put(int64_t(i)), rowRank.put(int64_t(0)), rowRank.put(int64_t(i + 1));
            rowRank.put(at, count);
            at += count;
            for (size_t r = 0; r + 1 < owners.size(); ++r) {
                const size_t b = std::max(owners[r], i + 1), e = owners[r + 1];
                if (b >= e) continue;
                to[r].put(int64_t(i)), to[r].put(int64_t(1)), to[r].put(int64_t(b));
                to[r].put(at + (b - i - 1), e - b);
            }
            at += count;
        }
    }
    std::vector<std::string> bytes;
    for (cluster::Packer& p : to) bytes.push_back(std::move(p.bytes));
    return bytes;
}

// What routeBlocks sent this rank, into its rows.
void receiveBlocks(FormFactorMatrix& F, const std::vector<std::string>& from) {
    std::vector<float> values;
    for (const std::string& bytes : from) {
        cluster::Unpacker in(bytes);
        while (!in.done()) {
            int64_t i = 0, kind = 0, first = 0;
            in.get(i), in.get(kind), in.get(first);
            in.get(values);
            for (size_t t = 0; t < values.size(); ++t) {
                const size_t row = kind == 0 ? size_t(i) : size_t(first) + t;
                const size_t column = kind == 0 ? size_t(first) + t : size_t(i);
                PENUMBRA_CHECK(row >= F.firstRow() && row < F.endRow() && column < F.size());
                F(row, column) = values[t];
            }
        }
    }
}

// Row blocks: what a rank keeps in its checkpoint: the tag, the ranks and its rows' range, the
// blocks done (every rank's: the same list on each), every back transfer, and its rows (their count
// here; the floats follow, written from F: saveOwn).
std::string rowBlockHead(const FormFactorMatrix& F, const std::vector<char>& done) {
    cluster::Packer packed;
    packed.bytes.assign(kRowBlockTag, sizeof kRowBlockTag);
    std::vector<int64_t> finished;
    for (size_t k = 0; k < done.size(); ++k)
        if (done[k]) finished.push_back(int64_t(k));
    packed.put(int64_t(cluster::size())), packed.put(uint64_t(F.firstRow())), packed.put(uint64_t(F.endRow()));
    packed.put(finished);
    packed.put(F.backTransfers);
    packed.put(uint64_t((F.endRow() - F.firstRow()) * F.size()));
    return std::move(packed.bytes);
}

void saveHeldRows(CastCheckpoint& checkpoint, int pass, const FormFactorMatrix& F, const std::vector<char>& done) {
    const size_t floats = (F.endRow() - F.firstRow()) * F.size();
    checkpoint.saveOwn(pass, rowBlockHead(F, done), floats ? reinterpret_cast<const char*>(F.row(F.firstRow())) : "",
                       floats * sizeof(float));
}

// A row-block checkpoint back into F and `done`, when every rank has one of the same blocks for this
// many ranks (a kill between two ranks' saves, or another count of ranks, leaves them apart: the
// matrix is then made again). Returns the blocks taken.
int64_t resumeHeldRows(FormFactorMatrix& F, const std::string& saved, std::vector<char>& done) {
    std::vector<int64_t> finished;
    std::vector<BackTransfer> back;
    bool usable = false;
    if (isRowBlockPass(saved)) {
        cluster::Unpacker in(saved);
        char tag[sizeof kRowBlockTag];
        for (char& c : tag) in.get(c);
        int64_t ranks = 0;
        uint64_t first = 0, end = 0;
        in.get(ranks), in.get(first), in.get(end);
        usable = ranks == cluster::size() && first == F.firstRow() && end == F.endRow();
        if (usable) {
            in.get(finished), in.get(back);
            for (int64_t k : finished) usable = usable && k >= 0 && size_t(k) < done.size();
            // Straight into the rows this rank holds (zero until then): no second copy of them.
            float none = 0;
            usable = usable && in.get(end > first ? &F(first, 0) : &none, (end - first) * F.size()) && in.done();
        }
    }
    cluster::Packer mine;
    mine.put(int64_t(usable));
    mine.put(usable ? finished : std::vector<int64_t>());
    const std::vector<std::string> all = cluster::allGather(mine.bytes);
    for (const std::string& theirs : all)
        if (theirs != all[0]) usable = false;
    if (!usable) {
        if (!saved.empty()) F = FormFactorMatrix(F.size(), F.rowBlocks(), cluster::rank());  // rows read: zero again
        if (!saved.empty() || all[0] != mine.bytes)
            logWarning(
                "form factors: the ranks' checkpoints of their rows do not match (another count of ranks, or "
                "a kill between two ranks' saves): computing the matrix again");
        return 0;
    }
    F.backTransfers = back;
    for (int64_t k : finished) done[size_t(k)] = 1;
    return int64_t(finished.size());
}

// A round of blocks takes about this long (by the last round's pace): the ranks exchange their rows
// after each, and the checkpoint takes them when due (at least every 20 s).
constexpr double kRoundSeconds = 5;

}  // namespace

FormFactorMatrix computeFormFactors(const PatchSet& patches, const RayScene& scene,
                                    const FormFactorSettings& settings) {
    Timer timer;
    const size_t n = patches.size();
    const bool blocked = !settings.rowBlocks.empty();
    FormFactorMatrix F = blocked ? FormFactorMatrix(n, settings.rowBlocks, cluster::rank()) : FormFactorMatrix(n);
    std::mutex backMutex;
    const CounterValues before = counterValues();
    const std::vector<size_t> start = pairBlocks(n);
    const int64_t blocks = int64_t(start.size()) - 1;
    std::vector<char> done(size_t(blocks), 0);
    // A killed solve's blocks, from its checkpoint (io/checkpoint.h).
    CastCheckpoint* checkpoint = settings.checkpoint;
    const int pass = checkpoint ? checkpoint->beginPass() : 0;
    if (checkpoint && blocked) {
        // Row blocks: each rank its own rows, from a file of its own.
        if (const int64_t resumed = resumeHeldRows(F, checkpoint->ownRows(pass), done); resumed > 0)
            logInfo("form factors: ", resumed, " of ", blocks, " blocks of rows from the ranks' checkpoints");
        checkpoint->forget(pass);
    } else if (checkpoint && isRowBlockPass(checkpoint->savedRows(pass))) {
        logWarning(
            "form factors: the checkpoint holds the matrix in row blocks, which this run does not use: "
            "computing it again");
    } else if (checkpoint && !checkpoint->savedRows(pass).empty()) {
        unpackBlocks(F, start, checkpoint->savedRows(pass), done);
        logInfo("form factors: ", std::count(done.begin(), done.end(), 1), " of ", blocks,
                " blocks of rows from the checkpoint");
    }
    std::vector<int64_t> left;
    for (int64_t k = 0; k < blocks; ++k)
        if (!done[size_t(k)]) left.push_back(k);
    Progress progress("form factors", blocks);
    progress.update(blocks - int64_t(left.size()));
    std::vector<BackTransfer> roundBack;
    std::vector<ComputedBlock> roundBlocks;  // row blocks: this rank's blocks of the round
    // Blocks from a work queue, round by round: under mpirun each rank takes them as its threads come
    // free, and after each round the ranks exchange their rows.
    // Tests: PENUMBRA_TEST_CHECKPOINT_ROWS=k makes every round k blocks (and saves after each).
    const char* fixed = std::getenv("PENUMBRA_TEST_CHECKPOINT_ROWS");
    const uint64_t fixedRound = fixed ? uint64_t(std::max(1, std::atoi(fixed))) : 0;
    uint64_t round = fixed ? fixedRound : std::max<uint64_t>(1, left.size() / 64);
    for (size_t at = 0; at < left.size();) {
        const size_t take = std::min<size_t>(round, left.size() - at);
        const Timer roundTimer;
        roundBack.clear();
        roundBlocks.clear();
        std::vector<int64_t> mine = cluster::forEachQueued(
            int64_t(take),
            [&](int64_t item) {
                const int64_t block = left[at + size_t(item)];
                uint64_t myPairs = 0, myEvaluations = 0, myRays = 0, myPartial = 0, myOccluded = 0;
                std::vector<BackTransfer> myBack;
                // Row blocks: the block's pairs as ComputedBlock holds them, row i's from `base`.
                ComputedBlock computed{block, {}};
                size_t base = 0;
                if (blocked) {
                    size_t count = 0;
                    for (size_t i = start[size_t(block)]; i < start[size_t(block) + 1]; ++i) count += 2 * (n - 1 - i);
                    computed.pairs.assign(count, 0.0f);
                }
                const auto put = [&](size_t i, size_t j, float ij, float ji) {
                    if (!blocked) {
                        F(i, j) = ij, F(j, i) = ji;
                        return;
                    }
                    computed.pairs[base + (j - i - 1)] = ij;
                    computed.pairs[base + (n - 1 - i) + (j - i - 1)] = ji;
                };
                for (size_t i = start[size_t(block)]; i < start[size_t(block) + 1]; base += 2 * (n - 1 - i), ++i) {
                    for (size_t j = i + 1; j < n; ++j) {
                        const PlaneSides jSeenByI = planeSides(patches, i, j), iSeenByJ = planeSides(patches, j, i);
                        const bool jFrontOfI = jSeenByI.front, iFrontOfJ = iSeenByJ.front;
                        const bool clipped = jSeenByI.straddles() || iSeenByJ.straddles();
                        if (!jFrontOfI && !iFrontOfJ) continue;
                        ++myPairs;
                        // Which faces exchange light: a patch sends from its front when the other lies in
                        // front of it; otherwise the other's front reaches its back.
                        const int sideI = jFrontOfI ? 1 : -1, sideJ = iFrontOfJ ? 1 : -1;
                        const Visibility vis = visibleFraction(patches, scene, i, j, sideI, sideJ, clipped,
                                                               settings.visibilityRays, settings.seed);
                        myRays += uint64_t(vis.rays);
                        if (vis.fraction == 0) {
                            ++myOccluded;
                            continue;
                        }
                        if (vis.fraction < 1) ++myPartial;
                        const CubatureSettings& cub = settings.cubature;
                        if (jFrontOfI && iFrontOfJ) {
                            // Front to front: integrate over the smaller patch, analytically over the larger.
                            const bool iSmaller = patches.area[i] <= patches.area[j];
                            const AreaFactors g =
                                unoccludedAreaFactors(patches, iSmaller ? i : j, iSmaller ? j : i, cub, &myEvaluations);
                            put(i, j, float(vis.fraction * g.front / patches.area[i]),
                                float(vis.fraction * g.front / patches.area[j]));
                            // Where one patch straddles the other's plane, part of it sees the other's back:
                            // tested by rays of its own (a block's side is mostly seen from behind through
                            // the block itself), and integrated only when some of them get through.
                            auto backPart = [&](size_t from, size_t to, bool fromIsSource) {
                                const Visibility vb =
                                    visibleFraction(patches, scene, from, to, 1, -1, clipped, settings.visibilityRays,
                                                    settings.seed, Stream::BackVisibility);
                                myRays += uint64_t(vb.rays);
                                if (vb.fraction == 0) return 0.0;
                                return vb.fraction *
                                       (fromIsSource
                                            ? g.back
                                            : unoccludedAreaFactors(patches, from, to, cub, &myEvaluations).back);
                            };
                            const double backIJ = iSeenByJ.straddles() ? backPart(i, j, iSmaller) : 0.0;
                            const double backJI = jSeenByI.straddles() ? backPart(j, i, !iSmaller) : 0.0;
                            if (backIJ > 0) myBack.push_back({int(i), int(j), backIJ});
                            if (backJI > 0) myBack.push_back({int(j), int(i), backJI});
                        } else if (jFrontOfI) {
                            // All of i lies behind j's plane: i's front reaches j's back.
                            myBack.push_back({int(i), int(j),
                                              vis.fraction * unoccludedAreaFactor(patches, i, j, cub, &myEvaluations)});
                        } else {
                            myBack.push_back({int(j), int(i),
                                              vis.fraction * unoccludedAreaFactor(patches, j, i, cub, &myEvaluations)});
                        }
                    }
                }
                g_facingPairs.add(myPairs);
                g_kernelEvaluations.add(myEvaluations);
                g_visibilityRays.add(myRays);
                g_partlyVisible.add(myPartial);
                g_occludedPairs.add(myOccluded);
                std::lock_guard<std::mutex> lock(backMutex);
                roundBack.insert(roundBack.end(), myBack.begin(), myBack.end());
                if (blocked) roundBlocks.push_back(std::move(computed));
            },
            [&](int64_t finished) { progress.update(finished); }, prepareTracingThread);
        for (int64_t& item : mine) item = left[at + size_t(item)];
        if (blocked) {
            // Each value to the rank that holds its row; every rank keeps every back transfer.
            receiveBlocks(F, cluster::exchange(routeBlocks(F, start, roundBlocks)));
            // Every rank knows every block done (the checkpoint's list) and keeps every back transfer.
            cluster::Packer back;
            back.put(mine);
            back.put(roundBack);
            const std::vector<std::string> all = cluster::allGather(back.bytes);
            for (int r = 0; r < cluster::size(); ++r)
                if (r != cluster::rank()) {
                    cluster::Unpacker from(all[size_t(r)]);
                    std::vector<int64_t> theirBlocks;
                    std::vector<BackTransfer> theirs;
                    from.get(theirBlocks);
                    from.get(theirs);
                    for (int64_t k : theirBlocks) done[size_t(k)] = 1;
                    F.backTransfers.insert(F.backTransfers.end(), theirs.begin(), theirs.end());
                }
        } else if (cluster::distributed()) {
            const std::vector<std::string> all = cluster::allGather(packBlocks(F, start, mine, roundBack));
            for (int r = 0; r < cluster::size(); ++r)
                if (r != cluster::rank()) unpackBlocks(F, start, all[size_t(r)], done);
        }
        F.backTransfers.insert(F.backTransfers.end(), roundBack.begin(), roundBack.end());
        for (int64_t k : mine) done[size_t(k)] = 1;
        at += take;
        // The next round at this one's pace, as the leader measured it (every rank takes the same).
        uint64_t next = uint64_t(
            std::clamp(double(take) / std::max(roundTimer.seconds(), 1e-3) * kRoundSeconds, 1.0, double(left.size())));
        // And whether to save now (row blocks: every rank its rows, by the leader's clock): 0 no, 1 keep,
        // 2 keep and write.
        const uint64_t save =
            checkpoint && at < left.size() && checkpoint->due() ? (checkpoint->writesNow() ? 2 : 1) : 0;
        uint64_t told[2] = {next, save};
        std::string sent(reinterpret_cast<const char*>(told), sizeof told);
        sent = cluster::broadcast(sent);
        std::memcpy(told, sent.data(), sizeof told);
        next = told[0];
        round = fixed ? fixedRound : next;
        // Row blocks: a round's values are held (and copied for the exchange) until it ends; at most a
        // sixteenth of the blocks keeps them under a quarter of what each rank holds.
        if (blocked) round = std::min<uint64_t>(round, std::max<int64_t>(1, blocks / 16));
        if (blocked && told[1] == 2) {  // (row blocks keep nothing in memory: only a write counts)
            saveHeldRows(*checkpoint, pass, F, done);
        } else if (!blocked && cluster::leader() && told[1] > 0) {
            std::vector<int64_t> finished;
            for (int64_t k = 0; k < blocks; ++k)
                if (done[size_t(k)]) finished.push_back(k);
            checkpoint->save(pass, packBlocks(F, start, finished, F.backTransfers));
        }
    }
    progress.done();
    // The pass done: all its rows into the checkpoint (a stage boundary).
    if (checkpoint && blocked) {
        const std::string write = cluster::broadcast(std::string(1, checkpoint->writesNow() ? '1' : '0'));
        if (write == "1") saveHeldRows(*checkpoint, pass, F, done);
    } else if (checkpoint && cluster::leader()) {
        std::vector<int64_t> all(static_cast<size_t>(blocks));
        std::iota(all.begin(), all.end(), 0);
        checkpoint->save(pass, packBlocks(F, start, all, F.backTransfers));
    }
    // Thread scheduling (and the ranks) decide the order of the merge; sort so the result is reproducible.
    std::sort(F.backTransfers.begin(), F.backTransfers.end(), [](const BackTransfer& a, const BackTransfer& b) {
        return a.from != b.from ? a.from < b.from : a.to < b.to;
    });
    // Every rank's counts (cluster::forEachQueued adds the others').
    CounterValues did = countersSince(before);
    logInfo("form factors: ", n, " patches, ", did["form_factors.facing_pairs"], " facing pairs (",
            did["form_factors.occluded_pairs"], " occluded, ", did["form_factors.partly_visible_pairs"],
            " partly visible), ", did["form_factors.visibility_rays"], " rays, ",
            did["form_factors.kernel_evaluations"], " kernel evaluations in ", timer.seconds(), " s");
    return F;
}

std::vector<ConvexOccluder> convexOccluders(const PatchSet& patches) {
    const std::vector<std::vector<size_t>> members = patches.byObject();
    std::vector<ConvexOccluder> out(members.size());
    using P2 = std::array<double, 2>;
    auto cross = [](const P2& o, const P2& a, const P2& b) {
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
    };
    for (size_t o = 0; o < members.size(); ++o) {
        if (members[o].empty()) continue;
        ConvexOccluder c;
        const size_t first = members[o][0];
        c.normal = patches.normal[first];
        c.offset = c.normal.dot(patches.centroid[first]);
        orthonormalBasis(c.normal, c.u, c.v);
        std::vector<P2> points;
        double area = 0, size = 0;
        bool planar = true;
        for (size_t i : members[o]) {
            planar = planar && patches.normal[i].dot(c.normal) > 1 - 1e-9;
            area += patches.area[i];
            size = std::max(size, patches.radius[i]);
            for (int k = 0; k < patches.cornerCount[i]; ++k) {
                const Vec3& x = patches.corners[i][size_t(k)];
                planar = planar && std::abs(c.normal.dot(x) - c.offset) <= 1e-9 + 1e-7 * patches.radius[i];
                points.push_back({x.dot(c.u), x.dot(c.v)});
            }
        }
        if (!planar) continue;
        // Andrew's monotone chain: the hull counter-clockwise, without collinear points.
        std::sort(points.begin(), points.end());
        std::vector<P2> hull(2 * points.size());
        size_t k = 0;
        for (size_t i = 0; i < points.size(); ++i) {
            while (k >= 2 && cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
            hull[k++] = points[i];
        }
        for (size_t i = points.size() - 1, lower = k + 1; i-- > 0;) {
            while (k >= lower && cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
            hull[k++] = points[i];
        }
        hull.resize(k > 0 ? k - 1 : 0);
        if (hull.size() < 3) continue;
        double hullArea = 0;
        for (size_t i = 0; i < hull.size(); ++i) hullArea += cross({0, 0}, hull[i], hull[(i + 1) % hull.size()]) / 2;
        if (std::abs(hullArea - area) > 1e-6 * area) continue;  // not one convex polygon
        c.margin = 1e-6 * size;
        for (size_t i = 0; i < hull.size(); ++i) {
            const P2 &s = hull[i], &e = hull[(i + 1) % hull.size()];
            const double length = std::hypot(e[0] - s[0], e[1] - s[1]);
            const double nx = -(e[1] - s[1]) / length, ny = (e[0] - s[0]) / length;  // left of a CCW edge
            c.edges.push_back({nx, ny, nx * s[0] + ny * s[1]});
        }
        out[o] = std::move(c);
    }
    return out;
}

bool hidesWholly(const ConvexOccluder& o, const PatchSet& patches, size_t i, size_t j) {
    if (o.edges.empty()) return false;
    // Each corner in the occluder's frame (u, v, signed distance); all of i's on one side, all of
    // j's strictly on the other.
    std::array<Vec3, 4> a, b;
    const int na = patches.cornerCount[i], nb = patches.cornerCount[j];
    auto frame = [&](const Vec3& x) { return Vec3(x.dot(o.u), x.dot(o.v), o.normal.dot(x) - o.offset); };
    for (int k = 0; k < na; ++k) a[size_t(k)] = frame(patches.corners[i][size_t(k)]);
    for (int k = 0; k < nb; ++k) b[size_t(k)] = frame(patches.corners[j][size_t(k)]);
    const double side = a[0][2] > 0 ? 1 : -1;
    for (int k = 0; k < na; ++k)
        if (!(side * a[size_t(k)][2] > o.margin)) return false;
    for (int k = 0; k < nb; ++k)
        if (!(-side * b[size_t(k)][2] > o.margin)) return false;
    for (int k = 0; k < na; ++k)
        for (int l = 0; l < nb; ++l) {
            const Vec3 &p = a[size_t(k)], &q = b[size_t(l)];
            const double t = p[2] / (p[2] - q[2]);
            const double x = p[0] + t * (q[0] - p[0]), y = p[1] + t * (q[1] - p[1]);
            for (const auto& e : o.edges)
                if (!(e[0] * x + e[1] * y > e[2] + o.margin)) return false;
        }
    return true;
}

double frontFormFactor(const PatchSet& patches, const RayScene& rays, size_t i, size_t j,
                       const FormFactorSettings& settings, Blockers* blockers, double* variance, Stream stream,
                       bool clear) {
    if (variance) *variance = 0;
    if (i == j) return 0;
    const size_t a = std::min(i, j), b = std::max(i, j);
    const PlaneSides bSeenByA = planeSides(patches, a, b), aSeenByB = planeSides(patches, b, a);
    if (!bSeenByA.front || !aSeenByB.front) return 0;
    // A shadow can fall across part of a patch that is large for its distance from the other (a
    // 5 m^2 floor patch under a desk, its lamp 2.7 m up) and slip between four rays, all of which
    // then call the pair fully visible: the rays grow with the square of that ratio.
    const double reach = std::sqrt(std::max(patches.area[a], patches.area[b])) /
                         std::max((patches.centroid[a] - patches.centroid[b]).norm(), 1e-12);
    const int grid = std::clamp(int(std::ceil(4 * reach)), 1, 4);
    Visibility vis{0, 0, 0};
    if (clear) {
        vis.fraction = 1;
    } else {
        vis = visibleFraction(patches, rays, a, b, 1, 1, bSeenByA.straddles() || aSeenByB.straddles(),
                              settings.visibilityRays * grid * grid, settings.seed, stream, blockers);
        g_visibilityRays.add(uint64_t(vis.rays));
    }
    if (vis.fraction == 0) return 0;
    uint64_t evaluations = 0;
    const bool aSmaller = patches.area[a] <= patches.area[b];
    const AreaFactors g =
        unoccludedAreaFactors(patches, aSmaller ? a : b, aSmaller ? b : a, settings.cubature, &evaluations);
    g_kernelEvaluations.add(evaluations);
    const double unoccluded = g.front / patches.area[i];
    // The unbiased estimate of a share's variance from m measuring rays, v (1 - v) / (m - 1) (its
    // kernel weights, where the rays disagree, taken as even).
    if (variance && vis.measured > 1)
        *variance = unoccluded * unoccluded * vis.fraction * (1 - vis.fraction) / (vis.measured - 1);
    return vis.fraction * unoccluded;
}

FormFactorMatrix::FormFactorMatrix(size_t n, std::vector<uint64_t> rowStart, std::vector<int32_t> column,
                                   std::vector<float> value)
    : n_(n), endRow_(n), rowStart_(std::move(rowStart)), column_(std::move(column)), value_(std::move(value)) {
    if (rowStart_.size() != n + 1 || column_.size() != value_.size() || rowStart_.back() != value_.size())
        throw Error("FormFactorMatrix: inconsistent sparse rows");
    if (n == 0) rowStart_.clear();
}

void FormFactorMatrix::setMeanRows(std::vector<uint64_t> start, std::vector<int32_t> column, std::vector<float> value) {
    if (start.size() != n_ + 1 || column.size() != value.size() || start.back() != value.size())
        throw Error("FormFactorMatrix: inconsistent mean rows");
    meanStart_ = std::move(start);
    meanColumn_ = std::move(column);
    meanValue_ = std::move(value);
}

FormFactorMatrix::FormFactorMatrix(size_t n, std::vector<size_t> blockStart, int rank)
    : n_(n), blockStart_(std::move(blockStart)) {
    PENUMBRA_CHECK(rank >= 0 && size_t(rank) + 1 < blockStart_.size() && blockStart_.back() == n);
    firstRow_ = blockStart_[size_t(rank)], endRow_ = blockStart_[size_t(rank) + 1];
    values_ = Dense::Zero(Eigen::Index(endRow_ - firstRow_), Eigen::Index(n));
}

int FormFactorMatrix::rowOwner(size_t i) const {
    if (blockStart_.empty()) return 0;
    return int(std::upper_bound(blockStart_.begin(), blockStart_.end(), i) - blockStart_.begin()) - 1;
}

uint64_t FormFactorMatrix::bytes() const {
    const uint64_t mean = uint64_t(meanValue_.size()) * (sizeof(float) + sizeof(int32_t)) +
                          meanStart_.size() * sizeof(uint64_t) + seen.size() * sizeof(float);
    return mean + (isSparse() ? uint64_t(value_.size()) * (sizeof(float) + sizeof(int32_t)) +
                                    rowStart_.size() * sizeof(uint64_t)
                              : uint64_t(endRow_ - firstRow_) * n_ * sizeof(float));
}

float FormFactorMatrix::operator()(size_t i, size_t j) const {
    if (!isSparse()) return values_(Eigen::Index(i - firstRow_), Eigen::Index(j));
    const SparseRow r = sparseRow(i);
    const int32_t* at = std::lower_bound(r.column, r.column + r.count, int32_t(j));
    return at != r.column + r.count && *at == int32_t(j) ? r.value[at - r.column] : 0.0f;
}

FormFactorMatrix FormFactorMatrix::transposed() const {
    PENUMBRA_CHECK(!inRowBlocks());
    std::vector<uint64_t> start(n_ + 1, 0);
    for (size_t i = 0; i < n_; ++i) forEachInRow(i, [&](size_t j, float) { ++start[j + 1]; });
    for (size_t j = 0; j < n_; ++j) start[j + 1] += start[j];
    std::vector<int32_t> column(start.back());
    std::vector<float> value(start.back());
    std::vector<uint64_t> next(start.begin(), start.end() - 1);
    for (size_t i = 0; i < n_; ++i)  // rows in order: each column's entries come out ascending
        forEachInRow(i, [&](size_t j, float f) {
            column[next[j]] = int32_t(i);
            value[next[j]++] = f;
        });
    FormFactorMatrix t(n_, std::move(start), std::move(column), std::move(value));
    t.sampled = sampled;
    t.reciprocal = reciprocal;
    return t;
}

std::vector<size_t> rowBlocksFor(size_t n, int ranks) {
    std::vector<size_t> start;
    for (int r = 0; r <= ranks; ++r) start.push_back(size_t(double(n) * r / ranks));
    start.back() = n;
    return start;
}

double balanceClosedScene(FormFactorMatrix& F, const std::vector<double>& area) {
    const size_t n = F.size();
    const int64_t first = int64_t(F.firstRow()), end = int64_t(F.endRow());
    if (F.isSparse() || !F.reciprocal) throw Error("balanceClosedScene: needs the dense, reciprocal matrix");
    std::vector<double> back(n, 0.0), d(n, 1.0), share(n);
    for (const BackTransfer& t : F.backTransfers) back[size_t(t.from)] += t.areaFactor / area[size_t(t.from)];
    // Every row's landing share under the scaling d (each rank its rows, then shared).
    auto shares = [&] {
        parallelFor(end - first, [&](int64_t b, int64_t e) {
            for (int64_t ii = first + b; ii < first + e; ++ii) {
                const size_t i = size_t(ii);
                const float* row = F.row(i);
                double s = 0;
                for (size_t j = 0; j < n; ++j) s += double(row[j]) * d[j];
                share[i] = d[i] * (s + back[i]);
            }
        });
        shareRowValues(F, share);
        double worst = 0;
        for (size_t i = 0; i < n; ++i) worst = std::max(worst, std::abs(share[i] - 1));
        return worst;
    };
    // Symmetric Sinkhorn: each sweep takes a geometric half step towards every row's target, which
    // from rows within a percent of one converges in a few sweeps.
    for (int sweep = 0; sweep < 200 && shares() > 1e-10; ++sweep)
        for (size_t i = 0; i < n; ++i)
            if (share[i] > 0) d[i] /= std::sqrt(share[i]);
    for (size_t i = F.firstRow(); i < F.endRow(); ++i)
        for (size_t j = 0; j < n; ++j)
            if (const float f = F(i, j); f != 0) F(i, j) = float(d[i] * f * d[j]);
    for (BackTransfer& t : F.backTransfers) t.areaFactor *= d[size_t(t.from)];
    std::fill(d.begin(), d.end(), 1.0);
    return shares();
}

std::string chooseFormFactors(const PatchSet& p, std::string& why) {
    // Pairs whose centroids lie in front of each other's plane, counted until there are too many.
    uint64_t facing = 0;
    for (size_t a = 0; a < p.size() && facing <= kAnalyticFacingPairs; ++a)
        for (size_t b = a + 1; b < p.size(); ++b) {
            const Vec3 d = p.centroid[b] - p.centroid[a];
            facing += p.normal[a].dot(d) > 0 && p.normal[b].dot(d) < 0;
        }
    if (facing <= kAnalyticFacingPairs) {
        why = cat(facing, " patch pairs face each other, few enough for the analytic cubature (at most ",
                  kAnalyticFacingPairs, ")");
        return "analytic";
    }
    why = cat("more than ", kAnalyticFacingPairs,
              " patch pairs face each other: ray casting costs rays in proportion to the patches, the cubature "
              "grows with the pairs");
    return "rays";
}

std::vector<double> rowSums(const FormFactorMatrix& F) {
    std::vector<double> sums(F.size(), 0.0);
    for (size_t i = F.firstRow(); i < F.endRow(); ++i) {
        double s = 0;
        F.forEachInRow(i, [&](size_t, float f) { s += f; });
        sums[i] = s;
    }
    shareRowValues(F, sums);
    return sums;
}

}  // namespace penumbra
