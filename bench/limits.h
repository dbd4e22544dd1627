// What this machine can do, measured in the same run as the bench so that its speeds can be stated
// as ratios: Embree alone on the scene's own patches (no Penumbra code between the rays), and the
// memory bandwidth that bounds a dense radiosity sweep. The Embree part calls Embree directly
// (embree_limit.cpp): the one place besides solver/visibility that does, by design.
#pragma once

#include <cstddef>
#include <cstdint>

#include "mesh/patches.h"

namespace penumbra::bench {

// Rays per second with the current thread count, each query on the same rays.
struct EmbreeLimit {
    double occluded1 = 0;   // rtcOccluded1: segments between random surface points (form-factor rays)
    double occluded8 = 0;   // the same segments as 8-wide packets (rtcOccluded8)
    double intersect1 = 0;  // rtcIntersect1: cosine rays from random surface points (gather rays)
    uint64_t rays = 0;      // rays in each measurement
    int threads = 0;
};
EmbreeLimit measureEmbreeLimit(const PatchSet& patches, uint64_t rays, uint64_t seed);

// GB/s over a float matrix of n x n: a plain read stream and a plain copy (bytes read + written),
// against the solvers' own sweeps over a matrix of that size (Jacobi with the current threads,
// Gauss-Seidel on one, as it runs), each the best of a few repetitions.
struct BandwidthLimit {
    size_t n = 0;
    double matrixBytes = 0;
    double readGBs = 0, copyGBs = 0;
    double readGBs1 = 0;  // the read stream on one thread: the yardstick of the sequential Gauss-Seidel
    double jacobiGBs = 0, gaussSeidelGBs = 0;
    double jacobiSeconds = 0, gaussSeidelSeconds = 0;  // one sweep
    int threads = 0;
};
BandwidthLimit measureBandwidth(size_t n, uint64_t seed);

}  // namespace penumbra::bench
