// Scene loading and meshing: transforms against hand-computed positions, every mesh format read
// through OpenMesh (each checked with a white furnace), spheres' area and orientation, patch
// counts, and display interpolation that stays within one object and one side of a crease.
#include <gtest/gtest.h>

#include <cmath>

#include "fixtures.h"

using namespace penumbra;

namespace {

// The unit cube's corners and its six faces, wound to face inwards.
const double kCorner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
const int kFaces[6][4] = {{0, 4, 5, 1}, {3, 2, 6, 7}, {0, 3, 7, 4}, {1, 5, 6, 2}, {4, 7, 6, 5}, {0, 1, 2, 3}};

std::string cubeObj() {
    std::string s;
    for (const auto& v : kCorner) s += cat("v ", v[0], " ", v[1], " ", v[2], "\n");
    for (const auto& f : kFaces) s += cat("f ", f[0] + 1, " ", f[1] + 1, " ", f[2] + 1, " ", f[3] + 1, "\n");
    return s;
}
std::string cubeOff() {
    std::string s = "OFF\n8 6 0\n";
    for (const auto& v : kCorner) s += cat(v[0], " ", v[1], " ", v[2], "\n");
    for (const auto& f : kFaces) s += cat("4 ", f[0], " ", f[1], " ", f[2], " ", f[3], "\n");
    return s;
}
std::string cubePly() {
    std::string s =
        "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 6\nproperty list uchar int vertex_indices\nend_header\n";
    for (const auto& v : kCorner) s += cat(v[0], " ", v[1], " ", v[2], "\n");
    for (const auto& f : kFaces) s += cat("4 ", f[0], " ", f[1], " ", f[2], " ", f[3], "\n");
    return s;
}
std::string cubeStl() {
    std::string s = "solid cube\n";
    for (const auto& f : kFaces)
        for (int t = 0; t < 2; ++t) {
            const int tri[3] = {f[0], f[1 + t], f[2 + t]};
            s += "facet normal 0 0 0\nouter loop\n";
            for (int k : tri) s += cat("vertex ", kCorner[k][0], " ", kCorner[k][1], " ", kCorner[k][2], "\n");
            s += "endloop\nendfacet\n";
        }
    return s + "endsolid cube\n";
}

}  // namespace

TEST(SceneLoading, TransformAppliesScaleThenRotationsThenTranslation) {
    const Scene scene =
        test::sceneFromJson(R"({"unit_scale": 0.5, "materials": {"m": {"type": "diffuse", "reflectance": 0.5}},
      "objects": [{"name": "t", "type": "triangle", "material": "m", "vertices": [[1,0,0],[0,1,0],[0,0,1]],
                   "transform": {"scale": [2, 3, 4], "rotate_deg": [90, 0, 90], "translate": [10, 20, 30]}}]})");
    // (1,0,0) -scale-> (2,0,0) -rotx 90-> (2,0,0) -rotz 90-> (0,2,0) -translate-> (10,22,30), then x 0.5.
    // (0,1,0) -> (0,3,0) -rotx-> (0,0,3) -rotz-> (0,0,3) -> (10,20,33).
    // (0,0,1) -> (0,0,4) -rotx-> (0,-4,0) -rotz-> (4,0,0) -> (14,20,30).
    const auto& v = scene.objects[0].vertices;
    EXPECT_LT((v[0] - 0.5 * Vec3(10, 22, 30)).norm(), 1e-12);
    EXPECT_LT((v[1] - 0.5 * Vec3(10, 20, 33)).norm(), 1e-12);
    EXPECT_LT((v[2] - 0.5 * Vec3(14, 20, 30)).norm(), 1e-12);
}

TEST(SceneLoading, NearlyPlanarQuadWithinOnePercentIsAccepted) {
    EXPECT_NO_THROW(test::sceneFromJson(R"({"materials": {"m": {"type": "diffuse", "reflectance": 0.5}},
      "objects": [{"name": "q", "type": "quad", "material": "m", "vertices": [[0,0,0],[1,0,0],[1,1,0.009],[0,1,0]]}]})"));
}

TEST(SceneLoading, CommentsAndUnderscoreKeysAreIgnored) {
    EXPECT_NO_THROW(test::sceneFromJson(
        R"({"comment": "x", "_note": 1, "materials": {"_m": 3, "m": {"type": "diffuse", "reflectance": 0.5, "comment": "grey"}},
      "objects": [{"name": "q", "_tag": [], "type": "quad", "material": "m", "vertices": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}]})"));
}

class MeshFormats : public ::testing::TestWithParam<std::string> {};

