// The form-factor matrix: F(i, j), the fraction of the light leaving patch i's front face that
// arrives at patch j's front face, for all pairs, with Embree-tested visibility. Stored dense,
// row-major, in float: A_i F(i,j) = A_j F(j,i) holds to float rounding because both come from one
// symmetric area factor. Light that reaches a back face (black, absorbing) is kept aside in
// `backTransfers` so the power balance can count it.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "core/cluster.h"
#include "core/error.h"
#include "core/rng.h"
#include "mesh/patches.h"
#include "solver/radiosity/form_factor_kernel.h"
#include "solver/visibility.h"

namespace penumbra {

// Where the form factors keep the rows they have made, so that a killed solve carries on from them
// (io/checkpoint.h holds the file; `solve --resume`). Each castFormFactors or computeFormFactors call
// of a solve is one pass, numbered in order; a pass's rows are packed bytes (ray_form_factors.cpp,
// form_factors.cpp).
class CastCheckpoint {
public:
    virtual ~CastCheckpoint() = default;
    virtual int beginPass() = 0;                               // this pass's number: 0, 1, ...
    virtual const std::string& savedRows(int pass) const = 0;  // empty: none saved
    virtual bool due() const = 0;                              // time to save the rows cast so far
    virtual void save(int pass, std::string rows) = 0;         // the pass's rows so far, atomically
    // Row blocks, where each rank saves its own rows: what this rank saved of the pass (rank 0's are
    // savedRows), whether a save now would write (the leader decides for every rank), and the save
    // of this rank's rows by every rank, into a file of its own.
    virtual const std::string& ownRows(int pass) const { return savedRows(pass); }
    virtual bool writesNow() const { return true; }
    // Writes this rank's bytes of the pass, `head` then `rowBytes` bytes at `rows` (its rows, written
    // from where they are and not kept: a rank's rows are what it has room for once).
    virtual void saveOwn(int pass, const std::string& head, const char* rows, size_t rowBytes) {
        save(pass, head + std::string(rows, rowBytes));
    }
    // Row blocks: the pass's saved bytes read, not kept in memory (the rows are).
    virtual void forget(int pass) { (void)pass; }
};

// A pass saved in row blocks begins with this (saveOwn's head); a pass of the whole matrix's
// blocks does not. A resume of the other kind computes the pass again.
inline constexpr char kRowBlockTag[8] = {'P', 'N', 'B', 'R', 'O', 'W', 'S', '1'};
inline bool isRowBlockPass(const std::string& bytes) {
    return bytes.size() >= sizeof kRowBlockTag && std::memcmp(bytes.data(), kRowBlockTag, sizeof kRowBlockTag) == 0;
}

struct FormFactorSettings {
    CubatureSettings cubature;
    int visibilityRays = 4;  // per pair to decide, as many again to measure (16x where partly visible)
    // auto (chooseFormFactors), rays (ray_form_factors.h) or analytic (cubature and visibility rays).
    std::string method = "auto";
    int raysPerPatch = 144;  // --form-factors rays: rays cast from each patch (then more where objectNoise asks)
    // --form-factors rays: the patches of an object whose mean's estimated relative standard error is
    // above this cast again with more rays (solve.cpp, raysForObjectNoise); 1: never.
    double objectNoise = 0.005;
    // The small sources' columns take no visibility rays from receivers proved in full view of
    // them (solver/shafts.h).
    bool clearShafts = true;
    uint64_t seed = 1;
    CastCheckpoint* checkpoint = nullptr;  // rows kept for a resume (none: not kept)
    // Analytic: empty, the whole matrix on every rank; else rank r holds rows [rowBlocks[r],
    // rowBlocks[r + 1]) alone (a matrix too large for one host: rowBlocksFor).
    std::vector<size_t> rowBlocks;
};

struct BackTransfer {
    int from, to;       // light leaving `from`'s front arrives at `to`'s back
    double areaFactor;  // A_from * F(from -> back of to), m^2
};

class FormFactorMatrix {
public:
    using Dense = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

    // One row of a sparse matrix: `count` entries, columns ascending.
    struct SparseRow {
        const int32_t* column;
        const float* value;
        size_t count;
    };

