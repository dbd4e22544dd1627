#include "mesh/gltf_scene.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <set>

#include "core/error.h"
#include "core/log.h"
#include "mesh/scene_detail.h"

namespace penumbra {
namespace {

using namespace scene_detail;

// glTF's thresholds for our three materials (docs/import.md): metallic and smooth is a mirror,
// transmissive is glass, anything else diffuse.
constexpr double kMirrorMetallic = 0.5, kMirrorRoughness = 0.05, kGlassTransmission = 0.5;

// What a number held as a float stands for: the shortest decimal that reads back as the same float
// (0.555f is 0.55500000715 as a double, and stands for 0.555). glTF holds positions as floats and
// exporters write factors from floats (Blender: 0.7300000190734863); read at face value, a box made
// in metres lies 1e-8 off its own numbers, and a seeded stochastic solve (photon paths past glass)
// follows other paths than the same scene written as decimals. Taken as their decimals, the file
// gives the scene it was made from. Changes a number by at most half a float step: what the file
// holds is unchanged.
double floatDecimal(double x) {
    const float f = float(x);
    if (!std::isfinite(f)) return x;
    char text[32];
    const auto written = std::to_chars(text, text + sizeof text, f);
    double d = x;
    if (written.ec == std::errc{}) std::from_chars(text, written.ptr, d);
    return d;
}

// The decimal of fewest significant digits within `tolerance` of x (x itself past 17 digits).
double simplestWithin(double x, double tolerance) {
    for (int digits = 1; digits <= 17; ++digits) {
        char text[40];
        const auto written = std::to_chars(text, text + sizeof text, x, std::chars_format::scientific, digits - 1);
        double d = x;
        if (written.ec == std::errc{}) std::from_chars(text, written.ptr, d);
        if (std::abs(d - x) <= tolerance) return d;
    }
    return x;
}

Vec3 floatDecimal(const Vec3& v) { return Vec3(floatDecimal(v.x()), floatDecimal(v.y()), floatDecimal(v.z())); }

double extensionNumber(const tinygltf::ExtensionMap& extensions, const char* extension, const char* key,
                       double otherwise) {
    const auto it = extensions.find(extension);
    if (it == extensions.end() || !it->second.IsObject() || !it->second.Has(key)) return otherwise;
    const tinygltf::Value& v = it->second.Get(key);
    return v.IsNumber() ? floatDecimal(v.GetNumberAsDouble()) : otherwise;
}

Rgb factor3(const std::vector<double>& v, double otherwise) {
    return v.size() >= 3 ? Rgb(floatDecimal(v[0]), floatDecimal(v[1]), floatDecimal(v[2])) : Rgb::Constant(otherwise);
}

Wrap wrapOf(int mode) {
    switch (mode) {
        case TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE:
            return Wrap::Clamp;
        case TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT:
            return Wrap::Mirror;
        default:
            return Wrap::Repeat;
    }
}

// Texture `index` of the file, as tinygltf decoded its image (PNG or JPEG, 8 or 16 bits: sRGB-encoded
// colour, as glTF has base colour and emissive textures), once per index.
class GltfTextures {
public:
    GltfTextures(const tinygltf::Model& model, const Where& top) : model_(model), top_(top) {}
    std::shared_ptr<const Texture> get(int index) {
        if (const auto it = made_.find(index); it != made_.end()) return it->second;
        const Where w = top_.at("textures").index(size_t(std::max(index, 0)));
        if (index < 0 || size_t(index) >= model_.textures.size()) w.fail("does not exist");
        const tinygltf::Texture& t = model_.textures[size_t(index)];
        if (t.source < 0 || size_t(t.source) >= model_.images.size())
            w.fail(cat("its image ", t.source, " does not exist"));
        const tinygltf::Image& image = model_.images[size_t(t.source)];
        const Where wi = top_.at("images").index(size_t(t.source), image.name.empty() ? image.uri : image.name);
        const int components = image.component, bytes = image.bits / 8;
        if (image.width <= 0 || image.height <= 0 || components < 1 || components > 4 || (bytes != 1 && bytes != 2) ||
            image.image.size() != size_t(image.width) * size_t(image.height) * size_t(components * bytes))
            wi.fail("its pixels could not be decoded (PNG and JPEG images are read)");
        std::vector<float> rgb(size_t(image.width) * size_t(image.height) * 3);
        const double top = bytes == 1 ? 255.0 : 65535.0;
        for (size_t p = 0; p < rgb.size() / 3; ++p)
            for (int c = 0; c < 3; ++c) {
                const size_t at = (p * size_t(components) + size_t(std::min(c, components - 1))) * size_t(bytes);
                const double v = bytes == 1 ? image.image[at] : image.image[at] | (image.image[at + 1] << 8);
                rgb[3 * p + size_t(c)] = float(srgbToLinear(v / top));
            }
        Wrap u = Wrap::Repeat, v = Wrap::Repeat;
        if (t.sampler >= 0 && size_t(t.sampler) < model_.samplers.size())
            u = wrapOf(model_.samplers[size_t(t.sampler)].wrapS), v = wrapOf(model_.samplers[size_t(t.sampler)].wrapT);
        const std::string name = !image.uri.empty() && image.uri.rfind("data:", 0) != 0 ? image.uri
                                 : !image.name.empty()                                  ? image.name
                                                                                        : cat("image", t.source);
        return made_[index] = std::make_shared<const Texture>(name, image.width, image.height, std::move(rgb), u, v);
    }

private:
    const tinygltf::Model& model_;
    Where top_;
    std::map<int, std::shared_ptr<const Texture>> made_;
};

// glTF material -> ours; `notes` collects what is not used, once per kind. `texCoord` is set to the
// coordinate set the textures read (0 without textures).
Material mapMaterial(const tinygltf::Material& g, const std::string& name, const Where& w, std::set<std::string>& notes,
                     GltfTextures& textures, int& texCoord) {
    texCoord = 0;
    Material m;
    m.name = name;
    const auto& pbr = g.pbrMetallicRoughness;
    const Rgb base = factor3(pbr.baseColorFactor, 1.0);
    for (int c = 0; c < 3; ++c)
        if (!(base[c] >= 0 && base[c] <= 1))
            w.at("pbrMetallicRoughness.baseColorFactor").fail(cat("each channel must lie in [0, 1], got ", base[c]));
    const double transmission = extensionNumber(g.extensions, "KHR_materials_transmission", "transmissionFactor", 0);
    if (transmission >= kGlassTransmission) {
        m.type = MaterialType::Dielectric;
        m.ior = extensionNumber(g.extensions, "KHR_materials_ior", "ior", 1.5);
        if (!(m.ior > 0) || m.ior > 10)
            w.at("KHR_materials_ior.ior").fail(cat("index of refraction must lie in (0, 10], got ", m.ior));
        m.transmittance = base;
        if (pbr.baseColorTexture.index >= 0) notes.insert("textures on mirrors and glass are not used");
        return m;
    }
    if (pbr.metallicFactor >= kMirrorMetallic && pbr.roughnessFactor <= kMirrorRoughness) {
        m.type = MaterialType::Mirror;
        m.reflectance = base;
        m.doubleSided = g.doubleSided;
        if (pbr.baseColorTexture.index >= 0) notes.insert("textures on mirrors and glass are not used");
        return m;
    }
    m.type = MaterialType::Diffuse;
    m.reflectance = base;
    m.doubleSided = g.doubleSided;
    if (pbr.metallicFactor >= kMirrorMetallic)
        notes.insert("rough metals (metallicFactor >= 0.5, roughnessFactor > 0.05) are taken as diffuse");
    if (g.extensions.count("KHR_materials_specular") || pbr.metallicFactor > 0)
        notes.insert("the specular layer of diffuse materials (KHR_materials_specular, metallicFactor) is left out");
    const double strength = extensionNumber(g.extensions, "KHR_materials_emissive_strength", "emissiveStrength", 1);
    m.emission = factor3(g.emissiveFactor, 0.0) * strength;
    if (!(m.emission >= 0).all() || !m.emission.allFinite())
        w.at("emissiveFactor").fail("emission must be finite and not negative");
    if (pbr.baseColorTexture.index >= 0) {
        m.reflectanceTexture = textures.get(pbr.baseColorTexture.index);
        texCoord = pbr.baseColorTexture.texCoord;
    }
    if (g.emissiveTexture.index >= 0 && m.emits()) {
        m.emissionTexture = textures.get(g.emissiveTexture.index);
        if (m.reflectanceTexture && g.emissiveTexture.texCoord != texCoord)
            notes.insert(
                "an emissive texture on another coordinate set than the base colour's reads the base colour's");
        else
            texCoord = g.emissiveTexture.texCoord;
    }
    if (pbr.metallicRoughnessTexture.index >= 0 || g.normalTexture.index >= 0 || g.occlusionTexture.index >= 0)
        notes.insert("metallic-roughness, normal and occlusion textures are not used");
    for (const auto* info : {&pbr.baseColorTexture.extensions, &g.emissiveTexture.extensions})
        if (info->count("KHR_texture_transform")) notes.insert("KHR_texture_transform is not applied");
    if (g.alphaMode != "OPAQUE") notes.insert("alphaMode " + g.alphaMode + ": surfaces are taken as opaque");
    if (g.extensions.count("KHR_materials_unlit"))
        notes.insert("KHR_materials_unlit materials are taken as diffuse of their base colour");
    return m;
}

// A node's local transform: its matrix, or translation x rotation x scale.
Eigen::Affine3d localTransform(const tinygltf::Node& n) {
    Eigen::Affine3d t = Eigen::Affine3d::Identity();
    if (n.matrix.size() == 16) {
        Eigen::Matrix4d m;
        for (int c = 0; c < 4; ++c)
            for (int r = 0; r < 4; ++r) m(r, c) = n.matrix[size_t(4 * c + r)];  // column-major
        t.matrix() = m;
        return t;
    }
    if (n.translation.size() == 3) t.translate(Vec3(n.translation[0], n.translation[1], n.translation[2]));
    if (n.rotation.size() == 4)
        t.rotate(Eigen::Quaterniond(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]).normalized());
    if (n.scale.size() == 3) t.scale(Vec3(n.scale[0], n.scale[1], n.scale[2]));
    return t;
}

// The floats or integers of an accessor, as doubles (positions) or indices.
template <typename T>
std::vector<T> readAccessor(const tinygltf::Model& model, int index, int components, const Where& w) {
    if (index < 0 || size_t(index) >= model.accessors.size()) w.fail(cat("accessor ", index, " does not exist"));
    const tinygltf::Accessor& a = model.accessors[size_t(index)];
    if (a.sparse.isSparse) w.fail(cat("accessor ", index, " is sparse, which is not read"));
    if (a.bufferView < 0 || size_t(a.bufferView) >= model.bufferViews.size())
        w.fail(cat("accessor ", index, " has no buffer view"));
    const tinygltf::BufferView& view = model.bufferViews[size_t(a.bufferView)];
    if (view.buffer < 0 || size_t(view.buffer) >= model.buffers.size())
        w.fail(cat("buffer view ", a.bufferView, " has no buffer"));
    const std::vector<unsigned char>& data = model.buffers[size_t(view.buffer)].data;
    const int size = tinygltf::GetComponentSizeInBytes(uint32_t(a.componentType));
    const int stride = a.ByteStride(view);
    if (size <= 0 || stride <= 0) w.fail(cat("accessor ", index, ": unknown component type ", a.componentType));
    const size_t first = view.byteOffset + a.byteOffset;
    if (a.count > 0 && first + (a.count - 1) * size_t(stride) + size_t(size * components) > data.size())
        w.fail(cat("accessor ", index, " reaches past the end of its buffer"));
    std::vector<T> out;
    out.reserve(a.count * size_t(components));
    for (size_t k = 0; k < a.count; ++k)
        for (int c = 0; c < components; ++c) {
            const unsigned char* p = data.data() + first + k * size_t(stride) + size_t(c * size);
            switch (a.componentType) {
                case TINYGLTF_COMPONENT_TYPE_FLOAT: {
                    float f;
                    std::memcpy(&f, p, sizeof f);
                    out.push_back(T(f));
                    break;
                }
                case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
                    out.push_back(T(*p));
                    break;
                case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
                    uint16_t v;
                    std::memcpy(&v, p, sizeof v);
                    out.push_back(T(v));
                    break;
                }
                case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
                    uint32_t v;
                    std::memcpy(&v, p, sizeof v);
                    out.push_back(T(v));
                    break;
                }
                default:
                    w.fail(cat("accessor ", index, ": component type ", a.componentType, " is not read here"));
            }
        }
    return out;
}