TEST_P(MeshFormats, ClosedCubeMeshIsAWhiteFurnace) {
    const std::string ext = GetParam();
    const std::string text = ext == "obj" ? cubeObj() : ext == "off" ? cubeOff() : ext == "ply" ? cubePly() : cubeStl();
    test::writeText("cube." + ext, text);
    const Scene scene =
        test::sceneFromJson(cat(R"({"materials": {"m": {"type": "diffuse", "reflectance": 0.9, "emission": 1}},
      "objects": [{"name": "cube", "type": "mesh", "material": "m", "file": "cube.)",
                                ext, R"("}]})"),
                            "mesh-" + ext + ".json");
    SolveOptions o;
    o.meshing.targetPatches = 100;
    const SolveResult r = solveScene(scene, o);
    double area = 0;
    for (double a : r.patches.area) area += a;
    EXPECT_NEAR(area, 6.0, 1e-9);
    const double expected = kPi / (1 - 0.9);
    for (size_t i = 0; i < r.patches.size(); ++i) ASSERT_NEAR(r.solution.B[i][0], expected, 0.005 * expected) << ext;
}

INSTANTIATE_TEST_SUITE_P(Readers, MeshFormats, ::testing::Values("obj", "off", "ply", "stl"));

TEST(Meshing, PatchCountFollowsTheTarget) {
    const Scene scene = test::sceneFromJson(test::closedCube(R"({"type": "diffuse", "reflectance": 0.5})"));
    for (int target : {6, 100, 1000}) {
        MeshingOptions o;
        o.targetPatches = target;
        o.patchesPerObject = 0;  // as an explicit --patches sets it
        const size_t n = meshScene(scene, o).size();
        EXPECT_GE(double(n), 0.8 * target);
        EXPECT_LE(double(n), 1.6 * target);
    }
}

// A 10 x 10 m floor (object 0) under 2,000 tiles of 5 x 5 cm at `height` above it (a library's books).
Scene floorUnderTiles(double height) {
    std::string objects = R"({"name": "floor", "type": "quad", "material": "m",
        "vertices": [[0, 0, 0], [0, 0, 10], [10, 0, 10], [10, 0, 0]]})";
    const std::string y = cat(", ", height, ", ");
    for (int k = 0; k < 2000; ++k) {
        const double x = 0.1 + 0.2 * (k % 45), z = 0.1 + 0.2 * (k / 45);
        objects += cat(R"(, {"name": "tile)", k, R"(", "type": "quad", "material": "m", "vertices": [[)", x, y, z,
                       "], [", x, y, z + 0.05, "], [", x + 0.05, y, z + 0.05, "], [", x + 0.05, y, z, "]]}");
    }
    return test::sceneFromJson(R"({"materials": {"m": {"type": "diffuse", "reflectance": 0.5}},
        "objects": [)" + objects +
                               "]}");
}

TEST(Meshing, ManySmallObjectsLeaveTheLargeSurfacesTheirShare) {
    // The floor under tiles 0.5 m up: at 3,000 patches in all the tiles would take two thirds and the
    // floor be meshed at 18 cm; the default's floor (four per object) asks 8,004, and the floor's
    // share of the area gets its share of them.
    const Scene scene = floorUnderTiles(0.5);
    MeshingOptions o;
    const double asked = MeshingOptions().patchesPerObject * 2001.0;
    EXPECT_EQ(patchTarget(scene, o), int(asked));
    const PatchSet p = meshScene(scene, o);
    const double area = 100 + 2000 * 0.0025, floorShare = 100 / area;
    const auto floorPatches = double(std::count(p.object.begin(), p.object.end(), 0));
    EXPECT_NEAR(floorPatches, floorShare * asked, 0.1 * floorShare * asked);
    o.patchesPerObject = 0;
    EXPECT_EQ(patchTarget(scene, o), 3000);
}

// The same floor with the tiles 1 cm above it, solved with the defaults: contact grading splits the
// floor under the tiles, and the many-object default keeps the floor's uniform mesh at its share of
// the 8,004 asked instead of coarsening it until the graded total is back near 8,004 (the building's
// large surfaces went from 0.37 m to 0.74 m that way), and casts 64 rays a patch; an explicit ray
// count (manyObjectsRays 0, as --ff-rays given) holds.
TEST(Meshing, ManyObjectsGradeOnTopOfTheLargeSurfacesShare) {
    const Scene scene = floorUnderTiles(0.01);
    SolveOptions o;
    o.solver = "gauss-seidel";
    o.formFactors.method = "rays";
    o.vertexRadiosity = "average";
    const SolveResult r = solveScene(scene, o);
    EXPECT_EQ(r.options.formFactors.raysPerPatch, 64);
    const double asked = MeshingOptions().patchesPerObject * 2001.0;
    EXPECT_GT(double(r.patches.size()), 1.1 * asked) << "grading added patches (which the count had taken back)";
    const double area = 100 + 2000 * 0.0025, floorShare = 100 / area;
    double floorArea = 0, floorPatches = 0;
    for (size_t i = 0; i < r.patches.size(); ++i)
        if (r.patches.object[i] == 0) floorArea += r.patches.area[i], ++floorPatches;
    EXPECT_NEAR(floorArea, 100, 1e-6);
    EXPECT_GE(floorPatches, 0.9 * floorShare * asked) << "the floor's uniform share, and its graded patches on top";
    o.manyObjectsRays = 0;
    o.grading.levels = 0;
    EXPECT_EQ(solveScene(scene, o).options.formFactors.raysPerPatch, 144);
}

