// Scenes as users have them (issue 17): glTF 2.0 and OBJ + MTL written by Blender's own exporters
// (scenes/blender/export_scene.py made the committed files) solve to the report of our JSON scene,
// renders the same image from the file's camera, and what cannot be honoured is refused by name.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "fixtures.h"
#include "io/export.h"
#include "io/image_io.h"
#include "io/solution.h"
#include "render/image_metrics.h"
#include "render/regions.h"

namespace fs = std::filesystem;
using namespace penumbra;
using test::CommandResult;
using test::run;

namespace {

std::string scenePath(const std::string& name) { return cat(PENUMBRA_SOURCE_DIR, "/scenes/", name); }

nlohmann::json reportOf(const std::string& dir) {
    std::ifstream in(dir + "/report.json");
    return nlohmann::json::parse(in);
}

// The largest relative difference between two reports' numbers per object and in the totals, and
// where it is.
std::pair<double, std::string> largestDifference(const nlohmann::json& a, const nlohmann::json& b) {
    std::pair<double, std::string> worst{0, ""};
    const auto compare = [&](const nlohmann::json& x, const nlohmann::json& y, const std::string& where) {
        if (!y.is_number() || !x.is_number()) return;
        const double u = x.get<double>(), v = y.get<double>();
        const double d = std::abs(u - v) / std::max(std::abs(u), 1e-12);
        if (d > worst.first) worst = {d, where};
    };
    for (const auto& [name, object] : a["objects"].items()) {
        if (!b["objects"].contains(name)) return {1e300, "object " + name + " missing"};
        for (const auto& [key, value] : object.items()) {
            const nlohmann::json& other = b["objects"][name][key];
            if (value.is_array())
                for (size_t c = 0; c < value.size(); ++c) compare(value[c], other[c], name + "." + key);
            else
                compare(value, other, name + "." + key);
        }
    }
    for (const auto& [key, value] : a["totals"].items())
        for (size_t c = 0; c < value.size(); ++c) compare(value[c], b["totals"][key][c], "totals." + key);
    if (a["objects"].size() != b["objects"].size()) worst = {1e300, "object counts differ"};
    return worst;
}

// Solves the Blender export `file` (of scenes/`json`, the Cornell box by default) and the JSON scene
// alike, in `out`:
// the reports agree within 1e-6 (every object's area, radiosity and powers, and the totals), and
// radiosity views (the file's from `camera`, empty for its own) agree within 1e-3 pooled L1 after a
// 5x5 blur.
void expectTheJsonCornellBox(const std::string& out, const std::string& file, const std::string& camera,
                             const std::string& json = "cornell-box.json") {
    fs::remove_all(out);
    const std::string settings = " --patches 300 --form-factors rays --quiet";
    ASSERT_EQ(run(cat("solve ", scenePath(json), settings, " --out ", out, "/json")).status, 0);
    const CommandResult solved = run(cat("solve ", scenePath(file), settings, " --out ", out, "/file"));
    ASSERT_EQ(solved.status, 0) << solved.output;
    const auto [difference, where] = largestDifference(reportOf(out + "/json"), reportOf(out + "/file"));
    EXPECT_LT(difference, 1e-6) << where;
    EXPECT_EQ(reportOf(out + "/file")["objects"].size(), reportOf(out + "/json")["objects"].size());
    const std::string view = " --integrator radiosity --resolution 64x64 --quiet";
    ASSERT_EQ(
        run(cat("render ", scenePath(json), " --solution ", out, "/json", view, " --out ", out, "/json.exr")).status,
        0);
    const CommandResult image =
        run(cat("render ", scenePath(file), " --solution ", out, "/file", view, camera, " --out ", out, "/file.exr"));
    ASSERT_EQ(image.status, 0) << image.output;
    const ImageError e = compareBlurred(readLinearImage(out + "/file.exr"), readLinearImage(out + "/json.exr"));
    EXPECT_LT(e.pooledL1, 1e-3) << "pooled L1 after a 5x5 blur";
}

}  // namespace

