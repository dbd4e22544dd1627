// The core services other tests lean on: named counters (core/counters.h) count exactly, whatever
// the threads, and a solve's report holds the counts its geometry implies; the scrambled Sobol
// points (core/sobol.h) are a net and unbiased.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "core/counters.h"
#include "core/cumulative.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "core/sobol.h"
#include "fixtures.h"

using namespace penumbra;

namespace {
const Counter g_testItems("test.items", "items counted by the counter test");
}  // namespace

TEST(Counters, SumEveryThreadsCountsExactly) {
    for (int threads : {1, 0}) {
        setThreadCount(threads);
        const CounterValues before = counterValues();
        parallelFor(100000, [](int64_t b, int64_t e) {
            for (int64_t k = b; k < e; ++k) g_testItems.add(uint64_t(k % 3));
        });
        // sum over k < 100000 of k mod 3: 33333 ones and 33333 twos.
        EXPECT_EQ(countersSince(before).at("test.items"), 99999u) << threads << " threads";
    }
    setThreadCount(0);
    EXPECT_EQ(counterDescription("test.items"), "items counted by the counter test");
    EXPECT_TRUE(counterDescription("no.such.counter").empty());
}

TEST(Counters, ASolveCountsWhatItsGeometryImplies) {
    // Two parallel unit squares facing each other at distance 1, each meshed into k patches: every
    // patch of one faces every patch of the other and none of its own (k^2 facing pairs), nothing
    // stands between them (no pair occluded or partly visible, so each pair casts exactly the
    // visibility rays asked for twice: a set that decides how to sample, then the set that measures),
    // and one ray scene serves the solve.
    const std::string json = R"({"materials": {"m": {"type": "diffuse", "reflectance": 0.5, "emission": 1}},
      "objects": [
        {"name": "a", "type": "quad", "material": "m", "vertices": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]},
        {"name": "b", "type": "quad", "material": "m", "vertices": [[0,0,1],[0,1,1],[1,1,1],[1,0,1]]}]})";
    SolveOptions o;
    o.meshing.targetPatches = 32;
    o.formFactors.visibilityRays = 4;
    const SolveResult r = solveScene(test::sceneFromJson(json), o);
    const uint64_t k = r.patches.size() / 2;
    ASSERT_EQ(2 * k, r.patches.size());
    EXPECT_EQ(r.counters.at("form_factors.facing_pairs"), k * k);
    EXPECT_EQ(r.counters.at("form_factors.occluded_pairs"), 0u);
    EXPECT_EQ(r.counters.at("form_factors.partly_visible_pairs"), 0u);
    EXPECT_EQ(r.counters.at("form_factors.visibility_rays"), 2 * 4 * k * k);
    EXPECT_EQ(r.counters.at("rays.scenes_built"), 1u);
    EXPECT_EQ(r.counters.at("specular.rays"), 0u) << "no mirrors or glass";
    EXPECT_GE(r.counters.at("rays.occlusion"), r.counters.at("form_factors.visibility_rays"));
}

// A pick through the guide table is the entry a binary search over the whole table finds, on tables
// with empty entries (zero weight), runs of them, one entry, and numbers on the cells' edges.
TEST(CumulativeTable, PicksTheEntryABinarySearchFinds) {
    Rng rng(11);
    for (int table = 0; table < 200; ++table) {
        const size_t n = table == 0 ? 1 : 1 + rng.next() % (table < 100 ? 9 : 3000);
        std::vector<double> cdf;
        double total = 0;
        for (size_t k = 0; k < n; ++k) cdf.push_back(total += rng.uniform() < 0.3 ? 0.0 : rng.uniform());
        if (!(total > 0)) continue;
        for (double& c : cdf) c /= total;
        cdf.back() = 1;
        const CumulativeTable t(cdf);
        std::vector<double> us = {0.0, 1.0, std::nextafter(1.0, 0.0)};
        for (int k = 0; k < 64; ++k) us.push_back(double(k) / 64);
        for (double c : cdf) us.push_back(c), us.push_back(std::nextafter(c, 0.0));
        for (int k = 0; k < 1000; ++k) us.push_back(rng.uniform());
        for (double u : us) {
            const size_t want = std::min(size_t(std::lower_bound(cdf.begin(), cdf.end(), u) - cdf.begin()), n - 1);
            double within = -1;
            ASSERT_EQ(t.pick(u, within), want) << "table " << table << " of " << n << ", u " << u;
            EXPECT_GE(within, 0);
            EXPECT_LE(within, 1);
        }
    }
}