// The sphere (centre, radius; world space) a primitive's triangles stand for: at least 48 vertices,
// every one within 1e-4 of the radius from the centre of their box, and every normal (`normals`, the
// file's, in its own frame) within 0.5 degree of the direction out from the centre: a smooth-shaded
// sphere, as Blender's UV and ico spheres are. Taken as the exact sphere its facets approximate (a
// mirror ball's flat facets mirrored the room in pieces); a faceted one, with flat normals, stays a
// mesh.
std::optional<std::pair<Vec3, double>> smoothSphere(const PolygonSoup& soup, const std::vector<double>& normals,
                                                    const Eigen::Affine3d& world) {
    const size_t n = soup.vertices.size();
    if (n < 48 || normals.size() != 3 * n) return std::nullopt;
    Eigen::AlignedBox3d box;
    for (const Vec3& v : soup.vertices) box.extend(v);
    Vec3 centre = box.center();
    double radius = 0, scatter = 0;
    for (const Vec3& v : soup.vertices) radius += (v - centre).norm() / double(n);
    for (const Vec3& v : soup.vertices) scatter = std::max(scatter, std::abs((v - centre).norm() - radius));
    // The simplest numbers the vertices allow: Blender's float trigonometry scatters a UV sphere's
    // vertices 5e-8 about the radius (7 float steps at 0.1 m), and the sphere it was made as, centre
    // (0.175, 0.1005, 0.19) and radius 0.1, lies within that scatter; the mean distance is 1e-7 off.
    for (int c = 0; c < 3; ++c) centre[c] = simplestWithin(centre[c], scatter);
    radius = simplestWithin(radius, scatter);
    if (!(radius > 0)) return std::nullopt;
    const Eigen::Matrix3d normalMatrix = world.linear().inverse().transpose();
    for (size_t k = 0; k < n; ++k) {
        const Vec3 out = soup.vertices[k] - centre;
        if (std::abs(out.norm() - radius) > 1e-4 * radius) return std::nullopt;
        const Vec3 normal = normalMatrix * Vec3(normals[3 * k], normals[3 * k + 1], normals[3 * k + 2]);
        if (!(normal.norm() > 0) || normal.normalized().dot(out / out.norm()) < std::cos(0.5 * kPi / 180))
            return std::nullopt;
    }
    return std::make_pair(centre, radius);
}

}  // namespace