// Blender's glTF of the Cornell box (quads split into triangle pairs, metres, float positions,
// emission as emissiveFactor x KHR_materials_emissive_strength, the camera as a node) gives the JSON
// scene's report: the same 19 objects by name, areas, powers and radiosities within 1e-6 (the file
// holds positions in float), and the same image from its own camera.
TEST(Import, BlenderGltfOfTheCornellBoxSolvesAndRendersAsTheJsonScene) {
    // From its own camera: a camera node, rotated half a turn about y.
    const std::string out = test::tempDir() + "/import-gltf";
    expectTheJsonCornellBox(out, "blender/cornell-box.glb", "");
    // Written back (the round trip), each of the file's vertices finds the patch corner at its point
    // (0.555f as 0.555, as the reader took it).
    const RoundTrip r = writeGltfRoundTrip(loadScene(scenePath("blender/cornell-box.glb")),
                                           readSolution(out + "/file/solution.bin"), out + "/lit.glb", 0);
    EXPECT_EQ(r.vertices, 76u);
    EXPECT_EQ(r.verticesOffCorners, 0u);
}

// Blender's glTF of cornell-glass solves to the JSON scene's report within 1e-6, the specular
// transport past its balls included: its numbers read as the decimals the floats stand for, the
// balls' centres and radii as the simplest within their vertices' scatter (measured 6.7e-8; read at
// face value, 9.1e-5: seeded paths past the glass followed other ways).
TEST(Import, BlenderGltfOfCornellGlassSolvesToTheJsonReport) {
    expectTheJsonCornellBox(test::tempDir() + "/import-glass-report", "blender/cornell-glass.glb", "",
                            "cornell-glass.json");
}

// Blender's glTF of cornell-glass: the chrome ball (metallic, roughness 0) a mirror, the glass ball
// (KHR_materials_transmission, IOR 1.5 by default) glass, both smooth-shaded UV spheres of 64 x 32
// facets, which the reader takes as the spheres they stand for (every vertex on one sphere, every
// normal radial). Final-gathered from the file's camera, the image is the JSON scene's: measured
// 0.0000 pooled L1 after a 5x5 blur, every region's mean 1.0000 (RMSE 1.4e-5). Read as their facets
// (before 2026-12-07) the mirror ball's mean was 1.031 (the room mirrored in pieces) and the image
// 1.16% off (two seeds of the JSON scene: 0.33%).
TEST(ImportSlow, BlenderGltfOfCornellGlassRendersAsTheJsonScene) {
    const std::string out = test::tempDir() + "/import-glass";
    fs::remove_all(out);
    const std::string view = " --resolution 128x128 --spp 16";
    const CommandResult json =
        run(cat("render ", scenePath("cornell-glass.json"), view, " --quiet --out ", out, "/json.exr"));
    ASSERT_EQ(json.status, 0) << json.output;
    const CommandResult gltf =
        run(cat("render ", scenePath("blender/cornell-glass.glb"), view, " --out ", out, "/glb.exr"));
    ASSERT_EQ(gltf.status, 0) << gltf.output;
    EXPECT_NE(gltf.output.find("specular transport: 2 mirror/glass objects"), std::string::npos) << gltf.output;
    const Image a = readLinearImage(out + "/glb.exr"), b = readLinearImage(out + "/json.exr");
    EXPECT_LT(compareBlurred(a, b).pooledL1, 0.002) << "pooled L1 after a 5x5 blur";
    EXPECT_NE(gltf.output.find("taken as that sphere"), std::string::npos) << gltf.output;
    // Regions of the JSON scene's view (its objects, and the caustic its photons make).
    const Scene scene = loadScene(scenePath("cornell-glass.json"));
    Camera camera = scene.camera;
    camera.width = a.width, camera.height = a.height;
    const PatchSet patches = meshScene(scene, MeshingOptions{});
    const SceneTracer tracer(scene, patches);
    ImageRegions regions = objectRegions(tracer, camera);
    regions.add("caustic", causticMask(tracer, PhotonMap(tracer, {}), regions));
    for (const RegionError& e : compareRegions(a, b, regions)) {
        if (e.pixels < 30) continue;  // the lamp's and the ceiling strips' few pixels
        EXPECT_NEAR(e.ratio, 1.0, 0.005) << e.name;
    }
}

