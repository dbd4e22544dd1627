#include "io/export.h"

#include <tiny_gltf.h>

#include <cstring>
#include <filesystem>
#include <sstream>

#include "core/error.h"
#include "io/atomic_file.h"
#include "io/image_io.h"
#include "mesh/mesh_file.h"

namespace penumbra {
namespace {

// Appends `bytes` to the buffer as a new view and returns the view's index.
int addView(tinygltf::Model& model, const void* bytes, size_t size, int target) {
    auto& data = model.buffers[0].data;
    while (data.size() % 4) data.push_back(0);
    const size_t offset = data.size();
    data.resize(offset + size);
    std::memcpy(data.data() + offset, bytes, size);
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = offset;
    view.byteLength = size;
    view.target = target;
    model.bufferViews.push_back(view);
    return int(model.bufferViews.size()) - 1;
}

int addVec3Accessor(tinygltf::Model& model, const std::vector<float>& values, bool bounds) {
    tinygltf::Accessor a;
    a.bufferView = addView(model, values.data(), values.size() * sizeof(float), TINYGLTF_TARGET_ARRAY_BUFFER);
    a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    a.count = values.size() / 3;
    a.type = TINYGLTF_TYPE_VEC3;
    if (bounds && a.count > 0) {
        a.minValues = {1e300, 1e300, 1e300};
        a.maxValues = {-1e300, -1e300, -1e300};
        for (size_t k = 0; k < values.size(); ++k) {
            a.minValues[k % 3] = std::min(a.minValues[k % 3], double(values[k]));
            a.maxValues[k % 3] = std::max(a.maxValues[k % 3], double(values[k]));
        }
    }
    model.accessors.push_back(a);
    return int(model.accessors.size()) - 1;
}

template <class F>
std::vector<float> flatten(size_t count, const F& at) {
    std::vector<float> out;
    out.reserve(3 * count);
    for (size_t i = 0; i < count; ++i)
        for (int c = 0; c < 3; ++c) out.push_back(float(at(i)[c]));
    return out;
}

}  // namespace

ExportMesh exportMesh(const PatchSet& patches, const CornerValues& corners) {
    ExportMesh m;
    for (size_t i = 0; i < patches.size(); ++i) {
        const int base = int(m.positions.size());
        for (int k = 0; k < patches.cornerCount[i]; ++k) {
            m.positions.push_back(patches.corners[i][size_t(k)]);
            m.normals.push_back(patches.normal[i]);
            m.radiance.push_back(corners[i][size_t(k)] * kInvPi);
        }
        m.triangles.push_back({base, base + 1, base + 2});
        if (patches.cornerCount[i] == 4) m.triangles.push_back({base, base + 2, base + 3});
    }
    return m;
}

double exportExposure(const ExportMesh& mesh, double stops) {
    std::vector<double> luminances;
    for (const Rgb& r : mesh.radiance) luminances.push_back(luminance(r));
    return exposureScale(luminances, stops);
}

void writeGltf(const ExportMesh& mesh, const std::string& path, double exposure) {
    tinygltf::Model model;
    model.asset.version = "2.0";
    model.asset.generator = "penumbra";
    tinygltf::Value::Object note;
    note["exposure"] = tinygltf::Value(exposure);
    note["COLOR_0"] = tinygltf::Value(std::string("min(1, exposure * radiance), linear"));
    note["_RADIANCE"] = tinygltf::Value(std::string("radiance B/pi per vertex, W sr^-1 m^-2, linear"));
    tinygltf::Value::Object extras;
    extras["penumbra"] = tinygltf::Value(note);
    model.asset.extras = tinygltf::Value(extras);
    model.buffers.resize(1);

    const size_t n = mesh.positions.size();
    const std::vector<float> positions = flatten(n, [&](size_t i) { return mesh.positions[i]; });
    const std::vector<float> normals = flatten(n, [&](size_t i) { return mesh.normals[i]; });
    const std::vector<float> radiance = flatten(n, [&](size_t i) { return mesh.radiance[i]; });
    const std::vector<float> colours =
        flatten(n, [&](size_t i) { return Rgb((exposure * mesh.radiance[i]).min(1.0)); });
    std::vector<uint32_t> indices;
    for (const auto& t : mesh.triangles)
        for (int v : t) indices.push_back(uint32_t(v));

    tinygltf::Primitive primitive;
    primitive.attributes["POSITION"] = addVec3Accessor(model, positions, true);
    primitive.attributes["NORMAL"] = addVec3Accessor(model, normals, false);
    primitive.attributes["COLOR_0"] = addVec3Accessor(model, colours, false);
    primitive.attributes["_RADIANCE"] = addVec3Accessor(model, radiance, false);
    tinygltf::Accessor index;
    index.bufferView =
        addView(model, indices.data(), indices.size() * sizeof(uint32_t), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    index.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    index.count = indices.size();
    index.type = TINYGLTF_TYPE_SCALAR;
    model.accessors.push_back(index);
    primitive.indices = int(model.accessors.size()) - 1;
    primitive.mode = TINYGLTF_MODE_TRIANGLES;

    // Unlit: the colours are the light itself, not an albedo to be lit again.
    tinygltf::Material material;
    material.name = "radiance";
    material.pbrMetallicRoughness.baseColorFactor = {1, 1, 1, 1};
    material.extensions["KHR_materials_unlit"] = tinygltf::Value(tinygltf::Value::Object());
    model.materials.push_back(material);
    model.extensionsUsed.push_back("KHR_materials_unlit");
    primitive.material = 0;

    tinygltf::Mesh m;
    m.name = "solved scene";
    m.primitives.push_back(primitive);
    model.meshes.push_back(m);
    tinygltf::Node node;
    node.mesh = 0;
    node.name = "solved scene";
    model.nodes.push_back(node);
    tinygltf::Scene scene;
    scene.nodes.push_back(0);
    model.scenes.push_back(scene);
    model.defaultScene = 0;

    // Made in memory and written by the checked writer: tinygltf's own file writing did not check
    // that the bytes reached the disk.
    const bool binary = std::filesystem::path(path).extension() != ".gltf";
    std::ostringstream bytes;
    tinygltf::TinyGLTF writer;
    if (!writer.WriteGltfSceneToStream(&model, bytes, !binary, binary))
        throw Error(cat(path, ": tinygltf could not make the glTF file"));
    writeFileAtomic(path, bytes.str());
}

void writePly(const ExportMesh& mesh, const std::string& path, double exposure) {
    std::vector<std::array<unsigned char, 3>> colours;
    for (const Rgb& r : mesh.radiance)
        colours.push_back({srgb8(exposure * r[0]), srgb8(exposure * r[1]), srgb8(exposure * r[2])});
    writeFileAtomic(path, colouredPly(mesh.positions, mesh.triangles, colours));
}

}  // namespace penumbra
