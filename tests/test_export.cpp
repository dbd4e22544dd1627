// Export of the solved mesh: the glTF reloads (tinygltf), has one colour per vertex, its colours
// are the stated tone mapping of its radiance, and its radiance is the closed form of a floor under
// a lamp (Howell's point-to-rectangle factor) at every floor vertex. The PLY holds the same vertices
// with the sRGB encoding of the same colours.
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>
#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <numeric>

#include "fixtures.h"
#include "io/image_io.h"
#include "io/solution.h"

using namespace penumbra;
namespace fs = std::filesystem;

namespace {

int runCli(const std::string& args) {
    return std::system((std::string(PENUMBRA_EXE) + " " + args + " --quiet").c_str());
}

std::vector<float> vec3Attribute(const tinygltf::Model& model, const tinygltf::Primitive& p, const std::string& name) {
    const auto it = p.attributes.find(name);
    if (it == p.attributes.end()) return {};
    const tinygltf::Accessor& a = model.accessors[size_t(it->second)];
    EXPECT_EQ(a.type, TINYGLTF_TYPE_VEC3) << name;
    EXPECT_EQ(a.componentType, TINYGLTF_COMPONENT_TYPE_FLOAT) << name;
    const tinygltf::BufferView& v = model.bufferViews[size_t(a.bufferView)];
    std::vector<float> out(3 * a.count);
    std::memcpy(out.data(), model.buffers[size_t(v.buffer)].data.data() + v.byteOffset + a.byteOffset,
                out.size() * sizeof(float));
    return out;
}

// Reads a binary glTF with tinygltf, the reader a user's tools would use; says why when it cannot.
::testing::AssertionResult loadGlb(const std::string& path, tinygltf::Model& model) {
    tinygltf::TinyGLTF loader;
    std::string error, warning;
    if (loader.LoadBinaryFromFile(&model, &error, &warning, path)) return ::testing::AssertionSuccess();
    return ::testing::AssertionFailure() << path << ": " << error;
}

}  // namespace

TEST(Export, GltfReloadsWithOneColourPerVertexInItsStatedToneMapping) {
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-box.json";
    const std::string dir = test::tempDir() + "/export";
    fs::remove_all(dir);
    ASSERT_EQ(runCli(cat("solve ", scene, " --out ", dir, " --patches 300 --form-factors rays")), 0);
    ASSERT_EQ(runCli(cat("export ", dir, " --out ", dir, "/scene.glb")), 0);
    ASSERT_EQ(runCli(cat("export ", dir, " --out ", dir, "/scene.ply")), 0);

    tinygltf::Model model;
    ASSERT_TRUE(loadGlb(dir + "/scene.glb", model));
    ASSERT_EQ(model.meshes.size(), 1u);
    const tinygltf::Primitive& p = model.meshes[0].primitives.at(0);
    const std::vector<float> position = vec3Attribute(model, p, "POSITION"),
                             colour = vec3Attribute(model, p, "COLOR_0"),
                             radiance = vec3Attribute(model, p, "_RADIANCE");
    ASSERT_FALSE(position.empty());
    ASSERT_EQ(colour.size(), position.size()) << "one colour per vertex";
    ASSERT_EQ(radiance.size(), position.size());
    const double exposure = model.asset.extras.Get("penumbra").Get("exposure").GetNumberAsDouble();
    ASSERT_GT(exposure, 0);
    for (size_t k = 0; k < colour.size(); ++k) ASSERT_NEAR(colour[k], std::min(1.0, exposure * radiance[k]), 1e-6);

    // Against the solution: the solved patches, in the order the export walks them.
    const SolveResult solution = readSolution(dir + "/solution.bin");
    const PatchSet& patches = solution.patches;
    size_t v = 0;
    for (size_t i = 0; i < patches.size(); ++i) {
        for (int k = 0; k < patches.cornerCount[i]; ++k, ++v) {
            const Rgb L(radiance[3 * v], radiance[3 * v + 1], radiance[3 * v + 2]);
            const Vec3 x(position[3 * v], position[3 * v + 1], position[3 * v + 2]);
            ASSERT_LT((x - patches.corners[i][size_t(k)]).norm(), 1e-6) << "vertex " << v;
            ASSERT_TRUE((L >= 0).all() && L.isFinite().all()) << "vertex " << v;
        }
    }
    ASSERT_EQ(v, position.size() / 3);

    // The PLY: the same vertices, binary little endian x y z (float) red green blue (uchar).
    std::ifstream ply(dir + "/scene.ply", std::ios::binary);
    std::string line, header;
    while (std::getline(ply, line) && line != "end_header") header += line + "\n";
    ASSERT_NE(header.find(cat("element vertex ", position.size() / 3)), std::string::npos) << header;
    ASSERT_NE(header.find("property uchar red"), std::string::npos) << header;
    for (size_t k = 0; k < position.size() / 3; ++k) {
        float xyz[3];
        unsigned char rgb[3];
        ply.read(reinterpret_cast<char*>(xyz), sizeof xyz);
        ply.read(reinterpret_cast<char*>(rgb), sizeof rgb);
        ASSERT_TRUE(ply.good());
        for (int c = 0; c < 3; ++c) {
            ASSERT_EQ(xyz[c], position[3 * k + size_t(c)]);
            ASSERT_NEAR(int(rgb[c]), int(srgb8(exposure * radiance[3 * k + size_t(c)])), 1) << "vertex " << k;
        }
    }
}