// Blender's glTF and OBJ of the textured Cornell box (scenes/cornell-textured.json: a checker floor
// and a striped back wall, image texture nodes on the base colour, the PNGs embedded in the .glb and
// named by map_Kd beside the OBJ, which has no Kd for them) give the JSON scene's report and radiosity
// view: the same texture coordinates (Blender's v up the image turned back by the exporters) and the
// same patch means. Measured (3,049 patches): glb within 5.1e-7, OBJ within 9e-16.
TEST(Import, BlenderExportsOfTheTexturedCornellBoxSolveAsTheJsonScene) {
    expectTheJsonCornellBox(test::tempDir() + "/import-textured-glb", "blender/cornell-textured.glb", "",
                            "cornell-textured.json");
    expectTheJsonCornellBox(
        test::tempDir() + "/import-textured-obj", "blender/cornell-textured.obj",
        R"( --camera '{"position": [0.278, 0.273, -0.8], "look_at": [0.278, 0.273, 0], "fov_y_deg": 39.3}')",
        "cornell-textured.json");
}

// Blender's OBJ + MTL of the Cornell box (quads kept, metres in decimals, Kd and Ke) gives the JSON
// scene's report (measured: within 1e-15) and, from the JSON's camera given in metres, its image.
TEST(Import, BlenderObjOfTheCornellBoxSolvesAndRendersAsTheJsonScene) {
    // OBJ has no camera: the JSON's, in metres.
    expectTheJsonCornellBox(
        test::tempDir() + "/import-obj", "blender/cornell-box.obj",
        R"( --camera '{"position": [0.278, 0.273, -0.8], "look_at": [0.278, 0.273, 0], "fov_y_deg": 39.3}')");
}

// An MTL's mirror (illum 3) and glass (illum 7, Ni) become ours: a mirror quad facing a lit wall and a
// glass slab solve with specular transport; an OBJ whose material library is missing is refused,
// since every lamp would go dark.
TEST(Import, ObjMaterialsMapToMirrorAndGlassAndAMissingLibraryIsRefused) {
    const std::string dir = test::tempDir() + "/import-obj-materials";
    fs::create_directories(dir);
    std::ofstream(dir + "/room.mtl") << "newmtl lamp\nKd 0.5 0.5 0.5\nKe 10 10 10\nillum 1\n"
                                        "newmtl chrome\nKs 0.9 0.9 0.9\nNs 1000\nillum 3\n"
                                        "newmtl glass\nNi 1.5\nillum 7\n";
    const std::string quads =
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
        "v 0 0 1\nv 0 1 1\nv 1 1 1\nv 1 0 1\n"
        "v 0 0 2\nv 1 0 2\nv 1 1 2\nv 0 1 2\n";
    std::ofstream(dir + "/room.obj") << "mtllib room.mtl\n"
                                     << quads
                                     << "o lamp\nusemtl lamp\nf 1 2 3 4\n"
                                        "o mirror\nusemtl chrome\nf 5 6 7 8\n"
                                        "o pane\nusemtl glass\nf 9 10 11 12\n";
    const CommandResult r = run(cat("solve ", dir, "/room.obj --out ", dir, "/out --patches 50"));
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_EQ(r.output.find("no mirrors or glass"), std::string::npos) << r.output;
    const nlohmann::json report = reportOf(dir + "/out");
    for (const char* name : {"lamp", "mirror", "pane"}) EXPECT_TRUE(report["objects"].contains(name)) << name;
    // The mirror and the glass hold no radiosity of their own: B = 0 on specular patches.
    EXPECT_EQ(report["objects"]["mirror"]["radiosity_mean"][0].get<double>(), 0.0);
    EXPECT_EQ(report["objects"]["pane"]["radiosity_mean"][0].get<double>(), 0.0);
    EXPECT_GT(report["objects"]["lamp"]["emitted_power_w"][0].get<double>(), 0.0);

    std::ofstream(dir + "/lost.obj") << "mtllib nowhere.mtl\n" << quads << "usemtl lamp\nf 1 2 3 4\n";
    const CommandResult lost = run(cat("solve ", dir, "/lost.obj --out ", dir, "/lost"));
    EXPECT_NE(lost.status, 0);
    EXPECT_NE(lost.output.find("lost.obj: its material library (mtllib) cannot be read"), std::string::npos)
        << lost.output;
    EXPECT_FALSE(fs::exists(dir + "/lost"));
}

