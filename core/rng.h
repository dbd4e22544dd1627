// A small counter-seeded generator (PCG32, O'Neill 2014) so each work item (patch pair, pixel,
// photon) draws its own reproducible stream whatever thread runs it.
#pragma once

#include <cstdint>

namespace penumbra {

// Mixes several integers into one 64-bit seed (SplitMix64 finaliser).
inline uint64_t mixSeed(uint64_t a, uint64_t b = 0, uint64_t c = 0) {
    uint64_t z = a * 0x9E3779B97F4A7C15ull ^ (b + 0x632BE59BD9B4E019ull) * 0xBF58476D1CE4E5B9ull ^
                 (c + 0x85EBCA77C2B2AE63ull) * 0x94D049BB133111EBull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

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

}  // namespace penumbra
