// Scrambled Sobol points: a 4-dimensional low-discrepancy set (Sobol 1967; direction numbers of Joe
// and Kuo 2008 for dimensions 2-4) under Owen's nested uniform scrambling, done by hashing (Burley
// 2020, after Laine and Karras 2011). Any aligned run of 2^m consecutive indices is a (t, m, 4)-net:
// the first two dimensions put exactly one point in every 2^-a x 2^-(m-a) box, and the others are
// stratified almost as well. The scramble keeps that structure and makes each point uniform on its
// own, so an estimate from the points is unbiased; a different seed gives an independent set.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace penumbra {

namespace sobol_detail {

// Direction numbers, 32 bits, of the first four Sobol dimensions.
struct Directions {
    uint32_t v[4][32];
    constexpr Directions() : v{} {
        // Dimension 1 is van der Corput's; the others from primitive polynomials of degree s with
        // coefficients a and initial numbers m (Joe and Kuo's table).
        constexpr int s[4] = {0, 1, 2, 3}, a[4] = {0, 0, 1, 1};
        constexpr uint32_t m0[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 3, 0}, {1, 3, 1}};
        for (int i = 0; i < 32; ++i) v[0][i] = 1u << (31 - i);
        for (int d = 1; d < 4; ++d) {
            uint32_t m[32] = {};
            for (int i = 0; i < 32; ++i) {
                if (i < s[d]) {
                    m[i] = m0[d][i];
                    continue;
                }
                uint32_t x = m[i - s[d]] ^ (m[i - s[d]] << s[d]);
                for (int k = 1; k < s[d]; ++k)
                    if ((a[d] >> (s[d] - 1 - k)) & 1) x ^= m[i - k] << k;
                m[i] = x;
            }
            for (int i = 0; i < 32; ++i) v[d][i] = m[i] << (31 - i);
        }
    }
};

inline constexpr Directions kDirections{};

constexpr uint32_t reverseBits(uint32_t x) {
    x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
    x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
    x = ((x >> 4) & 0x0F0F0F0Fu) | ((x & 0x0F0F0F0Fu) << 4);
    x = ((x >> 8) & 0x00FF00FFu) | ((x & 0x00FF00FFu) << 8);
    return (x >> 16) | (x << 16);
}

// A permutation of the bits in which each bit is flipped as a hash of the bits below it and the seed.
constexpr uint32_t laineKarras(uint32_t x, uint32_t seed) {
    x += seed;
    x ^= x * 0x6c50b47cu;
    x ^= x * 0xb82f1e52u;
    x ^= x * 0xc7afe638u;
    x ^= x * 0x8d22f6e6u;
    return x;
}

// Owen's scramble works on the bits of an index and of a point reversed, and reversal commutes with
// XOR. So per byte of a reversed index and per value of it: the four dimensions' direction numbers
// of its set bits (bit p of the reversed index is bit 31 - p of the index), each reversed, XORed. A
// scrambled point is then four lookups (16 KiB of tables) and half the reversals (ScrambledSobol),
// where a loop over the index's 32 bits was 2.3% of a cornell-glass solve's samples.
struct ReversedTables {
    alignas(16) uint32_t t[4][256][4];
    constexpr ReversedTables() : t{} {
        for (int byte = 0; byte < 4; ++byte)
            for (int value = 0; value < 256; ++value)
                for (int bit = 0; bit < 8; ++bit)
                    if ((value >> bit) & 1)
                        for (int d = 0; d < 4; ++d)
                            t[byte][value][d] ^= reverseBits(kDirections.v[d][31 - (8 * byte + bit)]);
    }
};

inline constexpr ReversedTables kReversedTables{};

}  // namespace sobol_detail

// Owen's nested uniform scramble of a 32-bit fraction: each bit flipped as a hash of the bits above it.
inline uint32_t owenScramble(uint32_t x, uint32_t seed) {
    using namespace sobol_detail;
    return reverseBits(laineKarras(reverseBits(x), seed));
}

// The four dimensions' unscrambled points at `index`: the XOR of the direction numbers of its set
// bits (Sobol's definition, without a branch per bit; ScrambledSobol finds its points by tables).
inline std::array<uint32_t, 4> sobolBits(uint32_t index) {
    std::array<uint32_t, 4> x{};
    for (int i = 0; i < 32; ++i) {
        const uint32_t mask = 0u - ((index >> i) & 1u);
        for (int d = 0; d < 4; ++d) x[std::size_t(d)] ^= sobol_detail::kDirections.v[d][i] & mask;
    }
    return x;
}

// One scrambled Sobol set: point `index` of the set of `seed`, its scrambles' seeds derived once.
// The index is scrambled too (y = reversed index, hashed), then each dimension: the same points as
// owenScramble applied to the index and to sobolBits of it, found from y's bytes in the reversed
// tables without reversing back and forth.
class ScrambledSobol {
public:
    ScrambledSobol() = default;
    explicit ScrambledSobol(uint64_t seed) {
        const uint32_t s0 = uint32_t(seed), s1 = uint32_t(seed >> 32);
        indexSeed_ = s0 * 0x9E3779B9u + 0x7F4A7C15u;
        for (int d = 0; d < 4; ++d)
            dimensionSeed_[std::size_t(d)] =
                sobol_detail::laineKarras(s1 ^ (0x85EBCA6Bu * uint32_t(d + 1)), s0 + uint32_t(d));
    }
    std::array<double, 4> operator()(uint32_t index) const {
        using namespace sobol_detail;
        const uint32_t y = laineKarras(reverseBits(index), indexSeed_);
        std::array<uint32_t, 4> reversed{};
        for (int byte = 0; byte < 4; ++byte) {
            const uint32_t* t = kReversedTables.t[byte][(y >> (8 * byte)) & 0xFFu];
            for (int d = 0; d < 4; ++d) reversed[std::size_t(d)] ^= t[d];
        }
        std::array<double, 4> p{};
        for (int d = 0; d < 4; ++d)
            p[std::size_t(d)] =
                double(reverseBits(laineKarras(reversed[std::size_t(d)], dimensionSeed_[std::size_t(d)]))) *
                (1.0 / 4294967296.0);
        return p;
    }

private:
    uint32_t indexSeed_ = 0;
    std::array<uint32_t, 4> dimensionSeed_{};
};

inline std::array<double, 4> scrambledSobol(uint32_t index, uint64_t seed) { return ScrambledSobol(seed)(index); }

}  // namespace penumbra