TEST(Meshing, MirroredSphereStillFacesOutward) {
    // scale -1 on x mirrors the sphere: its facets must still face away from its centre.
    const Scene scene = test::sceneFromJson(R"({"materials": {"m": {"type": "diffuse", "reflectance": 0.5}},
      "objects": [{"name": "s", "type": "sphere", "material": "m", "center": [1, 2, 3], "radius": 0.5,
                   "transform": {"scale": [-1, 1, 1]}}]})");
    MeshingOptions o;
    o.targetPatches = 200;
    const PatchSet p = meshScene(scene, o);
    const Vec3 centre(-1, 2, 3);
    for (size_t i = 0; i < p.size(); ++i) ASSERT_GT(p.normal[i].dot(p.centroid[i] - centre), 0) << "patch " << i;
}

TEST(Meshing, SphereFacesOutwardAndKeepsItsArea) {
    // A glowing sphere inside a black closed cube: every bit of its light reaches the cube (its
    // rows sum to 1), none returns, and its facets' area is close to 4 pi r^2.
    const std::string json = R"({"materials": {"black": {"type": "diffuse", "reflectance": 0},
                                              "glow": {"type": "diffuse", "reflectance": 0, "emission": 1}},
      "objects": [
        {"name": "ball", "type": "sphere", "material": "glow", "center": [0.5, 0.5, 0.5], "radius": 0.2},
        {"name": "bottom", "type": "quad", "material": "black", "vertices": [[0,0,0],[0,0,1],[1,0,1],[1,0,0]]},
        {"name": "top",    "type": "quad", "material": "black", "vertices": [[0,1,0],[1,1,0],[1,1,1],[0,1,1]]},
        {"name": "left",   "type": "quad", "material": "black", "vertices": [[0,0,0],[0,1,0],[0,1,1],[0,0,1]]},
        {"name": "right",  "type": "quad", "material": "black", "vertices": [[1,0,0],[1,0,1],[1,1,1],[1,1,0]]},
        {"name": "back",   "type": "quad", "material": "black", "vertices": [[0,0,1],[0,1,1],[1,1,1],[1,0,1]]},
        {"name": "front",  "type": "quad", "material": "black", "vertices": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}]})";
    SolveOptions o;
    o.meshing.targetPatches = 500;
    const SolveResult r = solveScene(test::sceneFromJson(json), o);
    const std::vector<double> rows = rowSums(r.F);
    double sphereArea = 0;
    for (size_t i = 0; i < r.patches.size(); ++i)
        if (r.patches.object[i] == 0) {
            sphereArea += r.patches.area[i];
            ASSERT_NEAR(rows[i], 1.0, 1e-4) << "sphere patch " << i;
        }
    EXPECT_NEAR(sphereArea, 4 * kPi * 0.04, 0.02 * 4 * kPi * 0.04);
    EXPECT_NEAR(r.power.escaped[0], 0.0, 1e-4 * r.power.totalEmitted[0]);
    EXPECT_NEAR(r.power.totalAbsorbed[0], r.power.totalEmitted[0], 1e-4 * r.power.totalEmitted[0]);
}

TEST(Meshing, DisplayInterpolationStaysWithinObjectsAndCreases) {
    // Two touching quads (different objects), and a folded mesh (a crease): corner values only
    // average patches of the same object on the same side of a crease.
    test::writeText("fold.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 1 1\nv 1 1 1\nf 1 2 3 4\nf 4 3 6 5\n");
    const Scene scene = test::sceneFromJson(R"({"materials": {"m": {"type": "diffuse", "reflectance": 0.5}},
      "objects": [
        {"name": "a", "type": "quad", "material": "m", "vertices": [[2,0,0],[3,0,0],[3,1,0],[2,1,0]]},
        {"name": "b", "type": "quad", "material": "m", "vertices": [[3,0,0],[4,0,0],[4,1,0],[3,1,0]]},
        {"name": "fold", "type": "mesh", "material": "m", "file": "fold.obj"}]})");
    MeshingOptions o;
    o.patchSize = 0.25;
    const PatchSet p = meshScene(scene, o);
    std::vector<Rgb> value(p.size());
    for (size_t i = 0; i < p.size(); ++i) {
        const bool foldUpper = p.object[i] == 2 && p.normal[i].y() < -0.5;
        value[i] = Rgb::Constant(p.object[i] == 0 ? 1.0 : p.object[i] == 1 ? 100.0 : foldUpper ? 7.0 : 3.0);
    }
    const auto corners = interpolateCorners(p, value);
    for (size_t i = 0; i < p.size(); ++i)
        for (int k = 0; k < 4; ++k) ASSERT_EQ(corners[i][size_t(k)][0], value[i][0]) << "patch " << i;
}