bool isGltfPath(const std::string& path) { return hasExtension(path, {".glb", ".gltf"}); }

namespace {

// Files a glTF names (buffers, images by URI) are read by our readFile: a folder, a device or a pipe
// (/dev/zero, a FIFO) or a file past 2 GiB is refused by name instead of read until memory runs out
// or forever.
bool readNamedFile(std::vector<unsigned char>* out, std::string* err, const std::string& path, void*) {
    try {
        const std::string bytes = readFile(path, "file the glTF names");
        out->assign(bytes.begin(), bytes.end());
        return true;
    } catch (const Error& e) {
        if (err) *err += e.what();
        return false;
    }
}

// The file's model, from its bytes.
void readModel(const std::string& path, const std::string& bytes, tinygltf::Model& model) {
    tinygltf::TinyGLTF reader;
    reader.SetFsCallbacks(
        {&tinygltf::FileExists, &tinygltf::ExpandFilePath, &readNamedFile, &tinygltf::WriteWholeFile, nullptr});
    std::string err, warn;
    const std::string base = std::filesystem::absolute(path).parent_path().string();
    const bool binary = bytes.size() >= 4 && bytes.compare(0, 4, "glTF") == 0;
    const bool ok =
        binary ? reader.LoadBinaryFromMemory(&model, &err, &warn, reinterpret_cast<const unsigned char*>(bytes.data()),
                                             unsigned(bytes.size()), base)
               : reader.LoadASCIIFromString(&model, &err, &warn, bytes.data(), unsigned(bytes.size()), base);
    if (!ok) Where{path, ""}.fail(cat("not a glTF 2.0 file tinygltf can read: ", err.empty() ? warn : err));
    if (!warn.empty()) logInfo(path, ": tinygltf: ", warn);
}

std::vector<Vec3> positionsOf(const tinygltf::Model& model, const tinygltf::Primitive& prim, const Where& wp) {
    const auto position = prim.attributes.find("POSITION");
    if (position == prim.attributes.end()) wp.fail("no POSITION attribute");
    const std::vector<double> xyz = readAccessor<double>(model, position->second, 3, wp);
    std::vector<Vec3> out;
    for (size_t k = 0; k + 2 < xyz.size(); k += 3) out.emplace_back(xyz[k], xyz[k + 1], xyz[k + 2]);
    return out;
}

}  // namespace

