// The command line as users and the acceptance checks drive it: every kind of bad input gets one
// clear error naming the file, object or field, a non-zero exit and no output; good input gets a
// report that ../shared/tools/check-report accepts.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "fixtures.h"
#include "io/image_io.h"
#include "io/solution.h"
#include "render/image_metrics.h"
#include "render/regions.h"
#include "solver/solve.h"

using namespace penumbra;
namespace fs = std::filesystem;

namespace {

using test::CommandResult;
using test::run;

const char* kLamp = R"("lamp": {"type": "diffuse", "reflectance": 0.5, "emission": 1})";

std::string sceneWith(const std::string& materials, const std::string& objects) {
    return cat(
        R"({"materials": {)", kLamp, materials.empty() ? "" : ", ", materials, R"(}, "objects": [)",
        R"({"name": "light", "type": "quad", "material": "lamp", "vertices": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]})",
        objects.empty() ? "" : ", ", objects, "]}");
}

// Solves `json` expecting failure: non-zero exit, one error line naming `file` and every fragment,
// and no output directory.
void expectRefused(const std::string& json, std::initializer_list<const char*> fragments,
                   const std::string& extra = "") {
    const std::string path = test::writeText("bad.json", json);
    const std::string out = test::tempDir() + "/refused-out";
    fs::remove_all(out);
    const CommandResult r = run(cat("solve ", path, " --out ", out, " --patches 20 ", extra));
    EXPECT_NE(r.status, 0) << r.output;
    EXPECT_LT(r.status, 64) << "crashed or internal error: " << r.output;
    size_t errors = 0;
    for (size_t at = r.output.find("error:"); at != std::string::npos; at = r.output.find("error:", at + 1)) ++errors;
    EXPECT_EQ(errors, 1u) << r.output;
    for (const char* f : fragments)
        EXPECT_NE(r.output.find(f), std::string::npos) << "missing '" << f << "' in: " << r.output;
    EXPECT_FALSE(fs::exists(out)) << "output written despite the error";
}

}  // namespace

TEST(CliErrors, MalformedJsonGivesLineAndColumn) {
    expectRefused("{\n  \"materials\": {,\n}", {"bad.json:2:", "malformed JSON"});
}

TEST(CliErrors, MaterialProblems) {
    expectRefused(
        sceneWith(
            "",
            R"({"name": "floor", "type": "quad", "material": "nope", "vertices": [[0,0,1],[0,1,1],[1,1,1],[1,0,1]]})"),
        {"objects[1] 'floor'", "unknown material 'nope'"});
    expectRefused(sceneWith("", R"({"name": "floor", "type": "quad", "vertices": [[0,0,1],[0,1,1],[1,1,1],[1,0,1]]})"),
                  {"objects[1] 'floor'", "'material'"});
    expectRefused(sceneWith(R"("w": {"type": "diffuse", "reflectance": [0.5, 1.2, 0.5]})", ""),
                  {"materials.w.reflectance", "[0, 1]"});
    expectRefused(sceneWith(R"("w": {"type": "diffuse", "reflectance": 0.5, "emission": [1, -2, 1]})", ""),
                  {"materials.w.emission", "negative"});
    expectRefused(sceneWith(R"("w": {"type": "diffuse", "reflectance": 0.5, "emission": 1e999})", ""),
                  {"bad.json", "1e999", "finite"});
    expectRefused(sceneWith(R"("w": {"type": "diffuse", "reflectence": 0.5})", ""),
                  {"materials.w", "unknown key 'reflectence'"});
    expectRefused(sceneWith(R"("w": {"type": "plastic", "reflectance": 0.5})", ""), {"materials.w.type", "plastic"});
}

TEST(CliErrors, GeometryProblems) {
    expectRefused(
        sceneWith(
            "", R"({"name": "q", "type": "quad", "material": "lamp", "vertices": [[0,0,1],[1,0,1],[2,0,1],[3,0,1]]})"),
        {"'q'", "degenerate quad"});
    expectRefused(
        sceneWith(
            "",
            R"({"name": "q", "type": "quad", "material": "lamp", "vertices": [[0,0,1],[0,1,1],[1,1,1],[1,0,1.03]]})"),
        {"'q'", "not planar"});
    expectRefused(
        sceneWith("",
                  R"({"name": "t", "type": "triangle", "material": "lamp", "vertices": [[0,0,1],[1,1,1],[2,2,1]]})"),
        {"'t'", "zero-area triangle"});
    expectRefused(
        sceneWith(
            "", R"({"name": "t", "type": "triangle", "material": "lamp", "vertices": [[0,0,1],[1,1e999,1],[2,2,1]]})"),
        {"bad.json", "1e999", "finite"});
    expectRefused(
        sceneWith("",
                  R"({"name": "t", "type": "triangle", "material": "lamp", "vertices": [[0,0,1],[1e12,1,1],[2,2,1]]})"),
        {"'t'", "unit_scale"});
    expectRefused(
        sceneWith("", R"({"name": "s", "type": "sphere", "material": "lamp", "center": [0,0,0], "radius": -1})"),
        {"'s'", "radius"});
    expectRefused(sceneWith("", R"({"name": "x", "type": "cone", "material": "lamp"})"),
                  {"'x'", "unknown object type 'cone'"});
    expectRefused(
        sceneWith(
            "", R"({"name": "light", "type": "triangle", "material": "lamp", "vertices": [[0,0,1],[1,0,1],[0,1,1]]})"),
        {"duplicate object name 'light'"});
    expectRefused(R"({"materials": {"m": {"type": "diffuse", "reflectance": 0.5}}, "objects": []})", {"empty"});
}

TEST(CliErrors, MeshFileProblems) {
    expectRefused(sceneWith("", R"({"name": "m", "type": "mesh", "material": "lamp", "file": "missing.obj"})"),
                  {"'m'", "missing.obj", "does not exist"});
    test::writeText("garbage.ply", "this is not a ply file\n");
    expectRefused(sceneWith("", R"({"name": "m", "type": "mesh", "material": "lamp", "file": "garbage.ply"})"),
                  {"'m'", "garbage.ply"});
    test::writeText("points.xyz", "0 0 0\n");
    expectRefused(sceneWith("", R"({"name": "m", "type": "mesh", "material": "lamp", "file": "points.xyz"})"),
                  {"'m'", "unsupported format"});
}