TEST(Export, UnknownFormatIsRefusedAndWritesNothing) {
    const std::string dir = test::tempDir() + "/export";
    fs::create_directories(dir);
    EXPECT_NE(runCli(cat("export ", dir, " --out ", dir, "/scene.obj 2>/dev/null")), 0);
    EXPECT_FALSE(fs::exists(dir + "/scene.obj"));
    EXPECT_NE(runCli(cat("export ", test::tempDir(), "/nowhere --out ", dir, "/x.glb 2>/dev/null")), 0);
    EXPECT_FALSE(fs::exists(dir + "/x.glb"));
}

TEST(Export, RadianceIsTheClosedFormUnderALamp) {
    // The floor under a square lamp, nothing in between: at every exported floor vertex the radiance
    // is rho E F(x -> lamp) / pi, F by Howell's point-to-rectangle closed form (test::unshadowedFloor).
    const std::string dir = test::tempDir() + "/export-lamp";
    fs::remove_all(dir);
    const std::string scene = test::writeText("lamp-floor.json", test::lampOverFloor(false));
    ASSERT_EQ(runCli(cat("solve ", scene, " --out ", dir, " --patches 400")), 0);
    ASSERT_EQ(runCli(cat("export ", dir, " --out ", dir, "/floor.glb")), 0);
    tinygltf::Model model;
    ASSERT_TRUE(loadGlb(dir + "/floor.glb", model));
    const tinygltf::Primitive& p = model.meshes.at(0).primitives.at(0);
    const std::vector<float> position = vec3Attribute(model, p, "POSITION"),
                             radiance = vec3Attribute(model, p, "_RADIANCE");
    ASSERT_EQ(radiance.size(), position.size());
    size_t checked = 0;
    double worst = 0;
    for (size_t v = 0; v < position.size() / 3; ++v) {
        const Vec3 x(position[3 * v], position[3 * v + 1], position[3 * v + 2]);
        if (std::abs(x.z()) > 1e-9) continue;  // the lamp's own vertices
        const double expected = test::unshadowedFloor(x) * kInvPi;
        worst = std::max(worst, std::abs(radiance[3 * v] / expected - 1));
        ++checked;
    }
    EXPECT_GT(checked, 300u);
    EXPECT_LT(worst, 0.01) << "worst relative deviation of an exported floor vertex from the closed form";
}