void readGltfModel(const std::string& path, tinygltf::Model& model) {
    readModel(path, readFile(path, "glTF file"), model);
}

std::vector<Vec3> gltfPrimitivePositions(const tinygltf::Model& model, int mesh, int primitive,
                                         const std::string& path) {
    const Where w{path, cat("meshes[", mesh, "] primitive ", primitive)};
    if (mesh < 0 || size_t(mesh) >= model.meshes.size() || primitive < 0 ||
        size_t(primitive) >= model.meshes[size_t(mesh)].primitives.size())
        w.fail("does not exist");
    return positionsOf(model, model.meshes[size_t(mesh)].primitives[size_t(primitive)], w);
}

Vec3 gltfWorldPosition(const Eigen::Affine3d& toWorld, const Vec3& local) {
    return floatDecimal(Vec3(toWorld * local));
}

std::vector<std::array<int, 3>> gltfPrimitiveTriangles(const tinygltf::Model& model, int mesh, int primitive,
                                                       const std::string& path) {
    const size_t vertices = gltfPrimitivePositions(model, mesh, primitive, path).size();
    const tinygltf::Primitive& prim = model.meshes[size_t(mesh)].primitives[size_t(primitive)];
    const Where w{path, cat("meshes[", mesh, "] primitive ", primitive)};
    std::vector<uint32_t> indices;
    if (prim.indices >= 0) {
        indices = readAccessor<uint32_t>(model, prim.indices, 1, w);
    } else {
        for (size_t k = 0; k < vertices; ++k) indices.push_back(uint32_t(k));
    }
    std::vector<std::array<int, 3>> out;
    for (size_t k = 0; k + 2 < indices.size(); k += 3) {
        for (size_t c = 0; c < 3; ++c)
            if (indices[k + c] >= vertices) w.fail(cat("index ", indices[k + c], " past its ", vertices, " vertices"));
        out.push_back({int(indices[k]), int(indices[k + 1]), int(indices[k + 2])});
    }
    return out;
}

