// The form-factor matrix: F(i, j), the fraction of the light leaving patch i's front face that
// arrives at patch j's front face, for all pairs, with Embree-tested visibility. Stored dense,
// row-major, in float: A_i F(i,j) = A_j F(j,i) holds to float rounding because both come from one
// symmetric area factor. Light that reaches a back face (black, absorbing) is kept aside in
// `backTransfers` so the power balance can count it.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "core/rng.h"
#include "mesh/patches.h"
#include "solver/radiosity/form_factor_kernel.h"
#include "solver/visibility.h"

namespace penumbra {

struct FormFactorSettings {
    CubatureSettings cubature;
    int visibilityRays = 4;           // per pair; pairs found partly visible get 4x as many
    std::string method = "analytic";  // analytic (cubature and visibility rays) or rays (ray_form_factors.h)
    int raysPerPatch = 1024;          // --form-factors rays: rays cast from each patch
    uint64_t seed = 1;
};

struct BackTransfer {
    int from, to;       // light leaving `from`'s front arrives at `to`'s back
    double areaFactor;  // A_from * F(from -> back of to), m^2
};

class FormFactorMatrix {
public:
    using Dense = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

    FormFactorMatrix() = default;
    explicit FormFactorMatrix(size_t n) : values_(Dense::Zero(Eigen::Index(n), Eigen::Index(n))) {}
    size_t size() const { return size_t(values_.rows()); }
    float operator()(size_t i, size_t j) const { return values_(Eigen::Index(i), Eigen::Index(j)); }
    float& operator()(size_t i, size_t j) { return values_(Eigen::Index(i), Eigen::Index(j)); }
    // Row i as contiguous floats: the solvers' sweeps walk rows.
    const float* row(size_t i) const { return values_.data() + i * size(); }
    const Dense& dense() const { return values_; }

    std::vector<BackTransfer> backTransfers;
    // Rows estimated by casting rays (ray_form_factors.h): a zero entry may hide a patch that is
    // seen, and reciprocity holds only on average.
    bool sampled = false;

private:
    Dense values_;
};

// Bytes the dense matrix of n patches needs.
inline uint64_t formFactorMatrixBytes(uint64_t n) { return n * n * sizeof(float); }

// Where the corners of patch b lie relative to patch a's plane (beyond a tolerance, so corners on
// the plane, as along a shared edge, count for neither side).
struct PlaneSides {
    bool front = false, behind = false;
    bool straddles() const { return front && behind; }
};
PlaneSides planeSides(const PatchSet& p, size_t a, size_t b);

// Fraction of segments between patches a and b that nothing blocks: `base` stratified rays, then
// four times as many when the first ones disagree (a shadow boundary crosses the pair). The
// endpoints are lifted off the faces that exchange light: sideA, sideB = +1 front, -1 back. Where
// a patch straddles the other's plane (`clipped`), the segments start on its facing part alone.
struct Visibility {
    double fraction;
    int rays;
};
Visibility visibleFraction(const PatchSet& p, const RayScene& scene, size_t a, size_t b, int sideA, int sideB,
                           bool clipped, int base, uint64_t seed, Stream stream = Stream::Visibility);

FormFactorMatrix computeFormFactors(const PatchSet& patches, const RayScene& rays, const FormFactorSettings& settings);

// F(i -> j) from i's front to j's front alone, as computeFormFactors finds it (0 unless each lies in
// front of the other): visibility rays, then the kernel's cubature over the smaller patch.
double frontFormFactor(const PatchSet& patches, const RayScene& rays, size_t i, size_t j,
                       const FormFactorSettings& settings);

// The row sums sum_j F(i, j) (front faces only), in double.
std::vector<double> rowSums(const FormFactorMatrix& F);

}  // namespace penumbra
