// A small counter-seeded generator (PCG32, O'Neill 2014) so each work item (patch pair, pixel,
// photon) draws its own reproducible stream whatever thread runs it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace penumbra {

// Mixes several integers into one 64-bit seed (SplitMix64 finaliser).
inline uint64_t mixSeed(uint64_t a, uint64_t b = 0, uint64_t c = 0) {
    uint64_t z = a * 0x9E3779B97F4A7C15ull ^ (b + 0x632BE59BD9B4E019ull) * 0xBF58476D1CE4E5B9ull ^
                 (c + 0x85EBCA77C2B2AE63ull) * 0x94D049BB133111EBull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

// The program's random streams, one per purpose, so that no two purposes draw the same numbers for
// one seed and work item; every generator is made through one of them (streamRng, pairRng).
enum class Stream : uint64_t {
    Visibility = 1,              // form-factor visibility rays of a patch pair
    BackVisibility = 2,          // the rays to the back part of a straddling pair
    VisibilityAgain = 4,         // a pair's visibility measured again with more rays (castMoreRays)
    Pixels = 3,                  // a pixel's camera samples (pairRng: row, column)
    EdgePixels = 0xED6E,         // an edge pixel's samples on a finer grid (pairRng: row, column)
    SpecularTransport = 0x5bec,  // the solve's rays through mirrors and glass, per patch
    Photons = 0x9407,            // caustic photons, per photon
    EscapeRays = 0xe5ca9e,       // rays counting the escaped power, per patch
    CausticRegion = 0xca057,     // emitter samples that find the caustic region, per pixel
    BenchReference = 0x5EF,      // the bench's path-traced reference image
    CastFormFactors = 0xCA57,    // ray-cast form factors, per patch
    CastMore = 0xCA58,           // ray-cast form factors cast again with more rays, per patch
    Closure = 0xC105ED,          // the rays that test whether the scene is closed, per patch
    ObjectReference = 0x0B1EC7,  // the path-traced per-object radiosity (pairRng: object, batch)
    CausticGrading = 0xCA0571,   // photons that find where caustics fall, for the mesh (per block)
    PhotonAim = 0xA1A1,          // emitter points that size the aimed photon pass
    LightPaths = 0x119A7,        // the path tracer's light paths to the camera, per path
};

class Rng {
public:
    explicit Rng(uint64_t seed, uint64_t stream = 0) {
        inc_ = (stream << 1u) | 1u;
        state_ = 0;
        next();
        state_ += seed;
        next();
    }
    uint32_t next() {
        const uint64_t old = state_;
        state_ = old * 6364136223846793005ull + inc_;
        const uint32_t xorshifted = uint32_t(((old >> 18u) ^ old) >> 27u);
        const uint32_t rot = uint32_t(old >> 59u);
        return (xorshifted >> rot) | (xorshifted << ((-rot) & 31));
    }
    // Uniform in [0, 1).
    double uniform() { return next() * (1.0 / 4294967296.0); }

private:
    uint64_t state_, inc_;
};

// The generator of work item `item` in stream `s`.
inline Rng streamRng(uint64_t seed, Stream s, uint64_t item) { return Rng(mixSeed(seed, uint64_t(s), item)); }
// The generator of a pair of work items (patches a, b; a pixel's row and column).
inline Rng pairRng(uint64_t seed, Stream s, uint64_t a, uint64_t b) {
    return Rng(mixSeed(mixSeed(seed, uint64_t(s)), a, b));
}
// The stream's seed, for code that takes a seed and makes its own generators.
inline uint64_t streamSeed(uint64_t seed, Stream s) { return mixSeed(seed, uint64_t(s)); }

// The side of the smallest square grid of strata holding at least `count` samples (1 for count <= 1).
inline int stratumSide(int count) {
    int side = 1;
    while (side * side < count) ++side;
    return side;
}

// The strata 0 .. count-1 in a random order (Fisher-Yates): stratum k of a sample's first part paired
// with order[k] of its second, each part stratified and the pairing unbiased. A fixed permutation
// (k m + 3 mod count, used until 2026-12-05) pairs the same strata every time, which biases any integrand whose two
// parts interact, as a point's visibility depends on where it is and where it looks: under a low roof it read 1.2% too
// few rays meeting the roof, whatever the seed, and the Cornell box's face in the short block's shadow +2.1% (over six
// seeds; +0.6% over eight with this order). The same fixed permutation shifted at random per row was no better there
// (+2.3%).
inline void shuffledStrata(std::vector<int>& order, int count, Rng& rng) {
    using std::size_t;
    order.resize(size_t(count));
    for (int k = 0; k < count; ++k) order[size_t(k)] = k;
    for (int k = count - 1; k > 0; --k) std::swap(order[size_t(k)], order[size_t(rng.next() % uint32_t(k + 1))]);
}

}  // namespace penumbra