// Issue 15's hostile inputs: each is refused with one line naming the file, field or option.
TEST(CliErrors, HostileFilesAreRefusedByName) {
    for (const auto& [path, what] :
         {std::pair<std::string, std::string>{"/dev/zero", "not a regular file"}, {test::tempDir(), "is a folder"}}) {
        const std::string out = test::tempDir() + "/hostile-out";
        const CommandResult r = run(cat("solve ", path, " --out ", out));
        EXPECT_EQ(r.status, 1) << r.output;
        EXPECT_NE(r.output.find(cat(path, ": ")), std::string::npos) << r.output;
        EXPECT_NE(r.output.find(what), std::string::npos) << r.output;
        EXPECT_FALSE(fs::exists(out));
    }
    const std::string loop = test::tempDir() + "/loop.json";
    fs::remove(loop);
    fs::create_symlink(loop, loop);
    const CommandResult r = run(cat("solve ", loop, " --out ", test::tempDir(), "/hostile-out"));
    EXPECT_NE(r.output.find("symbolic links"), std::string::npos) << r.output;
    // A 60-byte OFF file claiming 100,000 elements (it hung OpenMesh's reader), an OBJ face past the
    // vertices (dropped silently), a binary STL claiming 2^31 triangles (out of memory).
    test::writeText("claims.off", "OFF\n50000 50000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    expectRefused(sceneWith("", R"({"name": "m", "type": "mesh", "material": "lamp", "file": "claims.off"})"),
                  {"'m'", "claims.off", "claims 100000 vertices and faces"});
    test::writeText("counts.off", "OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    expectRefused(sceneWith("", R"({"name": "m", "type": "mesh", "material": "lamp", "file": "counts.off"})"),
                  {"counts.off", "the keyword OFF must stand alone on the first line, the counts on the next"});
    test::writeText("range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 7\n");
    expectRefused(sceneWith("", R"({"name": "m", "type": "mesh", "material": "lamp", "file": "range.obj"})"),
                  {"'m'", "range.obj", "line 5", "index 7 is out of range (3 vertices"});
    test::writeText("indented.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n  f\n");
    expectRefused(sceneWith("", R"({"name": "m", "type": "mesh", "material": "lamp", "file": "indented.obj"})"),
                  {"indented.obj", "line 4", "a face of 0 vertices"});
    test::writeText("negative.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n");
    expectRefused(sceneWith("", R"({"name": "m", "type": "mesh", "material": "lamp", "file": "negative.obj"})"),
                  {"negative.obj", "line 4", "index -4 is out of range"});
    // A property line of four words: OpenMesh's header reader took the last two for the next
    // keyword, swallowed end_header and looped forever (found by tests/fuzz).
    test::writeText("words.ply",
                    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x y z\nelement face 1\n"
                    "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    expectRefused(sceneWith("", R"({"name": "m", "type": "mesh", "material": "lamp", "file": "words.ply"})"),
                  {"words.ply", "line 4", "expected property TYPE NAME"});
    // Its data: a face of -1 corners ran OpenMesh out of memory (found by tests/fuzz).
    test::writeText("minus.ply",
                    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                    "end_header\n0 0 0\n1 0 0\n0 1 0\n-1 0 1 2\n");
    expectRefused(sceneWith("", R"({"name": "m", "type": "mesh", "material": "lamp", "file": "minus.ply"})"),
                  {"minus.ply", "face 0: a list of -1 entries"});
    std::string stl(84, '\0');
    stl[83] = char(0x80);  // 2^31 triangles in 84 bytes
    test::writeText("claims.stl", stl);
    expectRefused(sceneWith("", R"({"name": "m", "type": "mesh", "material": "lamp", "file": "claims.stl"})"),
                  {"claims.stl", "claims 2147483648 triangles"});
}

TEST(CliErrors, HostileValuesAreRefusedByName) {
    // Duplicate keys: the parser kept the last one silently.
    expectRefused(cat(R"({"materials": {)", kLamp, R"(,
        "white": {"type": "diffuse", "reflectance": 0.5},
        "white": {"type": "diffuse", "reflectance": 0.9}},
      "objects": [{"name": "light", "type": "quad", "material": "lamp", "vertices": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}]})"),
                  {"key 'white' on lines 2 and 3"});
    expectRefused(sceneWith(R"("sun": {"type": "diffuse", "reflectance": 0.5, "emission": 1e300})", ""),
                  {"materials.sun.emission", "unit mistake"});
    expectRefused(cat(sceneWith("", "").substr(0, sceneWith("", "").size() - 1),
                      R"(, "camera": {"position": [0,0,5], "look_at": [0,0,0], "up": [0,1,0], "fov_y_deg": 40,
                          "resolution": [4294967328, 32]}})"),
                  {"camera.resolution", "got 4294967328x32"});
    // Messages that said too little: a value barely out of range printed rounded into range, a
    // material that is not an object, a literal past double precision with no line.
    expectRefused(sceneWith(R"("w": {"type": "diffuse", "reflectance": [1.0000001, 0.5, 0.5]})", ""),
                  {"materials.w.reflectance", "got 1.0000001"});
    expectRefused(sceneWith(R"("w": 3)", ""), {"materials.w", "expected a material object", "got a number"});
    expectRefused(cat(R"({"materials": {)", kLamp, R"(,
        "w": {"type": "diffuse", "reflectance": 1e400}}, "objects": []})"),
                  {":2: malformed JSON", "1e400"});
    test::writeText("nan.obj", "v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n");
    expectRefused(sceneWith("", R"({"name": "m", "type": "mesh", "material": "lamp", "file": "nan.obj"})"),
                  {"nan.obj", "line 2", "'nan' is not a finite number"});
    // Options: numbers must be finite, thread counts bounded.
    expectRefused(sceneWith("", ""), {"--tolerance", "got nan"}, "--tolerance nan");
    expectRefused(sceneWith("", ""), {"--tolerance 0.01", "at most"}, "--tolerance 0.01");
    expectRefused(sceneWith("", ""), {"--seed", "expected a whole number, got -5"}, "--seed -5");
    // Refused in its first second (a matrix over --max-memory is known only once the scene is meshed):
    // the error alone, without the info lines of the meshing before it (core/log.h holds them).
    {
        const std::string path = test::writeText("budget.json", sceneWith("", ""));
        const CommandResult r =
            run(cat("solve ", path, " --out ", test::tempDir(), "/budget-out --solver gauss-seidel --max-memory 1e-9"));
        EXPECT_EQ(r.status, 1) << r.output;
        EXPECT_NE(r.output.find("--max-memory"), std::string::npos) << r.output;
        EXPECT_EQ(r.output.find("info:"), std::string::npos) << "the error alone: " << r.output;
    }
    // Every solver honours --max-memory: the hierarchy took 1.5 MiB under a bound of 1 KiB.
    const std::string facing =
        R"({"name": "r", "type": "quad", "material": "lamp", "vertices": [[0,0,1],[0,1,1],[1,1,1],[1,0,1]]})";
    expectRefused(sceneWith("", facing), {"the hierarchy's", "more than the 0.001024 MiB allowed (--max-memory)"},
                  "--solver hierarchical --max-memory 0.000001");
    expectRefused(sceneWith("", ""), {"--ff-noise", "expected a number in [1e-06, 1], got nan"}, "--ff-noise nan");
    expectRefused(sceneWith("", ""), {"--patches", "expected a number in [1, 100000000], got abc"}, "--patches abc");
    const CommandResult exposure =
        run(cat("render ", std::string(PENUMBRA_SOURCE_DIR), "/scenes/cornell-box.json --out ", test::tempDir(),
                "/never.exr --exposure inf"));
    EXPECT_NE(exposure.output.find("--exposure: expected a finite number, got inf"), std::string::npos)
        << exposure.output;
    expectRefused(sceneWith("", ""), {"--max-memory"}, "--max-memory nan");
    expectRefused(sceneWith("", ""), {"--threads", "thread count"}, "--threads -1");
    expectRefused(sceneWith("", ""), {"--threads", "thread count"}, "--threads 2000000000");
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-box.json";
    const CommandResult camera = run(cat("render ", scene, " --integrator path --out ", test::tempDir(),
                                         R"(/never.exr --camera '{"position": [1e999, 0, 0]}')"));
    EXPECT_EQ(camera.status, 1) << camera.output;
    EXPECT_NE(camera.output.find("--camera"), std::string::npos) << camera.output;
    EXPECT_NE(camera.output.find("finite"), std::string::npos) << camera.output;
}