// Images written by OpenEXR (linear EXR), libpng (PNG) and OpenImageIO's module (Radiance HDR)
// read back as written: EXR to the bit (32-bit float), HDR to its shared-exponent precision (8 bits
// of mantissa: 1/256 relative, 1/128 allowed), PNG to the sRGB code it wrote. A half-written file or
// a wrong channel order (B and R swapped) fails here.
TEST(ImageIo, WrittenImagesReadBackAsWritten) {
    const std::string dir = test::tempDir();
    Image image(7, 5);
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) image.set(x, y, Rgb(0.01 + 0.1 * x, 0.5 + y, 3.0 * (x + 1) * (y + 1)));
    writeLinearImage(image, dir + "/a.exr");
    const Image exr = readLinearImage(dir + "/a.exr");
    ASSERT_EQ(exr.width, 7);
    ASSERT_EQ(exr.height, 5);
    EXPECT_EQ(exr.rgb, image.rgb);
    writeLinearImage(image, dir + "/a.hdr");
    const Image hdr = readLinearImage(dir + "/a.hdr");
    ASSERT_EQ(hdr.rgb.size(), image.rgb.size());
    for (size_t k = 0; k < image.rgb.size(); ++k) {
        // RGBE shares the largest channel's exponent: each channel within 1/128 of that channel.
        const size_t p = k - k % 3;
        const float largest = std::max({image.rgb[p], image.rgb[p + 1], image.rgb[p + 2]});
        EXPECT_NEAR(hdr.rgb[k], image.rgb[k], largest / 128) << k;
    }
    std::vector<unsigned char> rgb(3 * 7 * 5);
    for (size_t k = 0; k < rgb.size(); ++k) rgb[k] = static_cast<unsigned char>(k * 7 % 256);
    writeRgb8(dir + "/a.png", 7, 5, rgb);
    const Image png = readLinearImage(dir + "/a.png");
    ASSERT_EQ(png.rgb.size(), rgb.size());
    for (size_t k = 0; k < rgb.size(); ++k) EXPECT_NEAR(png.rgb[k] * 255, rgb[k], 1e-3) << k;
    for (const char* left : {"a.exr", "a.hdr", "a.png"}) EXPECT_TRUE(fs::exists(dir + "/" + left));
    // A grey EXR (one Y channel) whose data window does not start at the origin: Y in each channel.
    {
        const Imath::Box2i window(Imath::V2i(2, 3), Imath::V2i(5, 4));  // 4 x 2 pixels
        Imf::Header header(window, window);
        header.channels().insert("Y", Imf::Channel(Imf::FLOAT));
        std::vector<float> grey = {1, 2, 3, 4, 5, 6, 7, 8};
        Imf::FrameBuffer frame;
        frame.insert("Y", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(grey.data() - 2 - 3 * 4), sizeof(float),
                                     4 * sizeof(float)));
        Imf::OutputFile out((dir + "/grey.exr").c_str(), header);
        out.setFrameBuffer(frame);
        out.writePixels(2);
    }
    const Image grey = readLinearImage(dir + "/grey.exr");
    ASSERT_EQ(grey.width, 4);
    ASSERT_EQ(grey.height, 2);
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 4; ++x)
            for (int c = 0; c < 3; ++c) EXPECT_EQ(grey.at(x, y)[c], 1 + x + 4 * y) << x << " " << y << " " << c;
    EXPECT_THROW(readLinearImage(dir + "/missing.exr"), Error);
    EXPECT_THROW(readLinearImage(dir + "/missing.png"), Error);
}

