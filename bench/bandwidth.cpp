// Memory bandwidth against the solvers' own sweeps over a dense matrix of the same size. The matrix
// holds random form factors (rows summing to 0.9): a sweep's cost does not depend on the values.
#include <algorithm>
#include <cstring>
#include <vector>

#include "bench/limits.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "core/timer.h"
#include "solver/radiosity/system.h"

namespace penumbra::bench {
namespace {

// Best seconds of `body` over `passes` runs.
template <typename Body>
double bestSeconds(int passes, const Body& body) {
    double best = 1e300;
    for (int p = 0; p < passes; ++p) {
        Timer timer;
        body();
        best = std::min(best, timer.seconds());
    }
    return best;
}

}  // namespace

BandwidthLimit measureBandwidth(size_t n, uint64_t seed) {
    BandwidthLimit out;
    out.n = n;
    out.threads = threadCount();
    out.matrixBytes = double(n) * double(n) * sizeof(float);
    FormFactorMatrix F(n);
    parallelFor(
        int64_t(n),
        [&](int64_t b, int64_t e) {
            for (int64_t i = b; i < e; ++i) {
                Rng rng(mixSeed(seed, uint64_t(i)));
                for (size_t j = 0; j < n; ++j) F(size_t(i), j) = float(rng.uniform() * 1.8 / double(n));
            }
        },
        16);
    RadiositySystem s;
    s.area.assign(n, 1.0);
    s.reflectance.assign(n, Rgb(0.7, 0.5, 0.3));
    s.emission.assign(n, Rgb::Zero());
    s.emission[0] = Rgb(1, 1, 1);
    std::vector<Rgb> B(n, Rgb(0.1, 0.2, 0.3));
    const int passes = 3;

    // A plain read of every float (summed, so it cannot be skipped), on all threads.
    std::vector<double> partial(size_t(threadCount()) * 64, 0.0);
    auto readRows = [&](int64_t b, int64_t e) {
        // Eigen's sum keeps several vector accumulators: bound by memory, not by add latency.
        double sum = 0;
        for (int64_t i = b; i < e; ++i)
            sum += Eigen::Map<const Eigen::ArrayXf>(F.row(size_t(i)), Eigen::Index(n)).sum();
        partial[size_t(b) % partial.size()] += sum;
    };
    const double read = bestSeconds(passes, [&] { parallelFor(int64_t(n), readRows, 16); });
    out.readGBs = out.matrixBytes / read / 1e9;
    out.readGBs1 = out.matrixBytes / bestSeconds(passes, [&] { readRows(0, int64_t(n)); }) / 1e9;

    // A plain copy into a second matrix (bytes read plus bytes written), on all threads.
    std::vector<float> copy(n * n);
    const double copied = bestSeconds(passes, [&] {
        parallelFor(
            int64_t(n),
            [&](int64_t b, int64_t e) {
                std::memcpy(copy.data() + size_t(b) * n, F.row(size_t(b)), size_t(e - b) * n * sizeof(float));
            },
            16);
    });
    out.copyGBs = 2 * out.matrixBytes / copied / 1e9;
    std::vector<float>().swap(copy);

    // The solvers' sweeps: Jacobi's gather (all threads) and one Gauss-Seidel pass (in order).
    std::vector<Rgb> H;
    out.jacobiSeconds = bestSeconds(passes, [&] { H = gatherIrradiance(s, F, B); });
    out.jacobiGBs = out.matrixBytes / out.jacobiSeconds / 1e9;
    out.gaussSeidelSeconds = bestSeconds(passes, [&] { gaussSeidelPass(s, F, B); });
    out.gaussSeidelGBs = out.matrixBytes / out.gaussSeidelSeconds / 1e9;
    return out;
}

}  // namespace penumbra::bench
