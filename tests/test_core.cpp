// The core services other tests lean on: named counters (core/counters.h) count exactly, whatever
// the threads, and a solve's report holds the counts its geometry implies.
#include <gtest/gtest.h>

#include <algorithm>

#include "core/counters.h"
#include "core/parallel.h"
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