namespace {

// Adds `values` (float, `components` each) to buffer 0 as a new accessor; returns its index.
int addAccessor(tinygltf::Model& model, const std::vector<float>& values, int components, int type) {
    auto& data = model.buffers[0].data;
    const size_t offset = data.size();
    data.resize(offset + values.size() * sizeof(float));
    std::memcpy(data.data() + offset, values.data(), values.size() * sizeof(float));
    tinygltf::BufferView view;
    view.buffer = 0, view.byteOffset = offset, view.byteLength = values.size() * sizeof(float);
    model.bufferViews.push_back(view);
    tinygltf::Accessor a;
    a.bufferView = int(model.bufferViews.size()) - 1;
    a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    a.count = values.size() / size_t(components);
    a.type = type;
    if (components == 3) {
        a.minValues = {1e30, 1e30, 1e30}, a.maxValues = {-1e30, -1e30, -1e30};
        for (size_t k = 0; k < values.size(); ++k) {
            a.minValues[k % 3] = std::min(a.minValues[k % 3], double(values[k]));
            a.maxValues[k % 3] = std::max(a.maxValues[k % 3], double(values[k]));
        }
    }
    model.accessors.push_back(a);
    return int(model.accessors.size()) - 1;
}

// A user's glTF of test::lampOverFloor: the floor a mesh of 8 x 8 quads (two triangles each) placed by
// two nodes, "floor" and "floor-east" (2 m along x), and the lamp, all children of a node "room"
// lifted 1 m and put back by its children; a diffuse floor of base colour 0.5, a black lamp emitting
// 1 x strength 10.
void writeUsersGltf(const std::string& path) {
    tinygltf::Model model;
    model.asset.version = "2.0";
    model.buffers.resize(1);
    const auto mesh = [&](const std::vector<float>& xyz, const std::vector<float>& indices, int material,
                          const std::string& name) {
        tinygltf::Primitive p;
        p.attributes["POSITION"] = addAccessor(model, xyz, 3, TINYGLTF_TYPE_VEC3);
        std::vector<uint32_t> idx(indices.begin(), indices.end());
        auto& data = model.buffers[0].data;
        const size_t offset = data.size();
        data.resize(offset + idx.size() * 4);
        std::memcpy(data.data() + offset, idx.data(), idx.size() * 4);
        tinygltf::BufferView view;
        view.buffer = 0, view.byteOffset = offset, view.byteLength = idx.size() * 4;
        model.bufferViews.push_back(view);
        tinygltf::Accessor a;
        a.bufferView = int(model.bufferViews.size()) - 1;
        a.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
        a.count = idx.size();
        a.type = TINYGLTF_TYPE_SCALAR;
        model.accessors.push_back(a);
        p.indices = int(model.accessors.size()) - 1;
        p.material = material;
        p.mode = TINYGLTF_MODE_TRIANGLES;
        tinygltf::Mesh m;
        m.name = name;
        m.primitives.push_back(p);
        model.meshes.push_back(m);
    };
    std::vector<float> floor, floorIndices;
    for (int j = 0; j <= 8; ++j)
        for (int i = 0; i <= 8; ++i) floor.insert(floor.end(), {-1 + i / 4.0f, -1 + j / 4.0f, 0});
    for (int j = 0; j < 8; ++j)
        for (int i = 0; i < 8; ++i) {
            const float a = float(9 * j + i), b = a + 1, c = a + 10, d = a + 9;
            floorIndices.insert(floorIndices.end(), {a, b, c, a, c, d});
        }
    mesh(floor, floorIndices, 0, "floor grid");
    mesh({-0.1f, -0.1f, 1, -0.1f, 0.1f, 1, 0.1f, 0.1f, 1, 0.1f, -0.1f, 1}, {0, 1, 2, 0, 2, 3}, 1, "lamp square");
    tinygltf::Material white, lamp;
    white.name = "white";
    white.pbrMetallicRoughness.baseColorFactor = {0.5, 0.5, 0.5, 1};
    white.pbrMetallicRoughness.metallicFactor = 0;
    lamp.name = "lamp";
    lamp.pbrMetallicRoughness.baseColorFactor = {0, 0, 0, 1};
    lamp.pbrMetallicRoughness.metallicFactor = 0;
    lamp.emissiveFactor = {1, 1, 1};
    tinygltf::Value::Object strength;
    strength["emissiveStrength"] = tinygltf::Value(10.0);
    lamp.extensions["KHR_materials_emissive_strength"] = tinygltf::Value(strength);
    model.extensionsUsed.push_back("KHR_materials_emissive_strength");
    model.materials = {white, lamp};
    tinygltf::Node room, floorNode, eastNode, lampNode;
    room.name = "room", room.translation = {0, 0, 1}, room.children = {1, 2, 3};
    floorNode.name = "floor", floorNode.mesh = 0, floorNode.translation = {0, 0, -1};
    eastNode.name = "floor-east", eastNode.mesh = 0, eastNode.translation = {2, 0, -1};
    lampNode.name = "lamp", lampNode.mesh = 1, lampNode.translation = {0, 0, -1};
    model.nodes = {room, floorNode, eastNode, lampNode};
    tinygltf::Scene scene;
    scene.nodes = {0};
    model.scenes = {scene};
    model.defaultScene = 0;
    tinygltf::TinyGLTF writer;
    ASSERT_TRUE(writer.WriteGltfSceneToFile(&model, path, true, true, false, true));
}

}  // namespace

