// The radiosity system B = E + diag(rho) (F B + S B) per colour channel, in exitance (W/m^2): F the
// dense form factors between patches, S the sparse transfers through mirrors and glass
// (specular_transport.h). Mirror and glass patches themselves have B = 0: what reaches them is
// passed on by S or absorbed.
#pragma once

#include <vector>

#include "core/math.h"
#include "mesh/patches.h"
#include "mesh/scene.h"
#include "solver/radiosity/form_factors.h"
#include "solver/radiosity/specular_transport.h"

namespace penumbra {

struct RadiositySystem {
    // m^2: where light leaves and lands, the patch's area less any part covered by a solid resting
    // on it (ray-cast form factors find those: FormFactorMatrix::exposed); B is the mean over it.
    std::vector<double> area;
    std::vector<Rgb> reflectance;  // diffuse albedo of the front face
    std::vector<Rgb> emission;     // exitance E = pi L_e of the front face, W/m^2
    std::vector<int> object;       // the scene object of each patch
    std::vector<char> specular;    // 1 for mirror and glass patches
    SpecularTransport transport;   // empty without mirrors and glass

    size_t size() const { return area.size(); }
};

RadiositySystem buildSystem(const Scene& scene, const PatchSet& patches);

// The emitting patches, when they cover less than a tenth of the surface: small bright sources,
// which cosine rays rarely find, whose columns ray-cast form factors take analytically and whose
// direct light the display takes at each vertex (vertex_radiosity.h). Where light comes from
// everywhere (a furnace) the rays find it as well as anything else: none (an empty mask).
std::vector<char> smallSources(const RadiositySystem& system);

// B as three planar arrays, one per channel: the layout the row kernel streams at full vector width.
struct ChannelPlanes {
    std::vector<double> c[3];
    explicit ChannelPlanes(const std::vector<Rgb>& B);
    void set(size_t i, const Rgb& v) { c[0][i] = v[0], c[1][i] = v[1], c[2][i] = v[2]; }
};

// Irradiance sum_j F(i,j) B_j arriving at patch i's front face, W/m^2: one pass over row i for all
// three channels, summed in double (system.cpp: vectorised, and built for AVX2 too, picked at run
// time, so that a sweep keeps pace with the memory that streams the matrix).
Rgb rowIrradiance(const FormFactorMatrix& F, size_t i, const ChannelPlanes& B);

// Irradiance at patch i's front face from all patches, directly and through mirrors and glass
// (`planes` holds the same values as `B`).
inline Rgb irradianceAt(const RadiositySystem& s, const FormFactorMatrix& F, size_t i, const std::vector<Rgb>& B,
                        const ChannelPlanes& planes) {
    return rowIrradiance(F, i, planes) + s.transport.incoming(i, B);
}

// One Gauss-Seidel pass in place: B_i = E_i + rho_i H_i in patch order, each row reading the values
// this pass already updated. Returns the pass's change, sum_i A_i |B_i,new - B_i,old| over the
// emitted power (all channels together): it bounds the relative residual of the new B from above,
// because what is left of row i's equation is rho_i sum_{j > i} F_ij (change of B_j), and the columns
// of A F sum to at most the areas (reciprocity, rows summing to at most one).
double gaussSeidelPass(const RadiositySystem& s, const FormFactorMatrix& F, std::vector<Rgb>& B);

// Irradiance H_i arriving at every front face, W/m^2: what the patch's rows gather, or with `mean`, its
// mean over the patch where part of it is hidden (FormFactorMatrix::seen).
std::vector<Rgb> gatherIrradiance(const RadiositySystem& s, const FormFactorMatrix& F, const std::vector<Rgb>& B,
                                  bool mean = false);

// Each patch's radiosity as the mean over its area, for the solution B: B itself, but where part of a
// patch is hidden from the rest of the scene (FormFactorMatrix::seen), B holds what the rest sees of
// it and the mean is E + rho times its mean row's irradiance.
std::vector<Rgb> meanRadiosity(const RadiositySystem& s, const FormFactorMatrix& F, const std::vector<Rgb>& B);

// Relative residual: sum_i A_i |E_i + rho_i H_i - B_i| over sum_i A_i E_i, all channels together.
// It is the fraction of the emitted power not yet accounted for (the unshot power).
double relativeResidual(const RadiositySystem& system, const std::vector<Rgb>& B, const std::vector<Rgb>& H);

// Where the power goes for a given B: per patch, what it emits and absorbs (front and back), and
// in all what leaves the scene. W per channel.
struct PowerBalance {
    std::vector<Rgb> emitted, absorbed;
    Rgb totalEmitted = Rgb::Zero(), totalAbsorbed = Rgb::Zero(), escaped = Rgb::Zero();
};
PowerBalance powerBalance(const RadiositySystem& system, const FormFactorMatrix& F, const std::vector<Rgb>& B);

}  // namespace penumbra
