// The path-traced per-object reference (render/object_reference.h, `penumbra reference`) against
// closed forms, and the default solve against it. The reference states its own noise; each check
// allows four of its standard errors beside the stated bound, and asserts that the noise is as
// small as asked (so a reference too noisy to judge by fails instead of passing everything).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "core/parallel.h"
#include "fixtures.h"
#include "io/report.h"
#include "render/object_reference.h"

using namespace penumbra;

namespace {

std::vector<ObjectEstimate> referenceOf(const Scene& scene, int patches, const ObjectReferenceSettings& settings) {
    MeshingOptions meshing;
    meshing.targetPatches = patches;
    const PatchSet mesh = meshScene(scene, meshing);
    const SceneTracer tracer(scene, mesh);
    return pathObjectRadiosity(tracer, settings);
}

int objectIndex(const Scene& scene, const std::string& name) {
    for (size_t o = 0; o < scene.objects.size(); ++o)
        if (scene.objects[o].name == name) return int(o);
    ADD_FAILURE() << "no object " << name;
    return 0;
}

// Two unit squares facing each other at distance 1: an emitter (E = pi L_e = 1, black) and a
// receiver of reflectance 0.5, alone in the dark. B = 0.5 F with Howell's F = 0.19982 (C-11).
const char* kParallelSquares = R"({
  "materials": {"lamp": {"type": "diffuse", "reflectance": 0, "emission": 0.3183098861837907},
                "grey": {"type": "diffuse", "reflectance": 0.5}},
  "objects": [
    {"name": "lamp", "type": "quad", "material": "lamp", "vertices": [[0,0,1],[0,1,1],[1,1,1],[1,0,1]]},
    {"name": "receiver", "type": "quad", "material": "grey", "vertices": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}]})";

}  // namespace

TEST(ObjectReference, ParallelSquaresGetHowellsFormFactor) {
    const Scene scene = test::sceneFromJson(kParallelSquares);
    ObjectReferenceSettings s;
    s.targetError = 0.002;
    const std::vector<ObjectEstimate> e = referenceOf(scene, 50, s);
    const ObjectEstimate& lamp = e[size_t(objectIndex(scene, "lamp"))];
    const ObjectEstimate& receiver = e[size_t(objectIndex(scene, "receiver"))];
    EXPECT_NEAR(lamp.radiosity[0], 1.0, 1e-12) << "a black emitter's radiosity is its emission, with no noise";
    const double exact = 0.5 * test::parallelRectangles(1, 1, 1);
    EXPECT_LE(receiver.relativeError, 0.002) << "sampled to the target";
    EXPECT_NEAR(receiver.radiosity[1], exact, 4 * receiver.stdError[1] + 1e-4 * exact)
        << "stated standard error " << receiver.stdError[1];
    // The stated noise is the real one: far from zero, not far above the target.
    EXPECT_GT(receiver.relativeError, 0.0005);
}

// The furnace with occluders (two boxes and a sphere in a closed cube, every surface rho, L_e = 1):
// every object's radiosity is pi L_e / (1 - rho), whatever the shadows.
TEST(ObjectReference, FurnaceWithOccludersGivesEOverOneMinusRho) {
    const double rho = 0.9;
    const Scene scene = test::sceneFromJson(test::furnaceWithOccluders(rho));
    ObjectReferenceSettings s;
    s.targetError = test::kSanitized ? 0.01 : 0.003;
    s.minSamples = test::kSanitized ? 2048 : 8192;
    const std::vector<ObjectEstimate> e = referenceOf(scene, 300, s);
    for (size_t o = 0; o < e.size(); ++o) {
        ASSERT_GT(e[o].samples, 0) << scene.objects[o].name;
        EXPECT_LE(e[o].relativeError, s.targetError) << scene.objects[o].name;
        EXPECT_NEAR(e[o].radiosity[0], kPi / (1 - rho), 4 * e[o].stdError[0]) << scene.objects[o].name;
    }
}

TEST(ObjectReference, SameEstimateWhateverTheThreadCount) {
    const Scene scene = test::sceneFromJson(test::furnaceWithOccluders(0.5));
    ObjectReferenceSettings s;
    s.targetError = 0.02;
    s.minSamples = 2048;
    setThreadCount(1);
    const std::vector<ObjectEstimate> one = referenceOf(scene, 100, s);
    setThreadCount(0);
    const std::vector<ObjectEstimate> all = referenceOf(scene, 100, s);
    for (size_t o = 0; o < one.size(); ++o) {
        EXPECT_EQ(one[o].samples, all[o].samples);
        EXPECT_EQ(one[o].radiosity[0], all[o].radiosity[0]) << scene.objects[o].name;
    }
}

// --min-area leaves the small objects out (a large scene's props) and changes nothing of the others:
// each object's points are seeded by the object and the batch, not by what else is sampled.
TEST(ObjectReference, SmallObjectsLeftOutAndTheOthersUnchanged) {
    const Scene scene = test::sceneFromJson(test::furnaceWithOccluders(0.5));
    ObjectReferenceSettings s;
    s.targetError = 0.02;
    s.minSamples = 2048;
    const std::vector<ObjectEstimate> all = referenceOf(scene, 100, s);
    s.minArea = 0.6;  // the cube's faces (1 m^2), not the boxes' or the ball (0.50 m^2)
    const std::vector<ObjectEstimate> large = referenceOf(scene, 100, s);
    int kept = 0;
    for (size_t o = 0; o < all.size(); ++o) {
        if (all[o].area >= 0.6) {
            ++kept;
            EXPECT_EQ(large[o].samples, all[o].samples) << scene.objects[o].name;
            EXPECT_EQ(large[o].radiosity[0], all[o].radiosity[0]) << scene.objects[o].name;
        } else {
            EXPECT_EQ(large[o].samples, 0) << scene.objects[o].name << ", " << all[o].area << " m^2";
        }
    }
    EXPECT_EQ(kept, 6);
}

// The default solve of the Cornell box, object by object, against the path-traced reference at 0.1%
// standard error: the room's surfaces within 1%, the block faces within 2% for now (issue 13 asks
// 1%). Measured at seed 1: worst short_block_2 +1.20%, the face in shadow, whose bottom row sees the
// floor's penumbra in constant patches (+6 to +19% there); 0.87 to 2.17% over seeds 1-4. Before the
// floor's patches under the blocks were counted as covered, the lit faces read -1.3 to -2.6%.
TEST(ObjectReferenceSlow, CornellDefaultsAgainstThePathTracedReference) {
    const Scene scene = test::sceneFromJson(test::sceneFile("cornell-box.json"), "cornell-box.json");
    ObjectReferenceSettings s;
    s.targetError = 0.001;
    const std::vector<ObjectEstimate> ref = referenceOf(scene, 3000, s);
    const SolveResult r = solveScene(scene, SolveOptions{});
    const std::vector<Rgb> solvedMean = objectRadiosity(r, scene.objects.size());
    for (size_t o = 0; o < ref.size(); ++o) {
        const std::string& name = scene.objects[o].name;
        ASSERT_LE(ref[o].relativeError, s.targetError) << name;
        const double solved = solvedMean[o].sum(), reference = ref[o].radiosity.sum();
        const double bound = name.find("block") != std::string::npos ? 0.02 : 0.01;
        EXPECT_NEAR(solved / reference, 1.0, bound + 4 * ref[o].relativeError) << name;
    }
}