// The round trip (issue 17): a user's glTF solved and exported comes back as the user's file, with
// the light on its own vertices. Same nodes by name, in order, with the same vertex counts; the mesh
// two nodes shared copied for the second (each is lit on its own); the floor's material unlit, the
// lamp's not; and at every floor vertex COLOR_0 / exposure = E / pi, the irradiance the lamp gives
// there in closed form (Howell's point-to-rectangle factor), _RADIANCE = 0.5 E / pi. The file then
// reads in again as a scene of the same objects.
TEST(Export, RoundTripGivesTheUsersGltfBackLitOnItsOwnVertices) {
    const std::string dir = test::tempDir() + "/round-trip";
    fs::remove_all(dir);
    fs::create_directories(dir);
    const std::string scene = dir + "/users.glb";
    writeUsersGltf(scene);
    ASSERT_EQ(runCli(cat("solve ", scene, " --out ", dir, "/solved --patches 400")), 0);
    // Three stops down: the vertices under the lamp stay below 1.
    ASSERT_EQ(runCli(cat("export ", dir, "/solved --out ", dir, "/lit.glb --exposure -3")), 0);
    // A PLY of the same solve is the patches' (the round trip is glTF only).
    EXPECT_EQ(runCli(cat("export ", dir, "/solved --out ", dir, "/patches.ply")), 0);
    EXPECT_TRUE(fs::exists(dir + "/patches.ply"));

    tinygltf::Model before, after;
    ASSERT_TRUE(loadGlb(scene, before));
    ASSERT_TRUE(loadGlb(dir + "/lit.glb", after));
    ASSERT_EQ(after.nodes.size(), before.nodes.size());
    for (size_t n = 0; n < before.nodes.size(); ++n) EXPECT_EQ(after.nodes[n].name, before.nodes[n].name);
    EXPECT_EQ(after.meshes.size(), before.meshes.size() + 1) << "the floor mesh copied for its second node";
    EXPECT_NE(after.nodes[1].mesh, after.nodes[2].mesh);
    ASSERT_EQ(after.materials.size(), 2u);
    EXPECT_EQ(after.materials[0].extensions.count("KHR_materials_unlit"), 1u);
    EXPECT_EQ(after.materials[1].extensions.count("KHR_materials_unlit"), 0u) << "the lamp stays lit";
    const double exposure = after.asset.extras.Get("penumbra").Get("exposure").GetNumberAsDouble();
    ASSERT_GT(exposure, 0);

    double worst = 0;
    size_t checked = 0;
    for (size_t n : {size_t(1), size_t(2)}) {
        const tinygltf::Primitive& p = after.meshes.at(size_t(after.nodes[n].mesh)).primitives.at(0);
        const std::vector<float> position = vec3Attribute(after, p, "POSITION"),
                                 colour = vec3Attribute(after, p, "COLOR_0"),
                                 radiance = vec3Attribute(after, p, "_RADIANCE");
        ASSERT_EQ(position.size(), 81u * 3) << "the user's 81 vertices, not the patches'";
        ASSERT_EQ(colour.size(), position.size());
        ASSERT_EQ(radiance.size(), position.size());
        const double east = n == 2 ? 2 : 0;
        for (size_t v = 0; v < 81; ++v) {
            const Vec3 x(position[3 * v] + east, position[3 * v + 1], position[3 * v + 2]);
            const double light = test::unshadowedFloor(x) / (0.5 * kPi);  // E / pi
            if (light * exposure >= 1) continue;                          // clipped at 1
            worst = std::max(worst, std::abs(colour[3 * v] / exposure / light - 1));
            worst = std::max(worst, std::abs(radiance[3 * v] / (0.5 * light) - 1));
            ++checked;
        }
    }
    EXPECT_GT(checked, 150u);
    EXPECT_LT(worst, 0.01) << "worst relative deviation of a vertex's light from the closed form";
    std::printf("round trip: %zu vertices, worst relative deviation %.5f\n", checked, worst);

    const Scene again = loadScene(dir + "/lit.glb");
    ASSERT_EQ(again.objects.size(), 3u);
    EXPECT_EQ(again.objects[0].name, "floor");
    EXPECT_EQ(again.objects[1].name, "floor-east");
    EXPECT_EQ(again.objects[2].name, "lamp");
}

// Export of a JSON scene's solve with --geometry scene is refused by name: there is no file of the
// user's to give back.
TEST(Export, RoundTripOfAJsonSceneIsRefused) {
    const std::string dir = test::tempDir() + "/round-trip-json";
    fs::remove_all(dir);
    const std::string scene = test::writeText("lamp-floor-json.json", test::lampOverFloor(false));
    ASSERT_EQ(runCli(cat("solve ", scene, " --out ", dir, " --patches 100")), 0);
    EXPECT_NE(runCli(cat("export ", dir, " --out ", dir, "/x.glb --geometry scene")), 0);
    EXPECT_FALSE(fs::exists(dir + "/x.glb"));
}

