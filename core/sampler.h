// Low-discrepancy numbers for the samples of one pixel (or any other item that takes many samples):
// sample `index` draws its decisions in order, dimension by dimension, four dimensions at a time from
// an Owen-scrambled Sobol set of its own per group (core/sobol.h), each group's index shuffled by the
// scramble of its own seed (Burley 2020's padding). Each decision is then stratified over the item's
// samples (a power of two of them: a (t, m, 4)-net per group), the groups are independent of each
// other, and every number is uniform on its own, so estimates stay unbiased. Deterministic for a
// seed, whatever thread draws it. Has the uniform() of Rng, so code templated on its generator
// takes either. Items may share one seed's sets and take aligned runs of its indices (the pixels of
// a tile, render/film.cpp): then any aligned block of items draws a net too.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>

#include "core/rng.h"
#include "core/sobol.h"

namespace penumbra {

class PixelSampler {
public:
    explicit PixelSampler(uint64_t seed) : seed_(seed) {}
    // Begins sample `index` at dimension 0.
    void start(uint32_t index) {
        index_ = index;
        dimension_ = 0;
    }
    // The next dimension's number, in [0, 1).
    double uniform() {
        if (dimension_ % 4 == 0) point_ = group(dimension_ / 4)(index_);
        return point_[dimension_++ % 4];
    }
    // Skips ahead to dimension `d` (a decision that always starts there: a path's bounce), unless
    // this sample is past it already (never backwards: two decisions of one sample never share a
    // number).
    void skipTo(uint32_t d) {
        if (d <= dimension_) return;
        if (d / 4 != dimension_ / 4 || dimension_ % 4 == 0) {
            dimension_ = d;
            if (d % 4 != 0) point_ = group(d / 4)(index_);
        } else {
            dimension_ = d;
        }
    }
    uint32_t dimension() const { return dimension_; }

private:
    // Group g's set, its seeds derived once per item for the first kKept groups (a path's first
    // vertices), not once per sample.
    static constexpr uint32_t kKept = 16;
    ScrambledSobol group(uint32_t g) {
        if (g >= kKept) return ScrambledSobol(mixSeed(seed_, g));
        if (!((made_ >> g) & 1u)) {
            kept_[g] = ScrambledSobol(mixSeed(seed_, g));
            made_ |= 1u << g;
        }
        return kept_[g];
    }
    uint64_t seed_;
    uint32_t made_ = 0;
    std::array<ScrambledSobol, kKept> kept_{};
    uint32_t index_ = 0, dimension_ = 0;
    std::array<double, 4> point_{};
};

}  // namespace penumbra