// A JSON scene's mesh object may name a glTF or OBJ file and keep its materials ("materials":
// "from-file"): its parts are the file's objects, named "<object>/<part>", and solve as the file does
// alone. Without it a glTF's triangles, all of them, take the object's one material.
TEST(Import, AJsonMeshObjectTakesAFilesObjectsAndMaterials) {
    const std::string dir = test::tempDir() + "/import-from-file";
    fs::remove_all(dir);
    fs::create_directories(dir);
    const std::string settings = " --patches 300 --form-factors rays --quiet";
    ASSERT_EQ(run(cat("solve ", scenePath("blender/cornell-box.obj"), settings, " --out ", dir, "/obj")).status, 0);
    const std::string scene = dir + "/scene.json";
    std::ofstream(scene) << R"({"materials": {"grey": {"type": "diffuse", "reflectance": 0.5}}, "objects": [)"
                         << R"({"name": "box", "type": "mesh", "materials": "from-file", "file": ")"
                         << scenePath("blender/cornell-box.obj") << R"("}]})";
    const CommandResult r = run(cat("solve ", scene, settings, " --out ", dir, "/json"));
    ASSERT_EQ(r.status, 0) << r.output;
    const nlohmann::json alone = reportOf(dir + "/obj"), within = reportOf(dir + "/json");
    ASSERT_EQ(alone["objects"].size(), within["objects"].size());
    for (const auto& [name, object] : alone["objects"].items()) {
        ASSERT_TRUE(within["objects"].contains("box/" + name)) << name;
        for (const char* key : {"area_m2", "radiosity_mean", "absorbed_power_w"}) {
            const nlohmann::json &a = object[key], &b = within["objects"]["box/" + name][key];
            for (size_t c = 0; c < (a.is_array() ? a.size() : 1); ++c) {
                const double u = a.is_array() ? a[c].get<double>() : a.get<double>();
                const double v = b.is_array() ? b[c].get<double>() : b.get<double>();
                EXPECT_NEAR(v, u, 1e-6 * std::abs(u)) << name << " " << key;
            }
        }
    }
    // The glTF's geometry alone, as one grey object: its area is the box's.
    std::ofstream(dir + "/shell.json")
        << R"({"materials": {"grey": {"type": "diffuse", "reflectance": 0.5}}, )"
        << R"("objects": [{"name": "shell", "type": "mesh", "material": "grey", "file": ")"
        << scenePath("blender/cornell-box.glb") << R"("}]})";
    const CommandResult shell =
        run(cat("solve ", dir, "/shell.json --patches 300 --form-factors rays --quiet --out ", dir, "/shell"));
    ASSERT_EQ(shell.status, 0) << shell.output;
    double area = 0;
    for (const auto& [name, object] : alone["objects"].items()) area += object["area_m2"].get<double>();
    EXPECT_NEAR(reportOf(dir + "/shell")["objects"]["shell"]["area_m2"].get<double>(), area, 1e-6 * area);
    // "from-file" needs a file that has materials; and it is that or "material", not both.
    for (const auto& [text, expected] : std::vector<std::pair<std::string, std::string>>{
             {R"("materials": "from-file", "file": "x.ply")", "needs a glTF (.glb, .gltf) or OBJ file"},
             {R"("materials": "from-file", "material": "grey", "file": "x.obj")", "not both"},
             {R"("materials": "mine", "file": "x.obj")", "expected \"from-file\""}}) {
        std::ofstream(dir + "/x.ply") << "ply\nformat ascii 1.0\nend_header\n";
        std::ofstream(dir + "/x.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        std::ofstream(dir + "/bad.json") << R"({"materials": {"grey": {"type": "diffuse", "reflectance": 0.5}}, )"
                                         << R"("objects": [{"name": "m", "type": "mesh", )" << text << "}]}";
        const CommandResult bad = run(cat("solve ", dir, "/bad.json --out ", dir, "/bad"));
        EXPECT_NE(bad.status, 0) << text;
        EXPECT_NE(bad.output.find("objects[0] 'm'"), std::string::npos) << bad.output;
        EXPECT_NE(bad.output.find(expected), std::string::npos) << bad.output;
        EXPECT_FALSE(fs::exists(dir + "/bad"));
    }
}

// What a glTF file holds that the solve cannot honour is refused with the file and what to do; a
// file that is not glTF is refused as such; nothing is written.
TEST(Import, WhatAGltfCannotGiveIsRefusedByName) {
    const std::string dir = test::tempDir() + "/import-refused";
    fs::create_directories(dir);
    // One triangle, its three float positions in a data URI (base64 of 36 bytes).
    const auto gltf = [&](const std::string& name, const std::string& extra, int mode) {
        const float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
        const auto* bytes = reinterpret_cast<const unsigned char*>(xyz);
        static const char* digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        std::string b64;
        for (size_t i = 0; i < sizeof xyz; i += 3) {
            const uint32_t v = uint32_t(bytes[i]) << 16 | uint32_t(bytes[i + 1]) << 8 | bytes[i + 2];
            for (int k = 3; k >= 0; --k) b64 += digits[(v >> (6 * k)) & 63];
        }
        const std::string text = cat(
            R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], )",
            R"("nodes": [{"name": "tri", "mesh": 0}], "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": )",
            mode, R"(, "material": 0}]}], "materials": [{"emissiveFactor": [1, 1, 1]}], )",
            R"("buffers": [{"byteLength": 36, "uri": "data:application/octet-stream;base64,)", b64, R"("}], )",
            R"("bufferViews": [{"buffer": 0, "byteLength": 36}], )",
            R"("accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", )",
            R"("min": [0, 0, 0], "max": [1, 1, 0]}])", extra, "}");
        const std::string path = dir + "/" + name;
        std::ofstream(path) << text;
        return path;
    };
    // The well-formed file solves: the reader is right, so the refusals below are for what they name.
    const std::string good = gltf("good.gltf", "", 4);
    const CommandResult solved = run(cat("solve ", good, " --out ", dir, "/good --quiet"));
    EXPECT_EQ(solved.status, 0) << solved.output;
    // The good file with each (from, to) pair of `edits` replaced once, as `name`.
    const auto variant = [&](const std::string& from, const std::string& name, auto... edits) {
        std::ifstream in(from);
        std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        const std::vector<std::string> pairs{edits...};
        for (size_t k = 0; k + 1 < pairs.size(); k += 2) {
            const size_t at = text.find(pairs[k]);
            EXPECT_NE(at, std::string::npos) << pairs[k];
            if (at != std::string::npos) text.replace(at, pairs[k].size(), pairs[k + 1]);
        }
        const std::string path = dir + "/" + name;
        std::ofstream(path) << text;
        return path;
    };
    struct Case {
        std::string file, expected;
    };
    const std::vector<Case> cases{
        {gltf("lines.gltf", "", 1), "primitive mode 1"},
        {gltf(
             "light.gltf",
             R"(, "extensionsUsed": ["KHR_lights_punctual"], "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point"}]}})",
             4),
         "model each lamp as emissive geometry"},
        {[&] {
             std::ofstream(dir + "/text.glb") << "not a glTF file";
             return dir + "/text.glb";
         }(),
         "not a glTF 2.0 file"},
        // Malformed (issue 17; the fuzzer, tests/fuzz/fuzz_import.cpp, tries many more): a missing
        // accessor, an index past the vertices (the float 1.0's bits read as an index), a buffer file
        // that is not there, and a count far past the buffer's bytes.
        {variant(good, "bad-accessor.gltf", R"("POSITION": 0)", R"("POSITION": 7)"), "accessor 7"},
        {variant(
             good, "bad-index.gltf", R"("mode": 4)", R"("mode": 4, "indices": 1)",
             R"("min": [0, 0, 0], "max": [1, 1, 0]}])",
             R"("min": [0, 0, 0], "max": [1, 1, 0]}, {"bufferView": 0, "byteOffset": 12, "componentType": 5125, "count": 3, "type": "SCALAR"}])"),
         "index 1065353216 past its 3 vertices"},
        {variant(good, "missing-buffer.gltf", R"("uri": "data:application/octet-stream;base64,)",
                 R"("uri": "missing.bin", "_was": ")"),
         "missing.bin"},
        {variant(good, "huge-count.gltf", R"("count": 3)", R"("count": 1000000000)"), "accessor"},
        // Positions that are NaN (every bit set): passed the distance check, and with all of them NaN
        // the scene's box was empty, its extent infinite (found by fuzz_import).
        {variant(good, "nan.gltf", "base64,",
                 "base64,////////////////////////////////////////////////\", \"_was\": \""),
         "is not a finite number"},
    };
    for (const Case& c : cases) {
        const std::string out = dir + "/out-" + fs::path(c.file).stem().string();
        const CommandResult r = run(cat("solve ", c.file, " --out ", out));
        EXPECT_NE(r.status, 0) << c.file;
        EXPECT_NE(r.output.find(c.file), std::string::npos) << r.output;
        EXPECT_NE(r.output.find(c.expected), std::string::npos) << r.output;
        EXPECT_FALSE(fs::exists(out)) << out;
    }
}