// Issue 18: the patches' export of a scene with a mirror and a glass ball carries them as glTF's own
// materials (a mirror metallic 1, roughness 0, tinted; glass KHR_materials_transmission with
// KHR_materials_ior), in primitives without colours, so that a glTF viewer shows them and not black;
// read back by our importer they are a mirror of the same tint and glass of the same index.
TEST(Export, MirrorsAndGlassGoOutAsGltfMaterialsAndComeBack) {
    const std::string dir = test::tempDir() + "/export-specular";
    fs::remove_all(dir);
    const std::string scene = test::writeText("export-specular.json", R"({
      "materials": {"lamp": {"type": "diffuse", "reflectance": 0, "emission": 10},
                    "floor": {"type": "diffuse", "reflectance": 0.5},
                    "chrome": {"type": "mirror", "reflectance": [0.9, 0.8, 0.7]},
                    "glass": {"type": "dielectric", "ior": 1.33}},
      "objects": [
        {"name": "floor", "type": "quad", "material": "floor", "vertices": [[-1,-1,0],[1,-1,0],[1,1,0],[-1,1,0]]},
        {"name": "lamp", "type": "quad", "material": "lamp", "vertices": [[-0.1,-0.1,1],[-0.1,0.1,1],[0.1,0.1,1],[0.1,-0.1,1]]},
        {"name": "mirror", "type": "quad", "material": "chrome", "vertices": [[0.9,-1,0],[0.9,1,0],[0.9,1,1],[0.9,-1,1]]},
        {"name": "ball", "type": "sphere", "material": "glass", "center": [-0.5, 0, 0.3], "radius": 0.2}]})");
    ASSERT_EQ(runCli(cat("solve ", scene, " --out ", dir, " --patches 200")), 0);
    ASSERT_EQ(runCli(cat("export ", dir, " --out ", dir, "/scene.glb")), 0);

    tinygltf::Model model;
    ASSERT_TRUE(loadGlb(dir + "/scene.glb", model));
    int mirrors = 0, glasses = 0;
    for (const tinygltf::Primitive& p : model.meshes.at(0).primitives) {
        const tinygltf::Material& m = model.materials.at(size_t(p.material));
        if (m.extensions.count("KHR_materials_transmission")) {
            ++glasses;
            EXPECT_DOUBLE_EQ(m.extensions.at("KHR_materials_ior").Get("ior").GetNumberAsDouble(), 1.33);
            EXPECT_EQ(p.attributes.count("COLOR_0"), 0u);
        } else if (m.pbrMetallicRoughness.metallicFactor == 1) {
            ++mirrors;
            EXPECT_EQ(m.pbrMetallicRoughness.roughnessFactor, 0);
            EXPECT_DOUBLE_EQ(m.pbrMetallicRoughness.baseColorFactor[1], 0.8);
            EXPECT_EQ(p.attributes.count("COLOR_0"), 0u);
        } else {
            EXPECT_EQ(p.attributes.count("COLOR_0"), 1u) << "the diffuse patches show their radiance";
        }
    }
    EXPECT_EQ(mirrors, 1);
    EXPECT_EQ(glasses, 1);

    const Scene back = loadScene(dir + "/scene.glb");
    int mirror = 0, glass = 0;
    for (const Material& m : back.materials) {
        if (m.type == MaterialType::Mirror) {
            ++mirror;
            EXPECT_NEAR(m.reflectance[0], 0.9, 1e-12);
            EXPECT_NEAR(m.reflectance[2], 0.7, 1e-12);
        }
        if (m.type == MaterialType::Dielectric) {
            ++glass;
            EXPECT_DOUBLE_EQ(m.ior, 1.33);
        }
    }
    EXPECT_EQ(mirror, 1);
    EXPECT_EQ(glass, 1);
}