    FormFactorMatrix() = default;
    // Dense and zero: the analytic matrix, every pair a number.
    explicit FormFactorMatrix(size_t n) : n_(n), endRow_(n), values_(Dense::Zero(Eigen::Index(n), Eigen::Index(n))) {}
    // Dense and zero, in row blocks: rank r holds rows [blockStart[r], blockStart[r + 1]) of n
    // columns, and this one is rank `rank`'s (a matrix too large for one host, under mpirun).
    FormFactorMatrix(size_t n, std::vector<size_t> blockStart, int rank);
    // Sparse rows (compressed, row i's entries at rowStart[i] .. rowStart[i + 1], columns ascending):
    // the ray-cast matrix, whose row holds no more entries than the rays its patch cast.
    FormFactorMatrix(size_t n, std::vector<uint64_t> rowStart, std::vector<int32_t> column, std::vector<float> value);

    size_t size() const { return n_; }
    bool isSparse() const { return !rowStart_.empty(); }
    // Row blocks: this rank holds rows [firstRow(), endRow()) alone; the others are other ranks'.
    bool inRowBlocks() const { return !blockStart_.empty(); }
    size_t firstRow() const { return firstRow_; }
    size_t endRow() const { return endRow_; }
    const std::vector<size_t>& rowBlocks() const { return blockStart_; }
    // The rank holding row i (0 without row blocks).
    int rowOwner(size_t i) const;
    // Entries stored: n^2 dense (the rows held in row blocks), the nonzeros sparse.
    uint64_t entries() const { return isSparse() ? uint64_t(value_.size()) : uint64_t(endRow_ - firstRow_) * n_; }
    uint64_t bytes() const;
    float operator()(size_t i, size_t j) const;
    // Dense matrices only.
    float& operator()(size_t i, size_t j) { return values_(Eigen::Index(i - firstRow_), Eigen::Index(j)); }
    // Row i as contiguous floats (dense matrices only, a row held): the solvers' sweeps walk rows.
    const float* row(size_t i) const { return values_.data() + (i - firstRow_) * n_; }
    SparseRow sparseRow(size_t i) const {
        return {column_.data() + rowStart_[i], value_.data() + rowStart_[i], size_t(rowStart_[i + 1] - rowStart_[i])};
    }
    // f(j, F(i, j)) for every stored entry of row i that is not zero, j ascending.
    template <typename Visit>
    void forEachInRow(size_t i, const Visit& f) const {
        if (isSparse()) {
            const SparseRow r = sparseRow(i);
            for (size_t k = 0; k < r.count; ++k) f(size_t(r.column[k]), r.value[k]);
        } else {
            const float* r = row(i);
            for (size_t j = 0; j < n_; ++j)
                if (r[j] != 0) f(j, r[j]);
        }
    }
    // Multiplies every entry F(i, j) of row i by factor(j), and of its mean row by meanFactor(j).
    template <typename Factor, typename MeanFactor>
    void scaleRow(size_t i, const Factor& factor, const MeanFactor& meanFactor) {
        if (isSparse()) {
            for (uint64_t k = rowStart_[i]; k < rowStart_[i + 1]; ++k) value_[k] *= float(factor(size_t(column_[k])));
            if (i + 1 < meanStart_.size())
                for (uint64_t k = meanStart_[i]; k < meanStart_[i + 1]; ++k)
                    meanValue_[k] *= float(meanFactor(size_t(meanColumn_[k])));
        } else {
            float* r = const_cast<float*>(row(i));
            for (size_t j = 0; j < n_; ++j) r[j] *= float(factor(j));
        }
    }
    // The same matrix with rows and columns swapped, sparse (column access for shooting).
    FormFactorMatrix transposed() const;
    const Dense& dense() const { return values_; }