// glTF's doubleSided, and our JSON's "double_sided": both faces reflect and emit. In the furnace
// (every surface emits 1 and reflects rho), a panel standing in the middle of the room holds
// B = pi / (1 - rho) on both its faces only if its back reflects and emits as its front does: with
// a one-sided panel (the back black, as the contract has a back face) the room around it falls below
// the closed form. Its back is an object of its own, "panel#back".
TEST(Import, ADoubleSidedPanelKeepsTheFurnaceAndAOneSidedOneDoesNot) {
    const double rho = 0.5, expected = kPi / (1 - rho);
    const auto furnace = [&](bool doubleSided) {
        const std::string panel = cat(R"({"type": "diffuse", "reflectance": )", rho,
                                      R"(, "emission": 1, "double_sided": )", doubleSided ? "true" : "false", "}");
        return test::furnaceCube(
            rho, panel, false,
            R"(, {"name": "panel", "type": "quad", "material": "spec", "vertices": [[0.5,0.1,0.2],[0.5,0.9,0.2],[0.5,0.9,0.8],[0.5,0.1,0.8]]})");
    };
    SolveOptions o;
    o.meshing.targetPatches = 600;
    o.solverSettings.tolerance = 1e-9;
    o.solverSettings.maxIterations = 100000;
    const Scene twoSided = test::sceneFromJson(furnace(true), "double-sided-furnace.json");
    ASSERT_EQ(twoSided.objects.size(), 8u);
    EXPECT_EQ(twoSided.objects[7].name, "panel#back");
    const SolveResult r = solveScene(twoSided, o);
    double worst = 0;
    for (const Rgb& B : r.solution.B) worst = std::max(worst, std::abs(B[0] / expected - 1));
    EXPECT_LT(worst, 0.005) << "furnace with a double-sided panel: B off pi / (1 - rho)";

    const SolveResult one = solveScene(test::sceneFromJson(furnace(false), "one-sided-furnace.json"), o);
    double lowest = 1e300;
    for (const Rgb& B : one.solution.B) lowest = std::min(lowest, B[0] / expected);
    EXPECT_LT(lowest, 0.95) << "a one-sided panel's black back should darken the room";
}