// The round trip's lightmaps (`export --lightmap 128`): each primitive's layout on TEXCOORD_1 puts
// its charts (triangles joined by shared vertices, found here from the file alone) in rectangles no
// two of which overlap, inside the image; and a floor texel whose centre lies inside a triangle holds
// the light there, E / pi, as the closed form of the lamp over the floor gives it (decoded from its
// sRGB byte and the stated exposure; within 3%, and 2/255 for the bytes' steps); with
// `--lightmap-holds radiance`, the radiance B / pi = rho E / pi.
TEST(Export, LightmapChartsDoNotOverlapAndHoldTheLightAtTheirPoints) {
    const std::string dir = test::tempDir() + "/lightmap";
    fs::remove_all(dir);
    fs::create_directories(dir);
    const std::string scene = dir + "/users.glb";
    writeUsersGltf(scene);
    ASSERT_EQ(runCli(cat("solve ", scene, " --out ", dir, "/solved --patches 400")), 0);
    // The light E/pi (the floor's radiance over its reflectance, 0.5), or the radiance B/pi.
    for (const auto& [holds, perRadiance] : {std::pair{"light", 2.0}, std::pair{"radiance", 1.0}}) {
        SCOPED_TRACE(holds);
        ASSERT_EQ(runCli(cat("export ", dir, "/solved --out ", dir, "/lit-", holds,
                             ".glb --lightmap 128 --lightmap-holds ", holds)),
                  0);
        tinygltf::Model model;
        ASSERT_TRUE(loadGlb(cat(dir, "/lit-", holds, ".glb"), model));
        const double exposure = model.asset.extras.Get("penumbra").Get("exposure").GetNumberAsDouble();
        const auto decode = [](int byte) {
            const double c = byte / 255.0;
            return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
        };
        size_t texelsChecked = 0;
        double worst = -1, largest = 0;
        for (size_t n : {size_t(1), size_t(2), size_t(3)}) {
            const tinygltf::Primitive& p = model.meshes.at(size_t(model.nodes[n].mesh)).primitives.at(0);
            ASSERT_TRUE(p.extras.Has("penumbra_lightmap")) << model.nodes[n].name;
            const int texture = p.extras.Get("penumbra_lightmap").Get("texture").GetNumberAsInt();
            const tinygltf::Image& image = model.images.at(size_t(model.textures.at(size_t(texture)).source));
            ASSERT_EQ(image.width, 128);
            ASSERT_EQ(image.height, 128);
            const auto it = p.attributes.find("TEXCOORD_1");
            ASSERT_NE(it, p.attributes.end());
            const tinygltf::Accessor& a = model.accessors[size_t(it->second)];
            const tinygltf::BufferView& v = model.bufferViews[size_t(a.bufferView)];
            std::vector<float> uv(2 * a.count);
            std::memcpy(uv.data(), model.buffers[0].data.data() + v.byteOffset + a.byteOffset,
                        uv.size() * sizeof(float));
            const tinygltf::Accessor& ia = model.accessors[size_t(p.indices)];
            const tinygltf::BufferView& iv = model.bufferViews[size_t(ia.bufferView)];
            std::vector<uint32_t> index(ia.count);
            ASSERT_EQ(ia.componentType, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
            std::memcpy(index.data(), model.buffers[0].data.data() + iv.byteOffset + ia.byteOffset, index.size() * 4);
            const std::vector<float> position = vec3Attribute(model, p, "POSITION");
            // Charts: triangles joined by shared vertices; their rectangles in texels, pairwise apart.
            std::vector<int> chart(a.count);
            std::iota(chart.begin(), chart.end(), 0);
            std::function<int(int)> root = [&](int i) {
                return chart[size_t(i)] == i ? i : chart[size_t(i)] = root(chart[size_t(i)]);
            };
            for (size_t t = 0; t + 2 < index.size(); t += 3)
                for (int k = 1; k < 3; ++k) chart[size_t(root(int(index[t + size_t(k)])))] = root(int(index[t]));
            std::map<int, Eigen::AlignedBox2d> boxes;
            for (size_t i = 0; i < a.count; ++i) boxes[root(int(i))].extend(Vec2(uv[2 * i], uv[2 * i + 1]) * 128.0);
            for (const auto& [c, box] : boxes) {
                EXPECT_GE(box.min().minCoeff(), 0);
                EXPECT_LE(box.max().maxCoeff(), 128);
                for (const auto& [d, other] : boxes)
                    if (c < d) {
                        EXPECT_FALSE(box.intersects(other)) << model.nodes[n].name << ": charts overlap";
                    }
            }
            if (n == 3) continue;  // the lamp: its own light is its emission, not checked here
            const double east = n == 2 ? 2 : 0;
            for (size_t t = 0; t + 2 < index.size(); t += 3) {
                std::array<Vec2, 3> q;
                std::array<Vec3, 3> x;
                for (size_t k = 0; k < 3; ++k) {
                    const size_t i = index[t + k];
                    q[k] = Vec2(uv[2 * i], uv[2 * i + 1]) * 128.0;
                    x[k] = Vec3(position[3 * i] + east, position[3 * i + 1], position[3 * i + 2]);
                }
                const double area = (q[1] - q[0]).x() * (q[2] - q[0]).y() - (q[1] - q[0]).y() * (q[2] - q[0]).x();
                for (int py = 0; py < 128; ++py)
                    for (int px = 0; px < 128; ++px) {
                        const Vec2 c(px + 0.5, py + 0.5);
                        const double b1 =
                            ((c - q[0]).x() * (q[2] - q[0]).y() - (c - q[0]).y() * (q[2] - q[0]).x()) / area;
                        const double b2 =
                            ((q[1] - q[0]).x() * (c - q[0]).y() - (q[1] - q[0]).y() * (c - q[0]).x()) / area;
                        if (b1 < 0.01 || b2 < 0.01 || 1 - b1 - b2 < 0.01) continue;
                        const Vec3 point = (1 - b1 - b2) * x[0] + b1 * x[1] + b2 * x[2];
                        const double expected =
                            std::min(1.0, exposure * perRadiance * test::unshadowedFloor(point) * kInvPi);
                        const size_t at = (size_t(py) * 128 + size_t(px)) * size_t(image.component);
                        const double got = decode(image.image[at]);
                        worst = std::max(worst, std::abs(got - expected) - 0.03 * expected - 2.0 / 255);
                        if (expected > 0.05) largest = std::max(largest, std::abs(got / expected - 1));
                        ++texelsChecked;
                    }
            }
        }
        EXPECT_GT(texelsChecked, 2000u);
        EXPECT_LE(worst, 0) << "a texel off the closed form by more than 3% and 2/255";
        std::printf("lightmap (%s): %zu texels, largest relative deviation where the texel > 0.05: %.4f\n", holds,
                    texelsChecked, largest);
    }
}

// A smooth-shaded sphere in a glTF (a UV sphere's vertices on one sphere, its normals radial) is read
// as that sphere; the same vertices with flat normals (each face's own: a faceted ball meant as one)
// stay a mesh.
TEST(Import, ASmoothShadedSphereMeshIsReadAsTheSphere) {
    const std::string dir = test::tempDir() + "/smooth-sphere";
    fs::create_directories(dir);
    for (const bool smooth : {true, false}) {
        tinygltf::Model model;
        model.asset.version = "2.0";
        model.buffers.resize(1);
        // A UV sphere of radius 0.3 about (1, 2, 3): 16 segments, 8 rings; smooth or flat normals.
        const Vec3 centre(1, 2, 3);
        std::vector<float> xyz, normals, indices;
        const auto point = [&](int ring, int segment) {
            const double theta = kPi * ring / 8, phi = 2 * kPi * segment / 16;
            return Vec3(std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi));
        };
        for (int r = 0; r < 8; ++r)
            for (int g = 0; g < 16; ++g) {
                const Vec3 a = point(r, g), b = point(r + 1, g), c = point(r + 1, g + 1), d = point(r, g + 1);
                const Vec3 flat = (a + b + c + d).normalized();
                for (const Vec3* q : {&a, &c, &b, &a, &d, &c}) {
                    const Vec3 p = centre + 0.3 * *q, n = smooth ? *q : flat;
                    xyz.insert(xyz.end(), {float(p.x()), float(p.y()), float(p.z())});
                    normals.insert(normals.end(), {float(n.x()), float(n.y()), float(n.z())});
                }
            }
        tinygltf::Primitive prim;
        prim.attributes["POSITION"] = addAccessor(model, xyz, 3, TINYGLTF_TYPE_VEC3);
        prim.attributes["NORMAL"] = addAccessor(model, normals, 3, TINYGLTF_TYPE_VEC3);
        prim.mode = TINYGLTF_MODE_TRIANGLES;
        tinygltf::Material white;
        white.pbrMetallicRoughness.metallicFactor = 0;
        white.emissiveFactor = {1, 1, 1};
        model.materials.push_back(white);
        prim.material = 0;
        tinygltf::Mesh mesh;
        mesh.primitives.push_back(prim);
        model.meshes.push_back(mesh);
        tinygltf::Node node;
        node.name = "ball";
        node.mesh = 0;
        model.nodes.push_back(node);
        tinygltf::Scene scene;
        scene.nodes = {0};
        model.scenes = {scene};
        model.defaultScene = 0;
        const std::string path = cat(dir, smooth ? "/smooth.glb" : "/flat.glb");
        tinygltf::TinyGLTF writer;
        ASSERT_TRUE(writer.WriteGltfSceneToFile(&model, path, true, true, false, true));
        const Scene read = loadScene(path);
        ASSERT_EQ(read.objects.size(), 1u);
        const SceneObject& o = read.objects[0];
        if (smooth) {
            ASSERT_EQ(o.type, ShapeType::Sphere);
            EXPECT_LT((o.toWorld * o.center - centre).norm(), 1e-6);
            EXPECT_NEAR(o.radius, 0.3, 1e-6);
        } else {
            EXPECT_EQ(o.type, ShapeType::Mesh);
        }
    }
}
