// Form factors by ray casting (the transport of stochastic radiosity, Bekaert, Neumann and Sbert;
// Sillion and Puech's ray-traced form factors): from each patch, `raysPerPatch` rays with origins
// stratified over the patch and cosine-distributed directions, each landing on the first surface it
// meets. F(i, j) is the share of i's rays that reach j's front; a back face or the open scene takes
// the rest. Each row sums to one less the escaped and back-face shares *by construction*, so a
// closed scene conserves light exactly whatever the occluders (a uniform furnace stays uniform to
// rounding), and the cost is rays at Embree's rate rather than cubature. The price is noise, per row
// about 1/sqrt(raysPerPatch) of each entry, and no reciprocity. `--form-factors rays`.
//
// Small bright sources are where that noise hurts (a patch's rays rarely find the lamp, and direct
// light is most of what it receives): the columns of the patches marked in `analyticColumns` are
// computed as computeFormFactors does (cubature, visibility rays), and every other fate of the row's
// rays (other patches, back faces, the open scene) is scaled by (1 - analytic share) / (1 - rays'
// share), so that the fates still sum to one.
#pragma once

#include <array>
#include <vector>

#include "solver/radiosity/form_factors.h"

namespace penumbra {

// A patch partly covered by a solid resting on it (the floor under a block that stands across it)
// would otherwise hold the mean over its whole area, the covered part's darkness included, and show
// that to every patch that sees its uncovered part: the block's own face, beside it, read 10-14%
// dark in its bottom row. A ray that meets a back face is followed by five more from its origin,
// along the patch's normal and in four directions 5 degrees above its plane; if all of them meet
// back faces too, the origin lies inside a solid: it is dropped, the row is the mean over the other
// origins, and `exposed` holds their share. Patches that emit (marked in `emitting`) keep every
// origin: what a covered part emits goes into the solid, and their emitted power stays that of
// their whole area.
//
// A patch part of which is hidden from the rest of the scene without being inside a solid (the floor
// under a shelf's plinth, open at its sides, seen from there only through the plinth's back faces)
// holds a dark part and a lit one, and the rest of the scene sees the lit one. If any of its rays met a
// back face, each origin whose ray met a front patch casts a second, independent cosine ray: row i
// is then what the rest of the scene gathers from it, the mean of B weighted by v, the share of a
// point's directions that meet no back face (an origin's light counts where its second ray meets
// none, over the origins whose first ray met none), and the first rays' row is kept as its mean row
// (FormFactorMatrix::meanRow), for what it absorbs and what the report shows. The building's office
// ceilings had read 5-7% dark from their floors' hidden parts: its 147 large surfaces went from a
// median 1.12% to 0.64% off the path-traced reference, 69 to 88 of them within 1%.
//
// The same holds where the dark part is closed by a front face: a wall behind a shelf's back panel
// 1 cm away, the sides of books standing close. Where at least 1 in 8 of a patch's rays land nearer
// than a quarter of the patch's radius, each origin not in a solid tests its patch's normal that far: an
// origin whose normal meets a front face lies in a narrow gap, which the rest of the scene sees only
// through a slit, and it counts as hidden (v = 0) the way an origin behind a back face does. A patch
// wholly in a gap (the panel's face towards the wall) reads what its rays meet within the gap as its
// own light: read as the far side's, it would take the light the room sees of that side (the wall's
// part in the room) into the gap. Rows still sum to one (a furnace stays uniform); the gap's light is
// booked approximately, not exactly, in the power balance. The building's libraries: the wall
// patches half behind the shelves had shown the room their gap's darkness; its 147 large surfaces
// went from 119 to 135 within 1% of the path-traced reference (seed 1; 132-137 over three seeds),
// all 147 within 2%.
//
// Origins and directions are each stratified, and paired by a random permutation per row
// (shuffledStrata, core/rng.h).
//
// Same matrix layout as computeFormFactors (dense rows, back-face transfers), marked `sampled`.
struct HitReadings;
FormFactorMatrix castFormFactors(const PatchSet& patches, const RayScene& rays, const FormFactorSettings& settings,
                                 const std::vector<char>& analyticColumns = {}, const std::vector<char>& emitting = {},
                                 HitReadings* readings = nullptr, const std::vector<int>& raysFor = {});

// A patch's radiosity is its mean, and a ray that lands on it reads that mean wherever it lands. A
// receiver close to the patch sees its near part more than its far part, and where the light bends
// across it (the floor in the short block's shadow, darkest at the block's foot), the receiver reads
// the wrong mean: the short block's front face, seeing little but that floor, read 1.1-1.4% bright at
// the default mesh however many rays it cast (and 4.6% at 2,000 patches).
//
// Given `readings`, castFormFactors notes each ray that lands within 4 radii of the patch it meets,
// and where: readLightWhereRaysLand then makes it read the light at that point, the patch's mean
// plus its slope (least squares over its neighbours' means, in its tangent plane) times the offset,
// the slope limited by the solved B so that no corner of the patch reads farther from its mean than
// its farthest neighbour's mean lies (after Barth and Jespersen), as across a shadow edge. A landing
// point's weight moves between the patch's column and its neighbours'; each row's sum is unchanged,
// so a closed scene still conserves light exactly and a uniform furnace stays uniform, and the slope
// of uniform light is zero. Patches with `specular[j]` (mirrors' and glass's facets, whose light the
// specular transport carries, not B) keep their hits as they are: on cornell-glass their slopes had
// doubled the matrix (382,977 -> 778,047 entries; 552,293 without them) to move shares within each
// ball, changing no object's mean by more than 5e-10.
struct HitReadings {
    // Near hits of one row on one patch: the sum of their weights in the row, and of their weights
    // times their landing points' offsets from the patch's centroid in its tangent frame (metres).
    struct Near {
        int32_t patch;
        float weight, u, v;
    };
    std::vector<std::vector<Near>> rows, meanRows;
    // The same for the hits that landed farther (read only on steep patches: readLightWhereRaysLand).
    std::vector<std::vector<Near>> farRows, farMeanRows;
    // Per patch: its tangent frame; its uncovered part's centroid, offset in it; its neighbours k
    // (start .. start + 1) and their least-squares weights q_k = M^-1 d_k (d_k: the offset of k's
    // centroid, M: the sum of d_k d_k^T), so that the slope is the sum of q_k (B_k - B_j).
    std::vector<Vec3> tangentU, tangentV;
    std::vector<std::array<float, 2>> shift;
    std::vector<uint32_t> start;
    std::vector<int32_t> neighbour;
    std::vector<float> qu, qv;
    Vec3 uncoveredCentroid(const PatchSet& p, size_t i) const;
};
// `reflectance` (per patch): a row's moves are scaled down where they would take rho_i sum_j |F_ij|
// past halfway from rho_i sum_j F_ij to one, the bound under which the solvers converge (without
// it, no bound).
void readLightWhereRaysLand(FormFactorMatrix& F, const PatchSet& patches, const HitReadings& readings,
                            const std::vector<Rgb>& B, const std::vector<char>& specular = {},
                            const std::vector<Rgb>& reflectance = {});

// Casts the rows i with raysFor[i] > 0 again, with that many rays (a stream of their own), in place
// of F's and of their readings, and the slopes again (the uncovered parts are measured anew).
void castMoreRays(FormFactorMatrix& F, HitReadings& readings, const PatchSet& patches, const RayScene& rays,
                  const FormFactorSettings& settings, const std::vector<char>& analyticColumns,
                  const std::vector<char>& emitting, const std::vector<int>& raysFor);

// Whether the scene is closed, by `raysPerPatch` cosine rays from every patch's front face: none may
// leave the scene (`sealed`), and none may meet a back face either (`frontOnly`; a patch partly
// covered by a box resting on it sends rays into the box). In a sealed scene every row of the
// transport, front and back faces together, sums to one, a fact of the geometry; the analytic
// matrix, whose rows sum to one only within its cubature and visibility sampling, is scaled to it, and
// so is the hierarchy where no back face is in sight (its links join front faces only). A furnace at
// rho near one multiplies what is left by 1 / (1 - rho). A ray that slips through a crack between
// patches finds the scene open, and then nothing is scaled.
struct Closure {
    bool sealed = false, frontOnly = false;
};
Closure sceneClosure(const PatchSet& patches, const RayScene& rays, int raysPerPatch, uint64_t seed);

}  // namespace penumbra