Scene readGltfScene(const std::string& path) {
    const std::string bytes = readFile(path, "glTF file");
    const Where top{path, ""};
    tinygltf::Model model;
    readModel(path, bytes, model);
    if (!model.lights.empty() ||
        std::count(model.extensionsUsed.begin(), model.extensionsUsed.end(), "KHR_lights_punctual"))
        top.fail(cat(model.lights.size(),
                     " punctual light(s) (KHR_lights_punctual): a point, spot or sun light has no area to solve for; "
                     "model each lamp as emissive geometry (a mesh whose material has an emissiveFactor)"));

    Scene scene;
    scene.path = path;
    scene.fingerprint = fnv1a(bytes);
    scene.fileFingerprint = scene.fingerprint;
    for (const tinygltf::Buffer& b : model.buffers)
        if (!b.uri.empty()) {
            const std::string data(b.data.begin(), b.data.end());
            scene.fingerprint = fnv1a(data, scene.fingerprint);
            scene.fileFingerprint = scene.fingerprint;
        }
    std::set<std::string> notes;

    // Materials as the primitives use them; -1 is glTF's default material (white, metallic and
    // rough: here diffuse of reflectance 1).
    GltfTextures textures(model, top);
    std::map<int, std::pair<int, int>> materialOf;  // glTF index -> ours, its texture coordinate set
    std::set<std::string> materialNames;
    std::vector<std::string> renamedMaterials;  // not logged: the report names objects, not materials
    const auto material = [&](int index, const Where& w) {
        if (const auto it = materialOf.find(index); it != materialOf.end()) return it->second;
        tinygltf::Material g;
        std::string name = "default";
        Where wm = w;
        if (index >= 0) {
            if (size_t(index) >= model.materials.size()) w.fail(cat("material ", index, " does not exist"));
            g = model.materials[size_t(index)];
            name = g.name.empty() ? cat("material", index) : g.name;
            wm = top.at("materials").index(size_t(index), g.name);
        } else {
            g.pbrMetallicRoughness.metallicFactor = 1;
            g.pbrMetallicRoughness.roughnessFactor = 1;
            notes.insert("primitives without a material take glTF's default (white, reflectance 1)");
        }
        name = uniqueName(name, materialNames, renamedMaterials);
        int texCoord = 0;
        scene.materials.push_back(mapMaterial(g, name, wm, notes, textures, texCoord));
        materialOf[index] = {int(scene.materials.size()) - 1, texCoord};
        return materialOf[index];
    };

    std::set<std::string> objectNames;
    std::vector<std::string> renamed;
    const int sceneIndex = model.defaultScene >= 0 ? model.defaultScene : 0;
    if (model.scenes.empty() || size_t(sceneIndex) >= model.scenes.size()) top.fail("the file holds no scene");
    bool cameraFound = false;
    std::set<int> visiting;
    const std::function<void(int, const Eigen::Affine3d&)> visit = [&](int index, const Eigen::Affine3d& parent) {
        if (index < 0 || size_t(index) >= model.nodes.size()) top.fail(cat("node ", index, " does not exist"));
        if (!visiting.insert(index).second) top.fail(cat("node ", index, " is its own ancestor"));
        const tinygltf::Node& node = model.nodes[size_t(index)];
        const Where w = top.at("nodes").index(size_t(index), node.name);
        const Eigen::Affine3d world = parent * localTransform(node);
        if (node.skin >= 0) notes.insert("skins are not applied: meshes are taken in their bind pose");
        if (node.camera >= 0 && !cameraFound && size_t(node.camera) < model.cameras.size()) {
            const tinygltf::Camera& c = model.cameras[size_t(node.camera)];
            if (c.type == "perspective") {
                cameraFound = true;
                Camera& cam = scene.camera;
                cam.position = floatDecimal(Vec3(world * Vec3::Zero()));
                cam.lookAt = cam.position + (world.linear() * Vec3(0, 0, -1)).normalized();
                cam.up = (world.linear() * Vec3(0, 1, 0)).normalized();
                cam.fovYDeg = c.perspective.yfov * 180 / kPi;
                if (!(cam.fovYDeg > 0 && cam.fovYDeg < 180))
                    w.fail(cat("camera yfov ", c.perspective.yfov, " rad is not in (0, pi)"));
                const double aspect = c.perspective.aspectRatio > 0 ? c.perspective.aspectRatio : 1.0;
                cam.height = 512;
                cam.width = std::clamp(int(std::lround(512 * aspect)), 1, 16384);
                scene.hasCamera = true;
            } else {
                notes.insert("orthographic cameras are not used");
            }
        }
        if (node.mesh >= 0) {
            if (size_t(node.mesh) >= model.meshes.size()) w.fail(cat("mesh ", node.mesh, " does not exist"));
            const tinygltf::Mesh& mesh = model.meshes[size_t(node.mesh)];
            for (size_t p = 0; p < mesh.primitives.size(); ++p) {
                const tinygltf::Primitive& prim = mesh.primitives[p];
                const Where wp{path, cat(w.path, " mesh ", node.mesh, mesh.name.empty() ? "" : " '" + mesh.name + "'",
                                         " primitive ", p)};
                if (prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != -1)
                    wp.fail(cat("primitive mode ", prim.mode,
                                " (points, lines or strips and fans): only triangles (mode 4) are read; "
                                "export with triangulated faces"));
                const std::vector<Vec3> local = positionsOf(model, prim, wp);
                const size_t vertices = local.size();
                std::vector<uint32_t> indices;
                if (prim.indices >= 0) {
                    indices = readAccessor<uint32_t>(model, prim.indices, 1, wp);
                } else {
                    for (size_t k = 0; k < vertices; ++k) indices.push_back(uint32_t(k));
                }
                if (indices.size() % 3 != 0 || indices.empty()) wp.fail("no whole triangles");
                PolygonSoup soup;
                for (size_t k = 0; k < vertices; ++k) {
                    soup.vertices.push_back(gltfWorldPosition(world, local[k]));
                    checkCoordinate(soup.vertices.back(), 1, wp);
                }
                for (size_t k = 0; k < indices.size(); k += 3) {
                    for (int c = 0; c < 3; ++c)
                        if (indices[k + size_t(c)] >= vertices)
                            wp.fail(cat("index ", indices[k + size_t(c)], " past its ", vertices, " vertices"));
                    soup.faces.push_back({int(indices[k]), int(indices[k + 1]), int(indices[k + 2])});
                }
                const auto [ours, texCoord] = material(prim.material, wp);
                if (prim.attributes.count("COLOR_0"))
                    notes.insert("vertex colours (COLOR_0, a baked light among them) are not used");
                // Texture coordinates (the set the material's textures read), per face corner.
                const auto uvAttribute = prim.attributes.find(cat("TEXCOORD_", texCoord));
                if (uvAttribute != prim.attributes.end()) {
                    std::vector<double> uv = readAccessor<double>(model, uvAttribute->second, 2, wp);
                    const tinygltf::Accessor& a = model.accessors[size_t(uvAttribute->second)];
                    if (a.normalized) {  // integer coordinates stand for [0, 1]
                        const double most = a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ? 255 : 65535;
                        for (double& x : uv) x /= most;
                    }
                    if (uv.size() != 2 * vertices) wp.fail(cat("TEXCOORD_", texCoord, " has not one pair per vertex"));
                    for (const auto& f : soup.faces) {
                        soup.faceUv.emplace_back();
                        for (int k : f) soup.faceUv.back().emplace_back(uv[2 * size_t(k)], uv[2 * size_t(k) + 1]);
                    }
                } else if (scene.materials[size_t(ours)].textured()) {
                    notes.insert(cat("a textured primitive without TEXCOORD_", texCoord, " takes its textures' mean"));
                }
                // A mirrored transform turns the faces' winding: put it back, so that fronts stay fronts.
                if (world.linear().determinant() < 0) {
                    for (auto& f : soup.faces) std::swap(f[1], f[2]);
                    for (auto& f : soup.faceUv) std::swap(f[1], f[2]);
                }
                SceneObject o;
                std::string name = !node.name.empty() ? node.name : !mesh.name.empty() ? mesh.name : cat("node", index);
                if (mesh.primitives.size() > 1) name += cat("#", p);
                o.name = uniqueName(name, objectNames, renamed);
                o.material = ours;
                o.sourceNode = index, o.sourcePrimitive = int(p), o.sourceToWorld = world;
                const auto normals = prim.attributes.find("NORMAL");
                const std::optional<std::pair<Vec3, double>> ball =
                    normals == prim.attributes.end()
                        ? std::nullopt
                        : smoothSphere(soup, readAccessor<double>(model, normals->second, 3, wp), world);
                if (ball) {
                    o.type = ShapeType::Sphere;
                    o.center = ball->first;
                    o.radius = ball->second;
                    notes.insert(
                        "meshes whose vertices lie on a sphere, with normals pointing out from its centre (a "
                        "smooth-shaded sphere), are taken as that sphere");
                } else {
                    shapeFromSoup(o, std::move(soup), path, wp);
                }
                scene.objects.push_back(std::move(o));
            }
        }
        for (int child : node.children) visit(child, world);
        visiting.erase(index);
    };
    for (int root : model.scenes[size_t(sceneIndex)].nodes) visit(root, Eigen::Affine3d::Identity());
    if (scene.objects.empty()) top.fail("the scene has no meshes");
    logImport(path, renamed, notes);
    return scene;
}

Scene loadGltfScene(const std::string& path) {
    Scene scene = readGltfScene(path);
    normaliseLengths(scene, Where{path, ""});
    // The camera was found in metres; the lengths may since have been scaled (Scene::metresPerUnit).
    scene.camera.position /= scene.metresPerUnit;
    scene.camera.lookAt /= scene.metresPerUnit;
    if (!scene.hasEmitter())
        logWarning(path, ": no material emits light (emissiveFactor): every radiosity will be zero (a black answer)");
    return scene;
}

}  // namespace penumbra
