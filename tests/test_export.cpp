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
#include <map>
#include <nlohmann/json.hpp>

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