TEST(CliErrors, ClosedWhiteFurnaceHasNoSteadyState) {
    expectRefused(test::closedCube(R"({"type": "diffuse", "reflectance": 1, "emission": 1})"), {"no steady state"});
    // Nearly 1: a steady state that 20,000 sweeps do not reach is refused, not written unbalanced.
    expectRefused(test::closedCube(R"({"type": "diffuse", "reflectance": 0.9999999, "emission": 1})"),
                  {"did not converge", "still unshot", "--max-iterations"});
    // A reflectance-1 mirror for a wall: still nothing absorbs (only the diffuse walls were looked at).
    expectRefused(test::furnaceCube(1, R"({"type": "mirror", "reflectance": 1})", true), {"no steady state"});
}

TEST(CliErrors, OptionProblems) {
    expectRefused(sceneWith("", ""),
                  {"unknown solver 'magic'", "auto", "jacobi", "gauss-seidel", "southwell", "hierarchical"},
                  "--solver magic");
    expectRefused(sceneWith("", ""), {"--max-memory", "patches fit"}, "--solver gauss-seidel --max-memory 0.000001");
    expectRefused(sceneWith("", ""), {"--refine"}, "--refine -1");
    expectRefused(sceneWith("", ""), {"--vertex-radiosity", "gather"}, "--vertex-radiosity nearest");
    const CommandResult missing = run("solve /nonexistent/scene.json --out " + test::tempDir() + "/never");
    EXPECT_NE(missing.status, 0);
    EXPECT_NE(missing.output.find("/nonexistent/scene.json"), std::string::npos) << missing.output;
}

TEST(Cli, SceneWithoutEmitterWarnsAndSolvesToBlack) {
    const std::string path =
        test::writeText("dark.json", R"({"materials": {"m": {"type": "diffuse", "reflectance": 0.5}},
      "objects": [{"name": "q", "type": "quad", "material": "m", "vertices": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}]})");
    const CommandResult r = run(cat("solve ", path, " --out ", test::tempDir(), "/dark --patches 4"));
    EXPECT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("warning"), std::string::npos);
    EXPECT_NE(r.output.find("no material emits"), std::string::npos);
    // Black: nothing emitted, absorbed or escaped, and no radiosity anywhere (report and solution).
    std::ifstream in(test::tempDir() + "/dark/report.json");
    const nlohmann::json report = nlohmann::json::parse(in);
    for (const char* key : {"emitted_power_w", "absorbed_power_w", "escaped_power_w"})
        for (const auto& v : report["totals"][key]) EXPECT_EQ(v.get<double>(), 0.0) << key;
    for (const auto& v : report["objects"]["q"]["radiosity_mean"]) EXPECT_EQ(v.get<double>(), 0.0);
    const SolveResult solution = readSolution(test::tempDir() + "/dark/solution.bin");
    ASSERT_FALSE(solution.solution.B.empty());
    for (const Rgb& B : solution.solution.B) EXPECT_EQ(B.abs().maxCoeff(), 0.0);
    for (const auto& corners : solution.corners)
        for (const Rgb& c : corners) EXPECT_EQ(c.abs().maxCoeff(), 0.0);
}

TEST(Cli, CornellBoxSolvesToAConformingReportAndRendersFromTheSolution) {
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-box.json";
    const std::string out = test::tempDir() + "/cornell";
    fs::remove_all(out);
    const CommandResult solve = run(cat("solve ", scene, " --out ", out, " --patches 150 --quiet"));
    ASSERT_EQ(solve.status, 0) << solve.output;
    for (const char* f : {"report.json", "convergence.csv", "solution.bin", "radiosity.exr", "radiosity.png"})
        EXPECT_TRUE(fs::exists(out + "/" + f)) << f;
    const std::string checker = std::string(PENUMBRA_SHARED_DIR) + "/tools/check-report";
    ASSERT_TRUE(fs::exists(checker)) << "the contract's checker is missing at " << checker;
    const int checked = std::system(cat("python3 ", checker, " ", out, "/report.json ", scene, " > /dev/null").c_str());
    EXPECT_EQ(checked, 0);

    const CommandResult render = run(cat("render ", scene, " --solution ", out, " --integrator radiosity --out ", out,
                                         "/view.exr --resolution 64x48 --quiet"));
    EXPECT_EQ(render.status, 0) << render.output;
    EXPECT_TRUE(fs::exists(out + "/view.exr"));
    EXPECT_TRUE(fs::exists(out + "/view.png"));

    // The default integrator is the final gather; without mirrors or glass it runs no photon pass.
    const CommandResult gather = run(cat("render ", scene, " --solution ", out, " --out ", out,
                                         "/gather.exr --resolution 32x24 --spp 4 --gather-rays 4"));
    EXPECT_EQ(gather.status, 0) << gather.output;
    EXPECT_NE(gather.output.find("final-gather"), std::string::npos) << gather.output;
    EXPECT_NE(gather.output.find("no photon pass"), std::string::npos) << gather.output;
    EXPECT_TRUE(fs::exists(out + "/gather.exr"));
    EXPECT_TRUE(fs::exists(out + "/gather.png"));
    // The solution file carries the solve's indirect light (version 03): rendered from it, the final
    // gather is the same, bit for bit, as the one that solved first; gathered with rays it differs.
    const SolveResult stored = readSolution(out + "/solution.bin");
    EXPECT_EQ(stored.indirect.size(), stored.patches.size()) << "the indirect corners were written and read";
    ASSERT_EQ(run(cat("render ", scene, " --patches 150 --out ", out, "/solved.exr --resolution 32x24 --spp 4 --quiet"))
                  .status,
              0);
    ASSERT_EQ(run(cat("render ", scene, " --solution ", out, " --indirect gather --out ", out,
                      "/gathered.exr --resolution 32x24 --spp 4 --quiet"))
                  .status,
              0);
    const Image fromFile = readLinearImage(out + "/gather.exr");
    EXPECT_EQ(compareImages(fromFile, readLinearImage(out + "/solved.exr")).rmse, 0);
    EXPECT_GT(compareImages(fromFile, readLinearImage(out + "/gathered.exr")).rmse, 0);
    const CommandResult unknown =
        run(cat("render ", scene, " --solution ", out, " --integrator whitted --out ", out, "/unknown.exr"));
    EXPECT_NE(unknown.status, 0);
    EXPECT_NE(unknown.output.find("--integrator"), std::string::npos) << unknown.output;
    EXPECT_NE(unknown.output.find("known: final-gather, path, radiosity"), std::string::npos) << unknown.output;
    EXPECT_FALSE(fs::exists(out + "/unknown.exr"));

    // A solution belongs to its scene: another scene is refused, and nothing is written.
    const std::string other = test::writeText("other.json", sceneWith("", ""));
    const CommandResult mismatch = run(cat("render ", other, " --solution ", out,
                                           " --integrator radiosity --camera "
                                           "'{\"position\": [0.5,0.5,3], \"look_at\": [0.5,0.5,0]}' --out ",
                                           out, "/other.exr"));
    EXPECT_NE(mismatch.status, 0);
    EXPECT_NE(mismatch.output.find("another version"), std::string::npos) << mismatch.output;
    EXPECT_FALSE(fs::exists(out + "/other.exr"));
}

