// Mirrors and glass in the radiosity solve: extended form factors (Sillion & Puech 1989, by ray
// tracing). Light leaving a diffuse patch i that first meets a mirror or glass object o is the share
// F(i, o) = sum of F(i, s) over o's patches, which the dense matrix already holds exactly; rays
// from i, cosine-distributed, that meet o first tell where that share goes: through reflections and
// refractions (Fresnel, chosen at random in proportion) to the front of a diffuse patch j, absorbed
// by a mirror or a glass tint, absorbed by a back face, or out of the scene. Each ray's fates sum
// to one, so the split of F(i, o) conserves energy exactly and the power balance still closes.
#pragma once

#include <cstdint>
#include <vector>

#include "core/math.h"
#include "mesh/patches.h"
#include "mesh/scene.h"
#include "solver/radiosity/form_factors.h"
#include "solver/tracer.h"

namespace penumbra {

struct SpecularSettings {
    int raysPerPatch = 4096;  // cosine rays from each patch that sees a mirror or glass
    int maxDepth = 64;        // specular bounces before a chain is counted absorbed
    uint64_t seed = 1;
};

struct SpecularTransport {
    // Irradiance reaching the front of patch j through mirrors and glass, per unit radiosity of
    // patch i: weight = A_i S(i -> j) / A_j, with S the share of i's light that gets there. Stored
    // by target (for gathering solvers) and by source (for shooting ones).
    std::vector<size_t> inStart;
    std::vector<int> inSource;
    std::vector<Rgb> inWeight;
    std::vector<size_t> outStart;
    std::vector<int> outTarget;
    std::vector<Rgb> outWeight;
    // Shares of patch i's light absorbed on the way (by a mirror, a glass tint or a back face), per
    // object, by source patch.
    std::vector<size_t> lossStart;
    std::vector<int> lossObject;
    std::vector<Rgb> lossShare;

    double unresolvedShare = 0;         // area-weighted share F(i, o) no ray found (counted absorbed by o)
    std::vector<double> rowUnresolved;  // that share per source patch
    double seconds = 0;

    bool empty() const { return inStart.empty(); }
    // sum_i weight(i -> j) B_i, W/m^2.
    Rgb incoming(size_t j, const std::vector<Rgb>& B) const {
        if (inStart.empty()) return Rgb::Zero();
        Rgb h = Rgb::Zero();
        for (size_t k = inStart[j]; k < inStart[j + 1]; ++k) h += inWeight[k] * B[size_t(inSource[k])];
        return h;
    }
};

// Empty when the scene has no mirror or glass.
// With `previous` and `only`, the rows i with only[i] > 0 are traced again (their rows of F were cast
// again: castMoreRays) and the others kept from `previous`.
SpecularTransport computeSpecularTransport(const Scene& scene, const PatchSet& patches, const FormFactorMatrix& F,
                                           const SceneTracer& tracer, const SpecularSettings& settings,
                                           const SpecularTransport* previous = nullptr,
                                           const std::vector<int>& only = {});

}  // namespace penumbra
