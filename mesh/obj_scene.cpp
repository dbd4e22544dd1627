#include "mesh/obj_scene.h"

#include <tiny_obj_loader.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "core/log.h"
#include "mesh/scene_detail.h"
#include "mesh/texture.h"

namespace penumbra {
namespace {

using namespace scene_detail;

// MTL -> ours (docs/import.md): illum 3, or Ns >= 900 with some Ks, is a mirror tinted by Ks; illum
// 4, 6 or 7 a dielectric of index Ni; anything else diffuse of reflectance Kd, emitting Ke.
// A map_Kd or map_Ke texture, named relative to the OBJ file (its -clamp option kept).
std::shared_ptr<const Texture> objTexture(const std::string& file, const tinyobj::texture_option_t& option,
                                          const std::string& directory, const Where& w) {
    const Wrap wrap = option.clamp ? Wrap::Clamp : Wrap::Repeat;
    try {
        return readTextureFile((std::filesystem::path(directory) / file).string(), wrap, wrap);
    } catch (const Error& e) {
        w.fail(e.what());
    }
}

// The materials of the OBJ's libraries (mtllib) that give a Kd line. The reader cannot say: it puts
// 0.6 in a Kd left out beside a map_Kd, but only until some earlier material has had a Kd (its flag
// is not reset per material), and Blender leaves Kd out when a texture gives the colour.
std::set<std::string> materialsWithKd(const std::string& objBytes, const std::string& directory) {
    std::set<std::string> out;
    std::istringstream obj(objBytes);
    for (std::string line; std::getline(obj, line);) {
        std::istringstream words(line);
        std::string key, library;
        if (!(words >> key) || key != "mtllib") continue;
        while (words >> library) {
            std::ifstream in(std::filesystem::path(directory) / library);
            std::string current;
            for (std::string l; std::getline(in, l);) {
                std::istringstream w(l);
                std::string k;
                if (!(w >> k)) continue;
                if (k == "newmtl") w >> current;
                if (k == "Kd" && !current.empty()) out.insert(current);
            }
        }
    }
    return out;
}

Material mapMaterial(const tinyobj::material_t& t, const std::string& name, const std::string& directory, bool hasKd,
                     const Where& w, std::set<std::string>& notes) {
    Material m;
    m.name = name;
    const auto rgb = [](const tinyobj::real_t* v) { return Rgb(double(v[0]), double(v[1]), double(v[2])); };
    const auto unit = [&](const Rgb& v, const char* key) {
        for (int c = 0; c < 3; ++c)
            if (!(v[c] >= 0 && v[c] <= 1)) w.at(key).fail(cat("each channel must lie in [0, 1], got ", v[c]));
        return v;
    };
    const Rgb ks = rgb(t.specular);
    if (t.illum == 4 || t.illum == 6 || t.illum == 7) {
        m.type = MaterialType::Dielectric;
        m.ior = double(t.ior);
        if (!(m.ior > 0) || m.ior > 10) w.at("Ni").fail(cat("index of refraction must lie in (0, 10], got ", m.ior));
        return m;
    }
    if (t.illum == 3 || (t.shininess >= 900 && ks.maxCoeff() > 0)) {
        m.type = MaterialType::Mirror;
        m.reflectance = unit(ks, "Ks");
        return m;
    }
    m.type = MaterialType::Diffuse;
    m.reflectance = unit(rgb(t.diffuse), "Kd");
    m.emission = rgb(t.emission);
    if (!(m.emission >= 0).all() || !m.emission.allFinite())
        w.at("Ke").fail("emission must be finite and not negative");
    if (ks.maxCoeff() > 0) notes.insert("the specular colour Ks of diffuse materials is left out");
    if (!t.diffuse_texname.empty()) {
        m.reflectanceTexture = objTexture(t.diffuse_texname, t.diffuse_texopt, directory, w.at("map_Kd"));
        // Blender writes no Kd beside a map_Kd: the texture alone is meant.
        if (!hasKd) {
            m.reflectance = Rgb::Ones();
            notes.insert("map_Kd without Kd: the texture alone gives the reflectance, as Blender writes it");
        }
        if (m.reflectanceTexture->maximum() > 1)
            w.at("map_Kd").fail(
                cat("a reflectance texture's values must lie in [0, 1], it holds ", m.reflectanceTexture->maximum()));
    }
    if (!t.emissive_texname.empty() && m.emits())
        m.emissionTexture = objTexture(t.emissive_texname, t.emissive_texopt, directory, w.at("map_Ke"));
    if (!t.bump_texname.empty() || !t.normal_texname.empty() || !t.specular_texname.empty())
        notes.insert("bump, normal and specular maps are not used");
    return m;
}

}  // namespace

Scene readObjScene(const std::string& path) {
    const std::string bytes = readFile(path, "OBJ file");
    const Where top{path, ""};
    tinyobj::ObjReaderConfig config;
    config.triangulate = false;  // quads stay quads, as our meshing takes them
    config.vertex_color = false;
    config.mtl_search_path = std::filesystem::path(path).parent_path().string();
    tinyobj::ObjReader reader;
    if (!reader.ParseFromFile(path, config)) top.fail(cat("not an OBJ file tinyobjloader can read: ", reader.Error()));
    // A material library that cannot be read would leave every lamp dark: refused.
    const std::string& warning = reader.Warning();
    if (warning.find("not found") != std::string::npos || warning.find("Failed to") != std::string::npos)
        top.fail(cat("its material library (mtllib) cannot be read: ", warning.substr(0, warning.find('\n'))));
    if (!warning.empty()) logInfo(path, ": tinyobjloader: ", warning.substr(0, warning.find('\n')));

    Scene scene;
    scene.path = path;
    scene.fingerprint = fnv1a(bytes);
    std::set<std::string> notes;
    const std::vector<tinyobj::material_t>& mtl = reader.GetMaterials();
    const std::set<std::string> withKd = materialsWithKd(bytes, config.mtl_search_path);
    for (size_t k = 0; k < mtl.size(); ++k) {
        const std::string name = mtl[k].name.empty() ? cat("material", k) : mtl[k].name;
        scene.materials.push_back(mapMaterial(mtl[k], name, config.mtl_search_path, withKd.count(mtl[k].name) > 0,
                                              top.at("newmtl " + name), notes));
        const std::string text = cat(mtl[k].name, mtl[k].illum, mtl[k].ior, mtl[k].shininess);
        scene.fingerprint = fnv1a(text, scene.fingerprint);
    }
    int defaultMaterial = -1;  // faces without a material: diffuse 0.8, as OBJ viewers show them
    const auto fallback = [&] {
        if (defaultMaterial < 0) {
            Material m;
            m.name = "default";
            m.reflectance = Rgb::Constant(0.8);
            scene.materials.push_back(m);
            defaultMaterial = int(scene.materials.size()) - 1;
            notes.insert("faces without a material (usemtl) take a diffuse grey of reflectance 0.8");
        }
        return defaultMaterial;
    };
    scene.fileFingerprint = scene.fingerprint;

    const tinyobj::attrib_t& attrib = reader.GetAttrib();
    const size_t vertices = attrib.vertices.size() / 3;
    std::set<std::string> names;
    std::vector<std::string> renamed;
    for (const tinyobj::shape_t& shape : reader.GetShapes()) {
        if (!shape.lines.indices.empty() || !shape.points.indices.empty())
            notes.insert("lines (l) and points (p) are left out: they have no area");
        // One object per material of the shape, named after the shape (o or g), with the material's
        // name after a '#' when the shape has several.
        std::map<int, PolygonSoup> byMaterial;
        std::map<int, std::map<int, int>> vertexOf;  // per material: file vertex -> soup vertex
        size_t at = 0;
        for (size_t f = 0; f < shape.mesh.num_face_vertices.size(); ++f) {
            const int count = shape.mesh.num_face_vertices[f];
            const int material = f < shape.mesh.material_ids.size() ? shape.mesh.material_ids[f] : -1;
            PolygonSoup& soup = byMaterial[material];
            std::vector<int> face;
            std::vector<Vec2> uv;
            for (int k = 0; k < count; ++k) {
                const int v = shape.mesh.indices[at + size_t(k)].vertex_index;
                const int t = shape.mesh.indices[at + size_t(k)].texcoord_index;
                if (t >= 0 && 2 * size_t(t) + 1 < attrib.texcoords.size())  // OBJ's v runs up the image
                    uv.emplace_back(double(attrib.texcoords[2 * size_t(t)]),
                                    1 - double(attrib.texcoords[2 * size_t(t) + 1]));
                if (v < 0 || size_t(v) >= vertices)
                    top.at(cat("'", shape.name, "'")).fail(cat("a face names vertex ", v + 1, " of ", vertices));
                auto [it, fresh] = vertexOf[material].emplace(v, int(soup.vertices.size()));
                if (fresh)
                    soup.vertices.push_back(Vec3(double(attrib.vertices[3 * size_t(v)]),
                                                 double(attrib.vertices[3 * size_t(v) + 1]),
                                                 double(attrib.vertices[3 * size_t(v) + 2])));
                face.push_back(it->second);
            }
            at += size_t(count);
            if (count >= 3) {
                soup.faces.push_back(std::move(face));
                soup.faceUv.push_back(std::move(uv));
            }
        }
        // Texture coordinates only where every face of the part has them.
        for (auto& [material, soup] : byMaterial)
            for (const auto& uv : soup.faceUv)
                if (uv.size() != soup.faces[size_t(&uv - soup.faceUv.data())].size()) {
                    soup.faceUv.clear();
                    break;
                }
        for (auto& [material, soup] : byMaterial) {
            if (soup.faces.empty()) continue;
            SceneObject o;
            std::string name = shape.name.empty() ? "object" : shape.name;
            if (byMaterial.size() > 1)
                name += "#" + (material >= 0 && size_t(material) < mtl.size() ? mtl[size_t(material)].name
                                                                              : std::string("default"));
            o.name = uniqueName(name, names, renamed);
            o.material = material >= 0 && size_t(material) < mtl.size() ? material : fallback();
            const Where w = top.at(cat("'", o.name, "'"));
            for (const Vec3& v : soup.vertices) checkCoordinate(v, 1, w);
            shapeFromSoup(o, std::move(soup), path, w);
            scene.objects.push_back(std::move(o));
        }
    }
    if (scene.objects.empty()) top.fail("the file holds no faces");
    logImport(path, renamed, notes);
    return scene;
}

Scene loadObjScene(const std::string& path) {
    Scene scene = readObjScene(path);
    normaliseLengths(scene, Where{path, ""});
    if (!scene.hasEmitter())
        logWarning(path, ": no material emits light (Ke): every radiosity will be zero (a black answer)");
    return scene;
}

bool isObjPath(const std::string& path) { return hasExtension(path, {".obj"}); }

}  // namespace penumbra