TEST(Cli, RefinedSolveReportsItsRoundsAndConforms) {
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-box.json";
    const std::string out = test::tempDir() + "/refined";
    fs::remove_all(out);
    const CommandResult solve =
        run(cat("solve ", scene, " --out ", out, " --refine 0.1 --patches 120 --max-patches 400 --seed 42 --quiet",
                " --form-factors rays"));  // the rounds are under test, not the cubature
    ASSERT_EQ(solve.status, 0) << solve.output;
    std::ifstream in(out + "/report.json");
    const nlohmann::json report = nlohmann::json::parse(in);
    // The report says how it was made: the settings given and the seed.
    EXPECT_EQ(report["settings"]["seed"].get<int>(), 42);
    EXPECT_EQ(report["settings"]["refine"].get<double>(), 0.1);
    EXPECT_EQ(report["settings"]["max_patches"].get<int>(), 400);
    EXPECT_EQ(report["settings"]["solver"].get<std::string>(), "auto");
    const auto& rounds = report["solver"]["refinement"];
    ASSERT_GE(rounds.size(), 2u);
    EXPECT_GT(rounds.back()["patches"].get<int>(), rounds.front()["patches"].get<int>());
    EXPECT_LE(report["solver"]["patches"].get<int>(), 400);
    EXPECT_EQ(report["solver"]["patches"].get<int>(), rounds.back()["patches"].get<int>());
    const std::string checker = std::string(PENUMBRA_SHARED_DIR) + "/tools/check-report";
    EXPECT_EQ(std::system(cat("python3 ", checker, " ", out, "/report.json ", scene, " > /dev/null").c_str()), 0);
}

TEST(Cli, EverySolveSettingIsAFlagAndComesBackInTheReport) {
    // One value per entry of the settings table, none of them the default: each flag must reach its
    // field (the report says what the solve used) under the key the table gives. A new entry without
    // a value here fails the first check.
    const std::map<std::string, double> values{{"patches", 60},           {"patch_size_m", 0.25},
                                               {"link_tolerance", 2e-4},  {"roots", 9},
                                               {"tolerance", 3e-5},       {"max_iterations", 777},
                                               {"visibility_rays", 3},    {"ff_tolerance", 2e-4},
                                               {"specular_rays", 33},     {"specular_max_depth", 7},
                                               {"refine", 0.5},           {"max_patches", 90},
                                               {"refine_rounds", 2},      {"ff_rays", 77},
                                               {"grade_contacts", 2},     {"ff_noise", 0.02},
                                               {"patches_per_object", 5}, {"specular_caustics", 0.25},
                                               {"grade_caustics", 1},     {"specular_receivers", 0.4}};
    SolveOptions defaults;
    std::string flags;
    for (const SolveSetting& e : solveSettings(defaults)) {
        ASSERT_TRUE(values.count(e.key)) << "no test value for setting " << e.key;
        const double given = values.at(e.key);
        EXPECT_NE(std::visit([](auto* v) { return double(*v); }, e.value), given) << e.key << ": pick a non-default";
        flags += cat(" ", e.flag, " ", given);
    }
    EXPECT_EQ(values.size(), solveSettings(defaults).size());
    const std::string out = test::tempDir() + "/every-setting";
    fs::remove_all(out);
    const CommandResult r =
        run(cat("solve ", test::writeText("settings.json", sceneWith("", "")), " --out ", out, " --seed 5", flags));
    ASSERT_EQ(r.status, 0) << r.output;
    std::ifstream in(out + "/report.json");
    const nlohmann::json settings = nlohmann::json::parse(in)["settings"];
    for (const auto& [key, given] : values) EXPECT_DOUBLE_EQ(settings.at(key).get<double>(), given) << key;
    EXPECT_EQ(settings.at("seed").get<int>(), 5);
}

