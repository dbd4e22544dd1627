#include "io/export.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>
#include <unordered_map>

#include "core/error.h"
#include "io/atomic_file.h"
#include "io/image_io.h"
#include "io/lightmap.h"
#include "mesh/gltf_scene.h"
#include "mesh/mesh_file.h"
#include "render/radiosity_view.h"
#include "solver/tracer.h"

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

int addVec2Accessor(tinygltf::Model& model, const std::vector<Vec2>& values) {
    std::vector<float> flat;
    for (const Vec2& v : values) flat.push_back(float(v.x())), flat.push_back(float(v.y()));
    tinygltf::Accessor a;
    a.bufferView = addView(model, flat.data(), flat.size() * sizeof(float), TINYGLTF_TARGET_ARRAY_BUFFER);
    a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    a.count = values.size();
    a.type = TINYGLTF_TYPE_VEC2;
    model.accessors.push_back(a);
    return int(model.accessors.size()) - 1;
}

int addIndexAccessor(tinygltf::Model& model, const std::vector<uint32_t>& indices) {
    tinygltf::Accessor a;
    a.bufferView =
        addView(model, indices.data(), indices.size() * sizeof(uint32_t), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    a.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    a.count = indices.size();
    a.type = TINYGLTF_TYPE_SCALAR;
    model.accessors.push_back(a);
    return int(model.accessors.size()) - 1;
}

// A new accessor of the elements of accessor `index` taken in the order `from` (element k the old
// element from[k]), bytes as they are: any type, any stride.
int remapAccessor(tinygltf::Model& model, int index, const std::vector<int>& from) {
    const tinygltf::Accessor old = model.accessors.at(size_t(index));
    if (old.bufferView < 0 || old.sparse.isSparse)
        throw Error(cat("accessor ", index, ": sparse or without a buffer view: not copied"));
    const tinygltf::BufferView& view = model.bufferViews.at(size_t(old.bufferView));
    const size_t element = size_t(tinygltf::GetComponentSizeInBytes(uint32_t(old.componentType))) *
                           size_t(tinygltf::GetNumComponentsInType(uint32_t(old.type)));
    const size_t stride = size_t(old.ByteStride(view));
    std::vector<unsigned char> bytes;
    const std::vector<unsigned char>& data = model.buffers.at(size_t(view.buffer)).data;
    for (int k : from) {
        const size_t at = view.byteOffset + old.byteOffset + size_t(k) * stride;
        if (k < 0 || size_t(k) >= old.count || at + element > data.size())
            throw Error(cat("accessor ", index, ": element ", k, " past its end"));
        bytes.insert(bytes.end(), data.begin() + long(at), data.begin() + long(at + element));
    }
    tinygltf::Accessor a = old;
    a.bufferView = addView(model, bytes.data(), bytes.size(), TINYGLTF_TARGET_ARRAY_BUFFER);
    a.byteOffset = 0;
    a.count = from.size();
    model.accessors.push_back(a);
    return int(model.accessors.size()) - 1;
}

// Binary (.glb) unless the name ends in .gltf. Made in memory and written by the checked writer:
// tinygltf's own file writing did not check that the bytes reached the disk.
void writeModel(tinygltf::Model& model, const std::string& path) {
    const bool binary = std::filesystem::path(path).extension() != ".gltf";
    std::ostringstream bytes;
    tinygltf::TinyGLTF writer;
    if (!writer.WriteGltfSceneToStream(&model, bytes, !binary, binary))
        throw Error(cat(path, ": tinygltf could not make the glTF file"));
    writeFileAtomic(path, bytes.str());
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

ExportMesh exportMesh(const PatchSet& patches, const CornerValues& corners, const Scene* scene) {
    ExportMesh m;
    if (scene) m.materials = scene->materials;
    for (size_t i = 0; i < patches.size(); ++i) {
        if (scene) {
            const int material = scene->objects.at(size_t(patches.object[i])).material;
            m.triangleMaterial.insert(m.triangleMaterial.end(), size_t(patches.cornerCount[i] - 2), material);
        }
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
    const int positionAccessor = addVec3Accessor(model, positions, true);
    const int normalAccessor = addVec3Accessor(model, normals, false);
    const int colourAccessor = addVec3Accessor(model, colours, false);
    const int radianceAccessor = addVec3Accessor(model, radiance, false);

    // Unlit: the colours are the light itself, not an albedo to be lit again.
    tinygltf::Material unlit;
    unlit.name = "radiance";
    unlit.pbrMetallicRoughness.baseColorFactor = {1, 1, 1, 1};
    unlit.pbrMetallicRoughness.metallicFactor = 0;  // not a metal to an importer (glTF's default is 1)
    unlit.extensions["KHR_materials_unlit"] = tinygltf::Value(tinygltf::Value::Object());
    model.materials.push_back(unlit);
    model.extensionsUsed.push_back("KHR_materials_unlit");

    // The triangles by what shows them: the radiance (glTF material 0), or a mirror's or glass's own.
    std::map<int, int> gltfMaterialOf;  // our material -> glTF's, mirrors and glass only
    std::map<int, std::vector<uint32_t>> byMaterial;
    for (size_t t = 0; t < mesh.triangles.size(); ++t) {
        int g = 0;
        if (!mesh.triangleMaterial.empty()) {
            const int ours = mesh.triangleMaterial[t];
            const Material& m = mesh.materials.at(size_t(ours));
            if (m.type != MaterialType::Diffuse) {
                if (!gltfMaterialOf.count(ours)) {
                    tinygltf::Material g2;
                    g2.name = m.name;
                    auto& pbr = g2.pbrMetallicRoughness;
                    pbr.roughnessFactor = 0;
                    if (m.type == MaterialType::Mirror) {
                        pbr.metallicFactor = 1;
                        pbr.baseColorFactor = {m.reflectance[0], m.reflectance[1], m.reflectance[2], 1};
                    } else {
                        pbr.metallicFactor = 0;
                        pbr.baseColorFactor = {m.transmittance[0], m.transmittance[1], m.transmittance[2], 1};
                        tinygltf::Value::Object transmission, ior;
                        transmission["transmissionFactor"] = tinygltf::Value(1.0);
                        ior["ior"] = tinygltf::Value(m.ior);
                        g2.extensions["KHR_materials_transmission"] = tinygltf::Value(transmission);
                        g2.extensions["KHR_materials_ior"] = tinygltf::Value(ior);
                        for (const char* e : {"KHR_materials_transmission", "KHR_materials_ior"})
                            if (std::find(model.extensionsUsed.begin(), model.extensionsUsed.end(), e) ==
                                model.extensionsUsed.end())
                                model.extensionsUsed.push_back(e);
                    }
                    model.materials.push_back(g2);
                    gltfMaterialOf[ours] = int(model.materials.size()) - 1;
                }
                g = gltfMaterialOf[ours];
            }
        }
        for (int v : mesh.triangles[t]) byMaterial[g].push_back(uint32_t(v));
    }

    tinygltf::Mesh m;
    m.name = "solved scene";
    for (const auto& [g, indices] : byMaterial) {
        tinygltf::Primitive primitive;
        primitive.attributes["POSITION"] = positionAccessor;
        primitive.attributes["NORMAL"] = normalAccessor;
        if (g == 0) {  // mirrors and glass take no colours: a viewer would tint them by it
            primitive.attributes["COLOR_0"] = colourAccessor;
            primitive.attributes["_RADIANCE"] = radianceAccessor;
        }
        primitive.indices = addIndexAccessor(model, indices);
        primitive.mode = TINYGLTF_MODE_TRIANGLES;
        primitive.material = g;
        m.primitives.push_back(primitive);
    }
    model.meshes.push_back(m);
    tinygltf::Node node;
    node.mesh = 0;
    node.name = "solved scene";
    model.nodes.push_back(node);
    tinygltf::Scene scene;
    scene.nodes.push_back(0);
    model.scenes.push_back(scene);
    model.defaultScene = 0;

    writeModel(model, path);
}

namespace {

// What a vertex of the file shows: the irradiance and the radiance at its point.
struct VertexLight {
    Rgb irradiance = Rgb::Zero(), radiance = Rgb::Zero();
};

// An object's patch corners, each with the light there (the mean over the patches meeting at it).
class CornerLight {
public:
    void add(const Vec3& p, const VertexLight& v) {
        auto [it, fresh] = at_.emplace(key(p), points_.size());
        if (fresh) points_.push_back({p, {}, 0});
        Point& q = points_[it->second];
        q.sum.irradiance += v.irradiance, q.sum.radiance += v.radiance, ++q.count;
    }
    // The light at p: of the corner at p, else of the nearest corner (`exact` false).
    VertexLight at(const Vec3& p, bool& exact) const {
        const auto it = at_.find(key(p));
        size_t best = 0;
        exact = it != at_.end();
        if (exact) {
            best = it->second;
        } else {
            for (size_t k = 1; k < points_.size(); ++k)
                if ((points_[k].p - p).squaredNorm() < (points_[best].p - p).squaredNorm()) best = k;
        }
        if (points_.empty()) return {};
        const Point& q = points_[best];
        return {q.sum.irradiance / q.count, q.sum.radiance / q.count};
    }

private:
    struct Point {
        Vec3 p;
        VertexLight sum;
        int count;
    };
    static std::string key(const Vec3& p) {
        return std::string(reinterpret_cast<const char*>(p.data()), sizeof(double) * 3);
    }
    std::unordered_map<std::string, size_t> at_;
    std::vector<Point> points_;
};

}  // namespace

RoundTrip writeGltfRoundTrip(const Scene& scene, const SolveResult& stored, const std::string& path, double stops,
                             int lightmap, LightmapHolds holds) {
    tinygltf::Model model;
    readGltfModel(scene.path, model);
    if (model.buffers.empty()) model.buffers.resize(1);
    RoundTrip out;

    // Each object's corners with their light: the irradiance there (cornerIrradiance) and the
    // displayed radiance.
    for (const int o : stored.patches.object)
        if (size_t(o) >= scene.objects.size())
            throw Error(cat(scene.path, ": the solution holds objects the scene does not"));
    const CornerValues irradiance = cornerIrradiance(scene, stored.patches, stored.corners);
    std::vector<CornerLight> corners(scene.objects.size());
    for (size_t i = 0; i < stored.patches.size(); ++i)
        for (int k = 0; k < stored.patches.cornerCount[i]; ++k)
            corners[size_t(stored.patches.object[i])].add(
                stored.patches.corners[i][size_t(k)],
                {irradiance[i][size_t(k)], Rgb(stored.corners[i][size_t(k)] * kInvPi)});

    // Each object's primitive, its vertices' light. A mesh placed by several nodes is copied for each
    // but the first.
    std::map<int, int> meshOfNode, users;
    for (const SceneObject& o : scene.objects)
        if (o.sourceNode >= 0) meshOfNode[o.sourceNode] = model.nodes[size_t(o.sourceNode)].mesh;
    for (const auto& [node, mesh] : meshOfNode)
        if (users[mesh]++ > 0) {
            model.meshes.push_back(model.meshes[size_t(mesh)]);
            meshOfNode[node] = model.nodes[size_t(node)].mesh = int(model.meshes.size()) - 1;
            ++out.meshesCopied;
        }
    struct Lit {
        int mesh, primitive;
        size_t object;
        std::vector<Vec3> points;  // the vertices in the scene's inside units
        std::vector<VertexLight> light;
    };
    std::vector<Lit> lit;
    std::vector<double> luminances;
    for (size_t i = 0; i < scene.objects.size(); ++i) {
        const SceneObject& o = scene.objects[i];
        if (o.sourceNode < 0) continue;
        Lit l{meshOfNode[o.sourceNode], o.sourcePrimitive, i, {}, {}};
        for (const Vec3& local : gltfPrimitivePositions(model, l.mesh, l.primitive, scene.path)) {
            bool exact = false;
            l.points.push_back(gltfWorldPosition(o.sourceToWorld, local) / scene.metresPerUnit);
            l.light.push_back(corners[i].at(l.points.back(), exact));
            out.verticesOffCorners += !exact;
            luminances.push_back(luminance(l.light.back().radiance));
        }
        lit.push_back(std::move(l));
    }
    out.nodes = meshOfNode.size();
    out.exposure = exposureScale(luminances, stops);

    std::shared_ptr<const RayScene> rays;
    double diagonal = 0;
    if (lightmap > 0)
        rays = buildRayScene(scene, stored.patches), diagonal = patchBounds(stored.patches).diagonal().norm();
    // What a texel holds at a point of patch i (Embree's parameters u, v): the light E/pi, or the
    // radiance rho(x) E/pi + emission with the texel of the material's textures there.
    const auto texel = [&](size_t i, double u, double v) -> Rgb {
        if (holds == LightmapHolds::Light) return interpolateAt(stored.patches, i, u, v, irradiance[i]) * kInvPi;
        return radianceFromIrradiance(scene, stored.patches, i, u, v, irradiance[i]);
    };
    std::set<int> unlit;
    for (Lit& l : lit) {
        tinygltf::Primitive& prim = model.meshes[size_t(l.mesh)].primitives[size_t(l.primitive)];
        if (lightmap > 0) {
            const LightmapLayout layout =
                layoutLightmap(l.points, gltfPrimitiveTriangles(model, l.mesh, l.primitive, scene.path), lightmap);
            // The light at a point of the surface: of the patch of its object that a short ray along
            // its normal meets, from either side, reaching farther where the file's triangles and our
            // patches part (a quad that is not quite flat, as the Cornell box's left wall: the file
            // folds it along a diagonal, our patches follow its bilinear surface, 1.6 mm apart).
            const std::vector<Rgb> texels = bakeLightmap(layout, l.points, [&](const Vec3& x, const Vec3& n) -> Rgb {
                for (const double reach : {1e-4 * diagonal, 1e-3 * diagonal, 1e-2 * diagonal})
                    for (const double side : {1.0, -1.0}) {
                        const Hit h = rays->intersect(x + side * reach * n, -side * n, 0, 2 * reach, RayView::Patches);
                        if (h.patch >= 0 && size_t(stored.patches.object[size_t(h.patch)]) == l.object)
                            return texel(size_t(h.patch), h.u, h.v);
                    }
                ++out.texelsMissed;
                return Rgb::Zero();
            });
            std::vector<unsigned char> rgb;
            for (const Rgb& t : texels)
                for (int c = 0; c < 3; ++c) rgb.push_back(srgb8(out.exposure * t[c]));
            const std::string png = pngBytes(lightmap, lightmap, rgb);
            tinygltf::Image image;
            image.name = cat(model.meshes[size_t(l.mesh)].name, " lightmap");
            image.mimeType = "image/png";
            image.bufferView = addView(model, png.data(), png.size(), 0);
            model.images.push_back(image);
            tinygltf::Sampler clamp;
            clamp.wrapS = clamp.wrapT = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
            model.samplers.push_back(clamp);
            tinygltf::Texture texture;
            texture.source = int(model.images.size()) - 1;
            texture.sampler = int(model.samplers.size()) - 1;
            model.textures.push_back(texture);
            // The primitive again on the layout's vertices: every attribute copied to them, TEXCOORD_1
            // its place in the image, the triangles on the new vertices.
            for (auto& [name, accessor] : prim.attributes) accessor = remapAccessor(model, accessor, layout.vertexOf);
            prim.attributes["TEXCOORD_1"] = addVec2Accessor(model, layout.uv);
            std::vector<uint32_t> indices;
            for (const auto& t : layout.triangles)
                for (int v : t) indices.push_back(uint32_t(v));
            prim.indices = addIndexAccessor(model, indices);
            std::vector<VertexLight> light;
            for (int v : layout.vertexOf) light.push_back(l.light[size_t(v)]);
            l.light = std::move(light);
            tinygltf::Value::Object note;
            note["texture"] = tinygltf::Value(int(model.textures.size()) - 1);
            note["texCoord"] = tinygltf::Value(1);
            const double density = layout.texelsPerMetre / scene.metresPerUnit;
            note["texels_per_metre"] = tinygltf::Value(density);
            note["holds"] = tinygltf::Value(std::string(
                holds == LightmapHolds::Light ? "min(1, exposure * irradiance / pi), as COLOR_0"
                                              : "min(1, exposure * radiance), the texture and emission baked in"));
            tinygltf::Value::Object extras =
                prim.extras.IsObject() ? prim.extras.Get<tinygltf::Value::Object>() : tinygltf::Value::Object();
            extras["penumbra_lightmap"] = tinygltf::Value(note);
            prim.extras = tinygltf::Value(extras);
            out.texelsPerMetre = out.lightmaps++ ? std::min(out.texelsPerMetre, density) : density;
        }
        prim.attributes["COLOR_0"] = addVec3Accessor(
            model,
            flatten(l.light.size(),
                    [&](size_t k) { return Rgb((out.exposure * l.light[k].irradiance * kInvPi).min(1.0)); }),
            false);
        prim.attributes["_RADIANCE"] =
            addVec3Accessor(model, flatten(l.light.size(), [&](size_t k) { return l.light[k].radiance; }), false);
        ++out.primitives;
        out.vertices += l.light.size();
        if (prim.material >= 0) unlit.insert(prim.material);
    }
    // Diffuse materials (not mirrors, not glass) shown unlit: COLOR_0 is their light.
    for (int m : unlit) {
        tinygltf::Material& material = model.materials[size_t(m)];
        const auto transmission = material.extensions.find("KHR_materials_transmission");
        const bool glass = transmission != material.extensions.end();
        const bool mirror = material.pbrMetallicRoughness.metallicFactor >= 0.5 &&
                            material.pbrMetallicRoughness.roughnessFactor <= 0.05;
        const bool lamp =
            std::any_of(material.emissiveFactor.begin(), material.emissiveFactor.end(), [](double e) { return e > 0; });
        // A lamp stays lit: unlit would drop its emission.
        if (!glass && !mirror && !lamp)
            material.extensions["KHR_materials_unlit"] = tinygltf::Value(tinygltf::Value::Object());
    }
    if (!unlit.empty() && std::find(model.extensionsUsed.begin(), model.extensionsUsed.end(), "KHR_materials_unlit") ==
                              model.extensionsUsed.end())
        model.extensionsUsed.push_back("KHR_materials_unlit");

    tinygltf::Value::Object note;
    note["exposure"] = tinygltf::Value(out.exposure);
    note["COLOR_0"] =
        tinygltf::Value(std::string("min(1, exposure * irradiance / pi), linear: times the base colour, the radiance"));
    note["_RADIANCE"] = tinygltf::Value(std::string("radiance B/pi per vertex, W sr^-1 m^-2, linear"));
    tinygltf::Value::Object extras =
        model.asset.extras.IsObject() ? model.asset.extras.Get<tinygltf::Value::Object>() : tinygltf::Value::Object();
    extras["penumbra"] = tinygltf::Value(note);
    model.asset.extras = tinygltf::Value(extras);

    writeModel(model, path);
    return out;
}

void writePly(const ExportMesh& mesh, const std::string& path, double exposure) {
    std::vector<std::array<unsigned char, 3>> colours;
    for (const Rgb& r : mesh.radiance)
        colours.push_back({srgb8(exposure * r[0]), srgb8(exposure * r[1]), srgb8(exposure * r[2])});
    writeFileAtomic(path, colouredPly(mesh.positions, mesh.triangles, colours));
}

}  // namespace penumbra