    std::vector<BackTransfer> backTransfers;
    // Rows estimated by casting rays (ray_form_factors.h): a zero entry may hide a patch that is
    // seen, and reciprocity holds only on average.
    bool sampled = false;
    // A_i F(i, j) = A_j F(j, i) to float rounding: the analytic matrix (balanced or not). Ray-cast
    // rows are not.
    bool reciprocal = true;
    // Ray-cast rows only (else empty): the share of each patch's area that light reaches, less the
    // part covered by a solid resting on it (a block standing on the floor: castFormFactors).
    // Row i then transports the uncovered part alone, so B[i] is the mean over that part.
    std::vector<float> exposed;
    // Ray-cast rows only (else empty): of each patch's uncovered origins, the share whose ray met no
    // back face. Below one, part of the patch is hidden from the rest of the scene, seen from it only
    // through back faces (the floor under a shelf's open plinth): row i is then what the rest of the
    // scene sees of the patch, and meanRow(i) the mean over its whole uncovered part
    // (ray_form_factors.h). Where it is one, row i is both.
    std::vector<float> seen;
    bool hasMeanRow(size_t i) const { return i < seen.size() && seen[i] < 1; }
    // Ray-cast rows only: the variance of each analytic entry (a small source's column, measured by
    // visibility rays) whose measuring rays disagreed, rows ascending. A patch in a penumbra reads its
    // lamp through a few rays; this is that noise, which the rays' own gather does not hold.
    struct EntryVariance {
        int32_t row, column;
        float variance;  // of F(row, column)
    };
    std::vector<EntryVariance> entryVariance;
    SparseRow meanRow(size_t i) const {
        return {meanColumn_.data() + meanStart_[i], meanValue_.data() + meanStart_[i],
                size_t(meanStart_[i + 1] - meanStart_[i])};
    }
    // The mean rows, compressed as the sparse rows are (empty where hasMeanRow is false).
    void setMeanRows(std::vector<uint64_t> start, std::vector<int32_t> column, std::vector<float> value);

private:
    size_t n_ = 0;
    size_t firstRow_ = 0, endRow_ = 0;
    std::vector<size_t> blockStart_;  // row blocks: each rank's first row, and n
    Dense values_;
    std::vector<uint64_t> rowStart_;
    std::vector<int32_t> column_;
    std::vector<float> value_;
    std::vector<uint64_t> meanStart_;
    std::vector<int32_t> meanColumn_;
    std::vector<float> meanValue_;
};

// Per-row values, each rank having computed those of the rows it holds (F.firstRow() to F.endRow()):
// afterwards every rank holds every row's, as one process computes them. Without row blocks, nothing
// to do.
template <typename T>
void shareRowValues(const FormFactorMatrix& F, std::vector<T>& values) {
    static_assert(cluster::kPlainData<T>);
    if (!F.inRowBlocks() || !cluster::distributed()) return;
    const std::vector<size_t>& start = F.rowBlocks();
    const std::vector<std::string> all = cluster::allGather(std::string(
        reinterpret_cast<const char*>(values.data() + F.firstRow()), (F.endRow() - F.firstRow()) * sizeof(T)));
    for (size_t r = 0; r < all.size(); ++r) {
        PENUMBRA_CHECK(all[r].size() == (start[r + 1] - start[r]) * sizeof(T));
        std::memcpy(static_cast<void*>(values.data() + start[r]), all[r].data(), all[r].size());
    }
}

// Row blocks for n rows on `ranks` ranks: equal rows (a dense row is n floats whoever holds it).
std::vector<size_t> rowBlocksFor(size_t n, int ranks);

// Bytes the dense matrix of n patches needs.
inline uint64_t formFactorMatrixBytes(uint64_t n) { return n * n * sizeof(float); }
// Most bytes the ray-cast (sparse) matrix of n patches with `raysPerPatch` rays each can need.
inline uint64_t sparseFormFactorBytes(uint64_t n, uint64_t raysPerPatch) {
    return n * (raysPerPatch * (sizeof(float) + sizeof(int32_t)) + sizeof(uint64_t));
}

// Where the corners of patch b lie relative to patch a's plane (beyond a tolerance, so corners on
// the plane, as along a shared edge, count for neither side).
struct PlaneSides {
    bool front = false, behind = false;
    bool straddles() const { return front && behind; }
};
PlaneSides planeSides(const PatchSet& p, size_t a, size_t b);

// Fraction of the light between patches a and b that nothing blocks: `base` stratified segments
// decide how to measure, then `base` more measure it, or 16 times as many when the first disagree
// (a shadow boundary crosses the pair); each measuring segment is weighted by the kernel between
// its ends, and the strata of a and b are paired in a random order. The mean is the share of the
// form factor that gets through, however narrow the opening. The endpoints are lifted off the faces
// that exchange light: sideA, sideB = +1 front, -1 back. Where a patch straddles the other's plane
// (`clipped`), the segments start on its facing part alone.
struct Visibility {
    double fraction;
    int rays;      // cast, the deciding ones included
    int measured;  // of which the estimate is made
};
// The last few patches that blocked segments to one patch (a lamp), for visibleFraction.
struct Blockers {
    std::array<int, 4> patch{-1, -1, -1, -1};
    int next = 0;  // the slot the next blocker takes
};

// An object that is one convex planar polygon (a wall quad, however it is meshed) as an occluder.
// Two convex patches whose every corner-to-corner segment crosses it, from one side to the other, are
// wholly hidden from each other: any segment between them crosses the plane at a convex combination
// of those crossings (weights alpha_k beta_l (d_k - d_l) >= 0 for signed distances d), so within it.
struct ConvexOccluder {
    Vec3 normal = Vec3::Zero(), u = Vec3::Zero(), v = Vec3::Zero();  // plane and its in-plane axes
    double offset = 0, margin = 0;
    // Its outline's edges in (u, v) as inward unit normals and offsets: (x, y) lies inside when
    // nx x + ny y > c for every edge. Empty: not an occluder.
    std::vector<std::array<double, 3>> edges;
};

// Per object: its outline if all its patches lie in one plane and together make one convex polygon
// (their corners' convex hull has their area), else an empty one.
std::vector<ConvexOccluder> convexOccluders(const PatchSet& patches);

// Whether `o` hides patches i and j wholly from each other (ConvexOccluder).
bool hidesWholly(const ConvexOccluder& o, const PatchSet& patches, size_t i, size_t j);

// With `blockers` (patches that blocked like segments before), each segment is first tested against
// those patches' triangles, as Embree splits them, and traced only if it misses them all; a traced
// segment that is blocked adds its nearest blocker. The answer is the same; rows of patches side by
// side against one lamp beyond a wall (the building's other rooms) cost triangle tests instead of rays.
Visibility visibleFraction(const PatchSet& p, const RayScene& scene, size_t a, size_t b, int sideA, int sideB,
                           bool clipped, int base, uint64_t seed, Stream stream = Stream::Visibility,
                           Blockers* blockers = nullptr);

FormFactorMatrix computeFormFactors(const PatchSet& patches, const RayScene& rays, const FormFactorSettings& settings);

// F(i -> j) from i's front to j's front alone, as computeFormFactors finds it (0 unless each lies in
// front of the other): visibility rays (more where the larger patch is wide for the pair's distance,
// up to 16 times `visibilityRays`), then the kernel's cubature over the smaller patch. `variance`, if
// given, receives the estimate's variance from the spread of its measuring rays (0 where they agree:
// its expectation over the rays is the variance's, whatever the truth). `stream` sets the rays: a
// second estimate of the same pair needs a stream of its own.
// `clear`: the pair's shaft is proved free of occluders (solver/shafts.h): no visibility rays.
double frontFormFactor(const PatchSet& patches, const RayScene& rays, size_t i, size_t j,
                       const FormFactorSettings& settings, Blockers* blockers = nullptr, double* variance = nullptr,
                       Stream stream = Stream::Visibility, bool clear = false);

// How far segment endpoints are lifted off patch i, towards the face that takes part: enough that a
// segment arriving at a grazing angle is not stopped by its own endpoint patch in float precision,
// far below any real gap between surfaces.
double liftDistance(const PatchSet& p, size_t i);

// Whether the segment from + t (to - from), t in (trim, 1 - trim), crosses patch k's triangles as the
// ray scene has them (a quad's 0 1 3 and 2 3 1; Moller and Trumbore).
bool segmentCrossesPatch(const PatchSet& p, size_t k, const Vec3& from, const Vec3& to, double trim);

// What `auto` form factors run on these patches, and why: the analytic cubature while the patch pairs
// that face each other are few enough for it to take well under a second (at most
// kAnalyticFacingPairs: the closed forms' scenes, small meshes), ray casting past that, whose cost
// grows as n rather than n^2.
constexpr uint64_t kAnalyticFacingPairs = 250000;
std::string chooseFormFactors(const PatchSet& patches, std::string& why);

// The row sums sum_j F(i, j) (front faces only), in double.
std::vector<double> rowSums(const FormFactorMatrix& F);

// For a closed scene (sceneClosure: no light leaves it), a reciprocal matrix made to land all of every
// row's light: F(i, j) <- d_i F(i, j) d_j and patch i's back-face transfers times d_i, with d solving
// d_i (sum_j F(i, j) d_j + back_i) = 1 (Sinkhorn's balancing, symmetric so that A_i F(i, j) stays
// A_j F(j, i)). Rows then sum to one, which the furnace needs, and so does every column's power,
// which the power balance needs: scaling rows alone would give the first and lose the second.
// Returns the largest |landing share - 1| left (float rounding, about 1e-7).
double balanceClosedScene(FormFactorMatrix& F, const std::vector<double>& area);

}  // namespace penumbra