TEST(Cli, ASolutionFitsItsSceneReindentedRecommentedOrSeenFromElsewhere) {
    // A solution is keyed on what the solve read (geometry, materials, units, mesh files), not the
    // file's bytes: it was refused after re-indenting the file, editing an ignored "_" key or moving
    // the camera. Another reflectance is another scene.
    std::ifstream in(std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-box.json");
    const nlohmann::json original = nlohmann::json::parse(in);
    const std::string out = test::tempDir() + "/keyed";
    fs::remove_all(out);
    const std::string scene = test::writeText("keyed.json", original.dump());
    ASSERT_EQ(run(cat("solve ", scene, " --out ", out, " --patches 100 --form-factors rays -q")).status, 0);
    auto renderWith = [&](const nlohmann::json& j) {
        const std::string path = test::writeText("keyed-variant.json", j.dump(7));
        return run(cat("render ", path, " --solution ", out, " --integrator radiosity --resolution 24x24 --out ",
                       test::tempDir(), "/keyed.exr -q"));
    };
    nlohmann::json moved = original;
    moved["_note"] = "edited";
    moved["camera"]["position"][0] = moved["camera"]["position"][0].get<double>() + 0.1;
    const CommandResult same = renderWith(moved);
    EXPECT_EQ(same.status, 0) << same.output;
    nlohmann::json other = original;
    other["materials"]["white"]["reflectance"] = 0.5;
    const CommandResult refused = renderWith(other);
    EXPECT_EQ(refused.status, 1) << refused.output;
    EXPECT_NE(refused.output.find("solve again"), std::string::npos) << refused.output;
}

// Scale invariance (issue 15): a scene scaled to a nanometre or to 1e-30 m rendered 11% bright,
// 10% dark or black, as ray offsets and tolerances were in metres. Lengths are now held in a unit
// of a power of two metres that makes the scene about one unit across (Scene::metresPerUnit), so a
// scene scaled by a power of two is the same computation: radiosity and pixels bit for bit, areas
// and powers by the square of the factor. By any other factor, within rounding.
TEST(Cli, AScaledSceneSolvesAndRendersAsAtItsOwnSize) {
    std::ifstream in(std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-box.json");
    const nlohmann::json original = nlohmann::json::parse(in);
    struct Result {
        nlohmann::json report;
        Image image;
    };
    auto solveAndRender = [&](double factor, const std::string& name) {
        nlohmann::json j = original;
        j["unit_scale"] = original["unit_scale"].get<double>() * factor;
        const std::string scene = test::writeText(name + ".json", j.dump());
        const std::string out = test::tempDir() + "/" + name;
        fs::remove_all(out);
        const CommandResult solved = run(cat("solve ", scene, " --out ", out, " --patches 200 -q"));
        EXPECT_EQ(solved.status, 0) << solved.output;
        const CommandResult rendered =
            run(cat("render ", scene, " --integrator path --spp 2 --resolution 24x24 --out ", out, "/path.exr -q"));
        EXPECT_EQ(rendered.status, 0) << rendered.output;
        std::ifstream report(out + "/report.json");
        return Result{nlohmann::json::parse(report), readLinearImage(out + "/path.exr")};
    };
    const Result base = solveAndRender(1, "scale-1");
    const double tiny = std::ldexp(1.0, -40);
    const Result pow2 = solveAndRender(tiny, "scale-2-40"), odd = solveAndRender(1e-30, "scale-1e-30");
    for (const auto& [name, object] : base.report["objects"].items()) {
        const nlohmann::json& p = pow2.report["objects"][name];
        EXPECT_EQ(p["radiosity_mean"], object["radiosity_mean"]) << name;
        EXPECT_EQ(p["area_m2"].get<double>(), object["area_m2"].get<double>() * tiny * tiny) << name;
        for (int c = 0; c < 3; ++c) {
            EXPECT_EQ(p["absorbed_power_w"][c].get<double>(),
                      object["absorbed_power_w"][c].get<double>() * tiny * tiny);
            const double b = object["radiosity_mean"][c], o = odd.report["objects"][name]["radiosity_mean"][c];
            EXPECT_NEAR(o, b, 1e-4 * b + 1e-12) << name;
        }
    }
    EXPECT_EQ(pow2.image.rgb, base.image.rgb);
    EXPECT_LT(compareBlurred(odd.image, base.image).pooledL1, 1e-3);
    // Beyond what areas in m^2 can hold in double precision: refused, by the file and the field to check.
    nlohmann::json j = original;
    j["unit_scale"] = 1e-300;
    expectRefused(j.dump(), {"m across", "check unit_scale"});
    j["unit_scale"] = 1e300;
    expectRefused(j.dump(), {"m from the origin", "check unit_scale"});
}

TEST(CliErrors, RenderWithoutCameraIsRefused) {
    const std::string path = test::writeText("nocam.json", sceneWith("", ""));
    const CommandResult r = run(cat("render ", path, " --integrator radiosity --out ", test::tempDir(), "/nocam.exr"));
    EXPECT_NE(r.status, 0);
    EXPECT_NE(r.output.find("camera"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(test::tempDir() + "/nocam.exr"));
}

TEST(Cli, ASolveForFewSamplesIsNoQuieterThanTheImage) {
    // render without --solution makes its solve and photons for an image of few samples per pixel
    // (gatherEffortFor: at 1 spp --ff-noise 0.02, 0.71 x the patches, half the specular paths, a
    // quarter of the photons), unless the option is given or the image is no final gather.
    const std::string box = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-box.json";
    const std::string glass = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-glass.json";
    const std::string out = test::tempDir() + "/few";
    const std::string common = cat(" --form-factors rays --resolution 16x16 -v --out ", out, ".exr");
    // The log lines naming what the render chose for the image ("" where it kept the defaults).
    auto chosen = [&](const std::string& scene, const std::string& options) {
        const CommandResult r = run(cat("render ", scene, common, options));
        EXPECT_EQ(r.status, 0) << r.output;
        std::string lines;
        for (const char* what : {"whose own noise hides the solve's", "whose own noise hides theirs"}) {
            const size_t at = r.output.find(what);
            if (at == std::string::npos) continue;
            const size_t begin = r.output.rfind('\n', at) + 1;
            lines += r.output.substr(begin, r.output.find('\n', at) - begin) + "\n";
        }
        return lines;
    };
    const std::string one = chosen(box, " --spp 1");
    EXPECT_NE(one.find("--ff-noise 0.02, --patches 2121"), std::string::npos) << one;
    EXPECT_EQ(one.find("specular"), std::string::npos) << "no mirrors or glass: " << one;
    EXPECT_EQ(one.find("photons"), std::string::npos) << one;
    const std::string given = chosen(box, " --spp 1 --patches 100");
    EXPECT_NE(given.find("--ff-noise 0.02"), std::string::npos) << given;
    EXPECT_EQ(given.find("--patches"), std::string::npos) << given;
    EXPECT_EQ(chosen(box, " --spp 1 --patches 100 --ff-noise 0.005"), "");
    EXPECT_EQ(chosen(box, " --spp 16 --patches 100"), "");
    EXPECT_EQ(chosen(box, " --spp 1 --integrator radiosity --patches 100"), "");
    const std::string caustics = chosen(glass, " --spp 4 --patches 300");
    EXPECT_NE(caustics.find("--ff-noise 0.01, --specular-rays 68"), std::string::npos) << caustics;
    EXPECT_NE(caustics.find("caustic photons: 500000 for images of 4"), std::string::npos) << caustics;
    EXPECT_EQ(chosen(glass, " --spp 4 --patches 300 --ff-noise 0.005 --specular-rays 96 --photons 1000000"), "");
}

TEST(Cli, GlassSceneRendersWithoutASolutionAndAgainstThePathTracer) {
    // Without --solution, render solves first; with mirrors and glass it traces caustic photons.
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-glass.json";
    const std::string out = test::tempDir() + "/glass";
    fs::remove_all(out);
    const CommandResult gather =
        run(cat("render ", scene, " --out ", out, "/gather.exr --patches 200 --resolution 24x24",
                " --spp 4 --gather-rays 4 --photons 20000"));
    ASSERT_EQ(gather.status, 0) << gather.output;
    EXPECT_NE(gather.output.find("solving first"), std::string::npos) << gather.output;
    EXPECT_NE(gather.output.find("caustic photons"), std::string::npos) << gather.output;
    // Its report balances the power with mirrors and glass present (the contract's checker).
    const CommandResult solve = run(cat("solve ", scene, " --out ", out, "/solve --patches 200 --quiet"));
    ASSERT_EQ(solve.status, 0) << solve.output;
    const std::string checker = std::string(PENUMBRA_SHARED_DIR) + "/tools/check-report";
    EXPECT_EQ(std::system(cat("python3 ", checker, " ", out, "/solve/report.json ", scene, " > /dev/null").c_str()), 0);
    const CommandResult path = run(cat("render ", scene, " --out ", out, "/path.exr --integrator path --patches 200",
                                       " --resolution 24x24 --spp 16"));
    ASSERT_EQ(path.status, 0) << path.output;
    EXPECT_EQ(path.output.find("solving"), std::string::npos) << "the path tracer needs no solve: " << path.output;
    const CommandResult compare = run(cat("compare ", out, "/gather.exr ", out, "/path.exr"));
    ASSERT_EQ(compare.status, 0) << compare.output;
    // compare's pooled L1 after the 5x5 blur, against the same measure computed here on its own: the
    // two renders agree to within their noise (4 and 16 samples per pixel at 24 x 24).
    double printed = -1;
    ASSERT_EQ(std::sscanf(compare.output.c_str(), "pooled L1 after 5x5 box blur %lf", &printed), 1) << compare.output;
    const Image a = readLinearImage(out + "/gather.exr"), b = readLinearImage(out + "/path.exr");
    auto blurred = [](const Image& im, int x, int y, int c) {
        double sum = 0;
        int count = 0;
        for (int yy = std::max(0, y - 2); yy <= std::min(im.height - 1, y + 2); ++yy)
            for (int xx = std::max(0, x - 2); xx <= std::min(im.width - 1, x + 2); ++xx, ++count)
                sum += im.rgb[size_t(3 * (yy * im.width + xx) + c)];
        return sum / count;
    };
    double l1 = 0, total = 0;
    for (int y = 0; y < a.height; ++y)
        for (int x = 0; x < a.width; ++x)
            for (int c = 0; c < 3; ++c) {
                l1 += std::abs(blurred(a, x, y, c) - blurred(b, x, y, c));
                total += blurred(b, x, y, c);
            }
    EXPECT_NEAR(printed, l1 / total, 1e-3) << compare.output;
    EXPECT_LT(printed, 0.15) << "final gather against the path tracer, 24 x 24, few samples";
    const CommandResult mismatch = run(
        cat("compare ", out, "/gather.exr ", std::string(PENUMBRA_SOURCE_DIR), "/docs/images/cornell-radiosity.png"));
    EXPECT_NE(mismatch.status, 0);
}

TEST(Cli, OrbitViewsDifferAndEachMatchesARenderOfItsCamera) {
    // A lit ball on a floor, the lamp off to one side: every azimuth sees something else.
    const std::string scene = test::writeText("orbit.json", R"({"materials": {
          "white": {"type": "diffuse", "reflectance": 0.7},
          "lamp": {"type": "diffuse", "reflectance": 0.5, "emission": 5}},
      "objects": [
        {"name": "floor", "type": "quad", "material": "white", "vertices": [[-2,0,-2],[-2,0,2],[2,0,2],[2,0,-2]]},
        {"name": "ball", "type": "sphere", "material": "white", "center": [0, 0.5, 0], "radius": 0.5},
        {"name": "lamp", "type": "quad", "material": "lamp", "vertices": [[1,2,0],[2,2,0],[2,2,1],[1,2,1]]}],
      "camera": {"position": [0, 1.5, -4], "look_at": [0, 0.5, 0], "fov_y_deg": 40, "resolution": [40, 30]}})");
    const std::string out = test::tempDir() + "/orbit";
    fs::remove_all(out);
    ASSERT_EQ(run(cat("solve ", scene, " --out ", out, "/solve --patches 200 --quiet")).status, 0);
    const CommandResult orbit = run(cat("render ", scene, " --solution ", out,
                                        "/solve --integrator radiosity --orbit 4 --out ", out, "/view.exr --quiet"));
    ASSERT_EQ(orbit.status, 0) << orbit.output;
    std::ifstream listFile(out + "/view-orbit.json");
    const nlohmann::json list = nlohmann::json::parse(listFile);
    ASSERT_EQ(list["views"].size(), 4u);
    std::vector<Image> views;
    for (const auto& v : list["views"]) {
        const std::string image = v["image"];
        ASSERT_TRUE(fs::exists(image)) << image;
        EXPECT_TRUE(fs::exists(previewPathFor(image))) << image;
        views.push_back(readLinearImage(image));
    }
    for (size_t a = 0; a < views.size(); ++a)
        for (size_t b = a + 1; b < views.size(); ++b)
            EXPECT_GT(compareImages(views[a], views[b]).meanRelative, 0.05) << "views " << a << " and " << b;
    // Each view is the render of its camera, as `render --camera` makes it.
    for (size_t k = 0; k < views.size(); ++k) {
        const std::string camera = list["views"][k]["camera"].dump();
        const CommandResult single =
            run(cat("render ", scene, " --solution ", out, "/solve --integrator radiosity --camera '", camera,
                    "' --out ", out, "/single.exr --quiet"));
        ASSERT_EQ(single.status, 0) << single.output;
        const ImageError e = compareImages(readLinearImage(out + "/single.exr"), views[k]);
        EXPECT_LT(e.rmse, 1e-6) << "view " << k;
    }
}

namespace {
// Solves the Cornell box (400 patches) into OUT/solve for the viewer tests.
void solveCornellInto(const std::string& out) {
    fs::remove_all(out);
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-box.json";
    // The viewer is under test, not the form factors: the ray-cast ones take 0.02 s here, the analytic
    // cubature that `auto` picks at 400 patches 1.7 s (30 s under the sanitizers).
    ASSERT_EQ(run(cat("solve ", scene, " --out ", out, "/solve --patches 400 --form-factors rays --quiet")).status, 0);
}
// `penumbra view` of that solve (of `scene`) under a virtual display. The window's GL driver is not
// ours to leak-check, hence detect_leaks=0 under the sanitizers.
int viewUnderXvfb(const std::string& out, const std::string& options, const std::string& scene = "cornell-box.json") {
    const std::string command =
        cat("ASAN_OPTIONS=detect_leaks=0 xvfb-run -a -s '-screen 0 640x480x24' ", PENUMBRA_EXE, " view ",
            PENUMBRA_SOURCE_DIR, "/scenes/", scene, " --solution ", out, "/solve ", options, " --quiet 2>&1");
    return std::system(command.c_str());
}
}  // namespace

TEST(Viewer, ScreenshotUnderXvfbMatchesTheHeadlessRadiosityView) {
    // Xvfb and Mesa's software OpenGL come with the set-up; without them this fails, loudly.
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-box.json";
    const std::string out = test::tempDir() + "/viewer";
    solveCornellInto(out);
    const std::string size = " --resolution 160x120";
    const CommandResult headless = run(cat("render ", scene, " --solution ", out, "/solve --integrator radiosity", size,
                                           " --spp 16 --out ", out, "/headless.exr --quiet"));
    ASSERT_EQ(headless.status, 0) << headless.output;
    ASSERT_EQ(viewUnderXvfb(out, cat(size, " --screenshot ", out, "/shot.png --frames 3")), 0);
    ASSERT_TRUE(fs::exists(out + "/shot.png"));
    // Both tone-mapped the same way (the previews' automatic exposure, sRGB), compared as 8-bit.
    const Image shot = readLinearImage(out + "/shot.png"), view = readLinearImage(out + "/headless.png");
    ASSERT_EQ(shot.width, 160);
    ASSERT_EQ(shot.height, 120);
    const ImageError e = compareImages(shot, view);
    std::printf("viewer screenshot vs headless radiosity view: mean relative error %.4f\n", e.meanRelative);
    EXPECT_LT(e.meanRelative, 0.05);
}

namespace {

// `scene` (of scenes/) solved at 400 patches, drawn by the viewer and by the headless radiosity view
// (16 spp) at 160 x 160 from its camera, both tone-mapped by one exposure (the headless view's
// automatic one) and clamped, as the previews are (the lamp and its highlights, 100 times the walls,
// would otherwise weigh like the rest): {viewer, headless}.
std::pair<Image, Image> viewerAndHeadless(const std::string& scene, const std::string& out) {
    const std::string path = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/" + scene;
    fs::remove_all(out);
    EXPECT_EQ(run(cat("solve ", path, " --out ", out, "/solve --patches 400 --form-factors rays --quiet")).status, 0);
    const std::string size = " --resolution 160x160";
    const CommandResult headless = run(cat("render ", path, " --solution ", out, "/solve --integrator radiosity", size,
                                           " --spp 16 --out ", out, "/headless.exr --quiet"));
    EXPECT_EQ(headless.status, 0) << headless.output;
    EXPECT_EQ(viewUnderXvfb(out, cat(size, " --screenshot ", out, "/shot.exr --frames 3"), scene), 0);
    Image shot = readLinearImage(out + "/shot.exr"), view = readLinearImage(out + "/headless.exr");
    EXPECT_EQ(shot.width, view.width);
    std::vector<double> luminances;
    for (size_t p = 0; p < view.rgb.size(); p += 3)
        luminances.push_back(luminance(Rgb(view.rgb[p], view.rgb[p + 1], view.rgb[p + 2])));
    const double exposure = exposureScale(luminances, 0);
    for (Image* image : {&shot, &view})
        for (float& v : image->rgb) v = std::clamp(float(exposure) * v, 0.0f, 1.0f);
    const ImageError e = compareImages(shot, view);
    std::printf(
        "%s: viewer screenshot vs headless radiosity view: mean relative error %.4f, pooled L1 after a "
        "5x5 blur %.4f\n",
        scene.c_str(), e.meanRelative, compareBlurred(shot, view).pooledL1);
    return {shot, view};
}

// The regions of `scene`'s objects seen from its camera at `image`'s size.
std::vector<RegionError> objectRegionErrors(const std::string& scene, const Image& image, const Image& reference) {
    const Scene loaded = loadScene(std::string(PENUMBRA_SOURCE_DIR) + "/scenes/" + scene);
    Camera camera = loaded.camera;
    camera.width = image.width, camera.height = image.height;
    const PatchSet patches = meshScene(loaded, MeshingOptions{});
    const SceneTracer tracer(loaded, patches);
    return compareRegions(image, reference, objectRegions(tracer, camera));
}
}  // namespace

// cornell-glass in the window: its mirror and glass balls drawn through probes of the solved scene
// (viewer/scene_draw.h) against the headless radiosity view, which follows the same specular walk
// by rays: the whole picture within the diffuse test's 5% mean relative error, each ball's mean
// within 5% (they show the room, not black).
TEST(Viewer, CornellGlassScreenshotShowsTheBallsAsTheHeadlessRadiosityView) {
    const auto [shot, view] = viewerAndHeadless("cornell-glass.json", test::tempDir() + "/viewer-glass");
    ASSERT_EQ(shot.width, view.width);
    EXPECT_LT(compareImages(shot, view).meanRelative, 0.05);
    int balls = 0;
    for (const RegionError& r : objectRegionErrors("cornell-glass.json", shot, view)) {
        if (r.name.find("ball") == std::string::npos) continue;
        ++balls;
        std::printf("  %s: %d pixels, mean ratio %.4f\n", r.name.c_str(), r.pixels, r.ratio);
        EXPECT_NEAR(r.ratio, 1.0, 0.05) << r.name;
    }
    EXPECT_EQ(balls, 2);
}

// The textured Cornell box in the window: the checker floor and the striped back wall drawn as the
// headless radiosity view shows them (the light at the corners times the texel), not as the
// patches' mean: each within 5% in the mean, and its detail kept (pooled L1 after the blur within
// the region). Measured: the image 3.2% pooled L1 after the blur (5.3% per pixel), floor 3.3%, back
// wall 1.3%; drawn by the patches' means (before 2026-12-07): 11.3% (24%), floor 28.6%, back wall
// 21.7%.
TEST(Viewer, TexturedCornellBoxShowsItsTexturesAsTheHeadlessRadiosityView) {
    const auto [shot, view] = viewerAndHeadless("cornell-textured.json", test::tempDir() + "/viewer-textured");
    ASSERT_EQ(shot.width, view.width);
    // After the blur: the checker's edges, a texel each, differ pixel by pixel (the headless view
    // averages 16 samples over a pixel, the viewer reads the filtered texture at its centre).
    EXPECT_LT(compareBlurred(shot, view).pooledL1, 0.05) << "pooled L1 after a 5x5 blur";
    int textured = 0;
    for (const RegionError& r : objectRegionErrors("cornell-textured.json", shot, view)) {
        if (r.name != "floor" && r.name != "back_wall") continue;
        ++textured;
        std::printf("  %s: %d pixels, mean ratio %.4f, pooled L1 after the blur %.4f\n", r.name.c_str(), r.pixels,
                    r.ratio, r.pooledL1);
        EXPECT_NEAR(r.ratio, 1.0, 0.05) << r.name;
        EXPECT_LT(r.pooledL1, 0.05) << r.name;
    }
    EXPECT_EQ(textured, 2);
}

// Occlusion culling (render/occlusion.h), forced on in scenes too small for it to be on by itself:
// the Cornell box from its camera, where the blocks hide parts of the lit walls and floor behind
// them (cells partly seen past the blocks' edges), and two-rooms from a corner of the lit room
// looking at the wall between the rooms, the dark room's cells in the frustum behind it. In both
// the viewer draws fewer cells than are in view, and the picture is the same to the byte as with
// every cell drawn: culling hides only what the depth test would have hidden.
TEST(Viewer, OcclusionCullingLeavesThePictureAsItWas) {
    const std::string out = test::tempDir() + "/viewer-occlusion";
    fs::remove_all(out);
    struct View {
        std::string scene, camera;
    };
    for (const View& view :
         {View{"cornell-box.json", ""},
          View{"two-rooms.json",
               R"( --camera '{"position": [-1.9, 1.6, -0.1], "look_at": [0, 1.1, -1.2], "fov_y_deg": 90}')"}}) {
        const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/" + view.scene;
        const std::string solved = out + "/" + view.scene;
        ASSERT_EQ(run(cat("solve ", scene, " --out ", solved, " --patches 1000 --form-factors rays --quiet")).status,
                  0);
        const auto shot = [&](const std::string& name, const std::string& culling) {
            const CommandResult r =
                run(cat("view ", scene, " --solution ", solved, " --resolution 200x200 --frames 3 --screenshot ", out,
                        "/", name, view.camera, " --occlusion-culling ", culling),
                    "ASAN_OPTIONS=detect_leaks=0 xvfb-run -a -s '-screen 0 640x480x24' ");
            EXPECT_EQ(r.status, 0) << r.output;
            std::ifstream in(out + "/" + name, std::ios::binary);
            return std::make_pair(r.output, std::string(std::istreambuf_iterator<char>(in), {}));
        };
        const auto [culledLog, culled] = shot("culled.png", "on");
        const auto [allLog, all] = shot("all.png", "off");
        ASSERT_FALSE(culled.empty());
        EXPECT_TRUE(culled == all) << view.scene << ": the pictures differ";
        // "(D of the N cells in view drawn": fewer drawn with culling, all of them without.
        const auto cells = [](const std::string& log) {
            const size_t at = log.find(" cells in view drawn");
            const size_t of = log.rfind(" of the ", at);
            const size_t open = log.rfind('(', of);
            EXPECT_NE(at, std::string::npos) << log;
            return std::make_pair(std::stoi(log.substr(open + 1, of - open - 1)),
                                  std::stoi(log.substr(of + 8, at - of - 8)));
        };
        const auto [drawn, inView] = cells(culledLog);
        EXPECT_LT(drawn, inView) << culledLog;
        const auto [drawnAll, inViewAll] = cells(allLog);
        EXPECT_EQ(drawnAll, inViewAll) << allLog;
        EXPECT_EQ(inViewAll, inView);
    }
}

TEST(Viewer, WithoutADisplayItSaysSoAndPointsToTheHeadlessForms) {
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-box.json";
    const std::string command =
        cat("env -u DISPLAY -u WAYLAND_DISPLAY ", PENUMBRA_EXE, " view ", scene, " --patches 50 --quiet 2>&1");
    FILE* pipe = popen(command.c_str(), "r");
    std::string output;
    char buffer[4096];
    while (size_t n = fread(buffer, 1, sizeof buffer, pipe)) output.append(buffer, n);
    const int status = pclose(pipe);
    EXPECT_NE(status, 0);
    EXPECT_NE(output.find("no display"), std::string::npos) << output;
    EXPECT_NE(output.find("--integrator radiosity"), std::string::npos) << output;
}

TEST(Viewer, InWindowFinalGatherMatchesTheRenderOfTheSameView) {
    // The progressive final gather the window shows on G, after 16 passes, against `render` at 16
    // samples per pixel: the same picture up to noise (compared after a 5x5 blur, tone-mapped alike).
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-box.json";
    const std::string out = test::tempDir() + "/viewer-gather";
    solveCornellInto(out);
    const std::string size = " --resolution 96x72";
    const CommandResult render =
        run(cat("render ", scene, " --solution ", out, "/solve", size, " --spp 16 --out ", out, "/render.exr --quiet"));
    ASSERT_EQ(render.status, 0) << render.output;
    ASSERT_EQ(viewUnderXvfb(out, cat(size, " --screenshot ", out, "/shot.png --gather-passes 16")), 0);
    const ImageError e = compareBlurred(readLinearImage(out + "/shot.png"), readLinearImage(out + "/render.png"));
    std::printf("in-window final gather vs render: blurred mean relative error %.4f\n", e.meanRelative);
    EXPECT_LT(e.meanRelative, 0.05);
}

// `reference` writes each object's path-traced radiosity with its noise; `compare` measures a solve's
// report.json against it, object by object. A closed furnace (pi L_e / (1 - rho) everywhere) gives
// both a known answer.
TEST(Cli, ReferenceMeasuresASolveObjectByObject) {
    const std::string scene = test::writeText("furnace-ref.json", test::furnaceWithOccluders(0.5));
    const std::string out = test::tempDir() + "/furnace-ref";
    fs::remove_all(out);
    const double error = test::kSanitized ? 0.03 : 0.01;
    const CommandResult ref = run(cat("reference ", scene, " --out ", out, "/reference.json --error ", error,
                                      " --min-points 1024 --patches 200"));
    ASSERT_EQ(ref.status, 0) << ref.output;
    std::ifstream in(out + "/reference.json");
    const nlohmann::json j = nlohmann::json::parse(in);
    ASSERT_EQ(j["objects"].size(), 19u);
    for (const auto& [name, o] : j["objects"].items()) {
        EXPECT_LE(o["relative_error"].get<double>(), error) << name;
        EXPECT_NEAR(o["radiosity_mean"][0].get<double>(), 2 * kPi, 4 * o["std_error"][0].get<double>()) << name;
    }
    const CommandResult solved = run(cat("solve ", scene, " --out ", out, "/solve --patches 200"));
    ASSERT_EQ(solved.status, 0) << solved.output;
    const CommandResult cmp = run(cat("compare ", out, "/solve/report.json ", out, "/reference.json"));
    ASSERT_EQ(cmp.status, 0) << cmp.output;
    EXPECT_NE(cmp.output.find("ball"), std::string::npos) << cmp.output;
    EXPECT_NE(cmp.output.find("19 objects: worst"), std::string::npos) << cmp.output;
    // Bad input: one clear error naming what is wrong, and nothing written.
    const CommandResult badOut = run(cat("reference ", scene, " --out ", out, "/reference.exr"));
    EXPECT_NE(badOut.status, 0);
    EXPECT_NE(badOut.output.find("expected a .json file name"), std::string::npos) << badOut.output;
    EXPECT_FALSE(fs::exists(out + "/reference.exr"));
    const CommandResult notReport = run(cat("compare ", out, "/solve/convergence.csv.json ", out, "/reference.json"));
    EXPECT_NE(notReport.status, 0);
    EXPECT_NE(notReport.output.find("cannot open"), std::string::npos) << notReport.output;
    test::writeText("not-a-report.json", "{\"views\": []}");
    const CommandResult wrongForm =
        run(cat("compare ", test::tempDir(), "/not-a-report.json ", out, "/reference.json"));
    EXPECT_NE(wrongForm.status, 0);
    EXPECT_NE(wrongForm.output.find("not-a-report.json: not a report.json"), std::string::npos) << wrongForm.output;
}