// Sobol's first two dimensions are a (0, 2)-sequence: any aligned run of 2^m points puts exactly one
// in every box of 2^-a by 2^-(m-a), and each dimension alone one in every 2^-m interval. Owen's
// scramble and the shuffled index must keep that (a wrong direction number or a scramble that is
// not nested breaks it).
TEST(Sobol, AnAlignedRunIsANet) {
    constexpr int kM = 10, kN = 1 << kM;
    for (uint64_t seed : {1ull, 77ull}) {
        for (uint32_t run : {0u, 3u}) {
            std::vector<std::array<double, 4>> p;
            for (uint32_t i = 0; i < kN; ++i) p.push_back(scrambledSobol(run * kN + i, seed));
            for (int a = 0; a <= kM; ++a) {
                std::vector<int> box(kN, 0);
                for (const auto& q : p)
                    ++box[size_t(int(q[0] * (1 << a)) * (1 << (kM - a)) + int(q[1] * (1 << (kM - a))))];
                EXPECT_EQ(*std::max_element(box.begin(), box.end()), 1) << "seed " << seed << ", boxes 2^-" << a;
            }
            for (int d = 0; d < 4; ++d) {
                std::vector<int> cell(kN, 0);
                for (const auto& q : p) ++cell[size_t(q[size_t(d)] * kN)];
                EXPECT_EQ(*std::max_element(cell.begin(), cell.end()), 1) << "dimension " << d;
            }
        }
    }
}

// A scrambled point found through the reversed tables is Owen's scramble, as defined, of the
// unscrambled point at the scrambled index.
TEST(Sobol, ScrambledPointsAreOwensScrambleOfTheDefinition) {
    Rng rng(5);
    for (uint64_t seed : {1ull, 0x9E3779B97F4A7C15ull, 77ull}) {
        const ScrambledSobol set(seed);
        const uint32_t s0 = uint32_t(seed), s1 = uint32_t(seed >> 32);
        for (int k = 0; k < 20000; ++k) {
            const uint32_t index = k < 4096 ? uint32_t(k) : uint32_t(rng.next());
            const std::array<uint32_t, 4> bits = sobolBits(owenScramble(index, s0 * 0x9E3779B9u + 0x7F4A7C15u));
            const std::array<double, 4> p = set(index);
            for (int d = 0; d < 4; ++d) {
                const uint32_t dimensionSeed =
                    sobol_detail::laineKarras(s1 ^ (0x85EBCA6Bu * uint32_t(d + 1)), s0 + uint32_t(d));
                ASSERT_EQ(p[size_t(d)], double(owenScramble(bits[size_t(d)], dimensionSeed)) / 4294967296.0)
                    << "index " << index << ", dimension " << d;
            }
        }
    }
}

// Each scrambled point is uniform on its own, so a mean over the points is unbiased; and the set
// stratifies a discontinuous integrand far better than independent points. The share of [0, 1)^4 in
// which (x - 1/2)^2 + (y - 1/2)^2 < 1/9 in dimensions 2 and 3 and x < 0.6 in dimension 0 is
// 0.6 * pi / 9; over 256 seeds of 1,024 points the mean must hold it within 4 standard errors, and
// the spread be under 0.4 of the binomial spread of independent points (measured: 0.24).
TEST(Sobol, ScrambledPointsEstimateAnAreaWithoutBiasAndWithLessNoise) {
    constexpr int kN = 1024, kSeeds = 256;
    const double truth = 0.6 * kPi / 9;
    double sum = 0, square = 0;
    for (int s = 0; s < kSeeds; ++s) {
        int in = 0;
        for (uint32_t i = 0; i < kN; ++i) {
            const auto q = scrambledSobol(i, mixSeed(uint64_t(s), 5));
            in += q[0] < 0.6 && (q[2] - 0.5) * (q[2] - 0.5) + (q[3] - 0.5) * (q[3] - 0.5) < 1.0 / 9;
        }
        const double e = double(in) / kN;
        sum += e;
        square += e * e;
    }
    const double mean = sum / kSeeds, sd = std::sqrt(std::max(0.0, square / kSeeds - mean * mean));
    const double binomial = std::sqrt(truth * (1 - truth) / kN);
    EXPECT_GT(sd, 0) << "every seed gave the same points";
    EXPECT_NEAR(mean, truth, 4 * sd / std::sqrt(double(kSeeds)));
    EXPECT_LT(sd, 0.4 * binomial) << "spread " << sd << " against " << binomial << " for independent points";
}
