// Mirrors and glass in the radiosity solve: extended form factors (Sillion & Puech 1989, by ray
// tracing). Light leaving a diffuse patch i that first meets a mirror or glass object o is the share
// F(i, o) = sum of F(i, s) over o's patches, which the matrix holds; where that share goes (through
// reflections and refractions, Fresnel chosen at random in proportion, to the front of a diffuse
// patch j; absorbed by a mirror, a glass tint or a back face; out of the scene) is told by light
// paths traced from the mirror's and glass's own surfaces: a point x on o and a direction w out of
// it; the ray from x along w finds the patch i the light comes from (it must see o directly), and
// the light's walk on from x through o finds where it goes. The paths sample the etendue through o
// once for every patch at the same time (per patch, rays from i would mostly miss a small ball:
// 4,096 a patch took 2.2 s on cornell-glass and most found nothing); by reciprocity the share of
// i's light that a path carries is its weight in etendue. Half the directions are aimed at points
// on the lamps, and on the caustics the objects throw (found by a first, small set of paths), in
// proportion to the light each sends into o, from points of a sphere's cap that sees the patch aimed
// at (multiple importance sampling, the balance heuristic): the lamps' light through o is most of
// what o passes on, and a glass ball images the caustic at its foot onto the ceiling. A quarter of a
// ball's paths are traced the other way, from the diffuse objects that see it (each as often as any
// other: a small one is reached as often as a large one), and weighed against the rest by the same
// heuristic. Row i's fates are then scaled to the row's share of o, so the split conserves energy
// exactly and the power balance still closes.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "core/math.h"
#include "mesh/patches.h"
#include "mesh/scene.h"
#include "solver/radiosity/form_factors.h"
#include "solver/tracer.h"

namespace penumbra {

struct SpecularPaths;  // the traced paths (specular_transport.cpp)

struct SpecularSettings {
    // Paths traced from (and back to) the mirrors and glass per patch that sees one. 128 until
    // 2026-12-06; with a quarter traced back from the receivers, cornell-glass at 96 had every object
    // within 1% at 16 of 16 seeds (max 1.00%, objects' rms 0.241%; at 128: max 0.67%, 0.215%), its
    // variants with the floor in quarters and the balls raised 8 of 8 (max 0.67% and 0.91%), for
    // 0.04 s less of the transport (0.11 s against 0.15 s).
    int pathsPerPatch = 96;
    double aimedShare = 0.5;  // of the paths' directions, the share aimed at the lamps
    int maxDepth = 64;        // specular bounces before a chain is counted absorbed
    // Bounces whose every branch (a glass's reflection and refraction) a path follows, before one by
    // Fresnel's odds. Once 1: a glass ball's 4% reflections chosen by their odds were the noise of
    // cornell-glass's ceiling pieces; since the paths aim at caustics from the caps that see them,
    // splitting costs 47% more rays (1.16 M against 0.79 M) for the same stated noise (ceiling_right
    // 0.91% against 0.93%) and the same spread over 16 seeds (objects' rms 0.322% against 0.328%).
    int splitBounces = 0;
    // Paths traced first, as a share of the paths, to find the patches the objects light by a
    // caustic (aimed at too, by that light); 0: the lamps alone are aimed at. (cornell-glass's stated
    // noise is the same from 1/32 to 1/4: 2026-12-05.)
    double causticShare = 1.0 / 32;
    // Of a ball's paths, the share traced the other way: from a point on the patch aimed at, the light
    // that reaches it through the ball followed back to where it came from. Each object that sees the
    // ball is aimed at as often as any other, so a small one is reached by as many paths as a large one
    // (the balance heuristic weighs them against the paths from the balls' surfaces).
    double receiverShare = 0.25;
    uint64_t seed = 1;
};

struct SpecularTransport {
    // Irradiance reaching the front of patch j through mirrors and glass, per unit radiosity of
    // patch i: weight = A_i S(i -> j) / A_j, with S the share of i's light that gets there. Stored
    // by target (for gathering solvers) and by source (for shooting ones).
    std::vector<size_t> inStart;
    std::vector<int> inSource;
    std::vector<Rgb> inWeight;
    std::vector<double> inSquare;  // the paths' noise in inWeight: sum of each one's part squared
    std::vector<size_t> outStart;
    std::vector<int> outTarget;
    std::vector<Rgb> outWeight;
    std::vector<double> outSquare;
    // Shares of patch i's light absorbed on the way (by a mirror, a glass tint or a back face), per
    // object, by source patch.
    std::vector<size_t> lossStart;
    std::vector<int> lossObject;
    std::vector<Rgb> lossShare;

    // Area-weighted share F(i, o) no path found (sent on by the fates of i's object's other rows
    // through o; absorbed by o where there are none).
    double unresolvedShare = 0;
    std::vector<double> rowUnresolved;  // that share per source patch
    double seconds = 0;
    int64_t paths = 0;  // light paths traced from the mirrors' and glass's surfaces
    // The paths, kept: rows cast again scale them to their new shares without tracing again.
    std::shared_ptr<const SpecularPaths> traced;
    // The share F(i, o) each row sends through mirror or glass object o (share[i * groups + o]), and
    // each patch's object (-1 unless a mirror's or glass's): matchSpecularShares makes F agree.
    std::vector<double> share;
    std::vector<int> patchGroup;
    size_t groups = 0;
    // Per row, what its fates were made from (its shares F(i, o), its rays, its exposed part; groups
    // + 2 each): a later call copies the fates of rows whose inputs are the same.
    std::vector<double> rowInputs;

    bool empty() const { return inStart.empty(); }
    // The variance the paths leave in incoming(j, B) (b: the mean of B's channels): a compound Poisson
    // sum over the paths that land on j, each carrying its part of its source's light.
    double incomingVariance(size_t j, const std::vector<Rgb>& B) const {
        if (inStart.empty()) return 0;
        double v = 0;
        for (size_t k = inStart[j]; k < inStart[j + 1]; ++k) {
            const double b = B[size_t(inSource[k])].sum() / 3;
            v += inSquare[k] * b * b;
        }
        return v;
    }
    // sum_i weight(i -> j) B_i, W/m^2.
    Rgb incoming(size_t j, const std::vector<Rgb>& B) const {
        if (inStart.empty()) return Rgb::Zero();
        Rgb h = Rgb::Zero();
        for (size_t k = inStart[j]; k < inStart[j + 1]; ++k) h += inWeight[k] * B[size_t(inSource[k])];
        return h;
    }
};

// Empty when the scene has no mirror or glass. With `previous`, its paths are scaled to the rows of
// F again (rows cast again: castMoreRays) instead of being traced again. With `rowRays`, the rays
// each row of a ray-cast F was cast with, each row's shares F(i, o) are measured again by the paths
// too (SpecularTransport::share; then matchSpecularShares); without, F's are kept.
SpecularTransport computeSpecularTransport(const Scene& scene, const PatchSet& patches, const FormFactorMatrix& F,
                                           const SceneTracer& tracer, const SpecularSettings& settings,
                                           const SpecularTransport* previous = nullptr,
                                           const std::vector<double>& rowRays = {});

// Scales each row of F so that its entries to mirror or glass object o sum to the transport's share
// for it and the rest (with what escapes, one minus the row's sum) to what is left: every row still
// sends all of its light somewhere, exactly.
void matchSpecularShares(FormFactorMatrix& F, const SpecularTransport& transport);

}  // namespace penumbra
