// The scene as the contract (shared/CONTRACT.md) defines it, validated and converted to metres.
// Geometry keeps each object's local description plus its transform; meshing (mesh/meshing.h)
// turns it into patches. Every field here has already passed validation.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "core/math.h"
#include "mesh/texture.h"

namespace penumbra {

enum class MaterialType { Diffuse, Mirror, Dielectric };

struct Material {
    std::string name;
    MaterialType type = MaterialType::Diffuse;
    Rgb reflectance = Rgb::Zero();    // hemispherical albedo (diffuse) or specular tint (mirror)
    Rgb emission = Rgb::Zero();       // radiance L_e, W sr^-1 m^-2, front face only
    double ior = 1.5;                 // dielectric only
    Rgb transmittance = Rgb::Ones();  // dielectric only
    // Both faces reflect (and emit): diffuse and mirror materials only. The loader adds each such
    // object's back as an object of its own (addBackFaces, scene_loader.cpp); a material without it
    // has a black back face, as the contract has it.
    bool doubleSided = false;
    // Diffuse only: textures multiplying `reflectance` and `emission` (mesh/texture.h), or null.
    std::shared_ptr<const Texture> reflectanceTexture, emissionTexture;
    bool emits() const { return (emission > 0).any(); }
    bool textured() const { return reflectanceTexture || emissionTexture; }
    // Reflectance and emission at texture coordinates `uv`; without coordinates (null), the
    // textures' means.
    Rgb reflectanceAt(const Vec2* uv) const {
        if (!reflectanceTexture) return reflectance;
        return reflectance * (uv ? reflectanceTexture->at(*uv) : reflectanceTexture->mean());
    }
    Rgb emissionAt(const Vec2* uv) const {
        if (!emissionTexture) return emission;
        return emission * (uv ? emissionTexture->at(*uv) : emissionTexture->mean());
    }
};

// Emitters covering less than this share of the surface are small sources: the solve takes their
// light in closed form (solver/radiosity/system.h: smallSources) and the mesher keeps them coarse.
constexpr double kSmallSourceShare = 0.1;

enum class ShapeType { Quad, Triangle, Mesh, Sphere };

// A polygon soup read from a mesh file, in the file's own units (before transform).
struct PolygonSoup {
    std::vector<Vec3> vertices;
    std::vector<std::vector<int>> faces;
    // Texture coordinates of each face's corners, parallel to `faces`; empty when the file has none.
    std::vector<std::vector<Vec2>> faceUv;
};

struct SceneObject {
    std::string name;
    ShapeType type = ShapeType::Quad;
    int material = -1;
    std::vector<Vec3> vertices;  // quad (4) or triangle (3), in metres, world space
    // Quad or triangle: texture coordinates of `vertices` (our JSON scenes default to the unit
    // square: (0, 0) at vertex 0, u towards vertex 1, v towards the last); empty when there are none.
    std::vector<Vec2> uv;
    PolygonSoup mesh;            // mesh: vertices in metres, world space
    std::string file;            // mesh: the resolved path
    Vec3 center = Vec3::Zero();  // sphere: local centre (scene units)
    double radius = 0;           // sphere: local radius (scene units)
    // Local-to-world map in metres (scene units -> metres included). Applied to spheres at meshing.
    Eigen::Affine3d toWorld = Eigen::Affine3d::Identity();
    // Where an object of a glTF file came from (the round trip back out, io/export.h): its node, the
    // primitive of the node's mesh, and the node's world transform in the file's lengths; -1 else.
    int sourceNode = -1, sourcePrimitive = -1;
    Eigen::Affine3d sourceToWorld = Eigen::Affine3d::Identity();
    // Whether the object carries texture coordinates (spheres never do).
    bool hasUv() const {
        return type == ShapeType::Mesh ? !mesh.faceUv.empty() : !uv.empty() && type != ShapeType::Sphere;
    }
};

struct Camera {
    Vec3 position = Vec3::Zero();  // metres
    Vec3 lookAt = Vec3(0, 0, 1);
    Vec3 up = Vec3(0, 1, 0);
    double fovYDeg = 40;
    int width = 512, height = 512;
};

struct Scene {
    std::string path;      // the scene file, as given
    double unitScale = 1;  // metres per scene unit, as the file gives it
    // Lengths inside are held in units of this many metres: 1 for scenes from a millimetre to a
    // thousand kilometres across, else the power of two that makes the scene half a unit to one unit
    // across (exact: every length is the one of the same scene at a normal size times a power of
    // two). Tolerances and ray offsets then follow the scene's size, and a scene of 1e-30 m solves
    // and renders as it does at 1 m. Areas and powers are converted back to m^2 and W at the
    // report, exported positions to metres.
    double metresPerUnit = 1;
    std::vector<Material> materials;
    std::vector<SceneObject> objects;
    bool hasCamera = false;
    Camera camera;
    // Hash of what a solve depends on, to match solutions: the parsed scene without its camera and
    // ignored "_" keys, and the mesh files' bytes (re-indenting the file or moving the camera keeps a
    // solution valid).
    uint64_t fingerprint = 0;
    uint64_t fileFingerprint = 0;  // hash of the scene file's and mesh files' bytes (the bench's caches)

    // Inside lengths per scene unit: what a camera given in scene units is multiplied by.
    double sceneUnit() const { return unitScale / metresPerUnit; }
    // Square metres per inside area unit, which is also watts per inside power unit (radiance has no
    // length in it): what the report's and the log's areas and powers are multiplied by.
    double squareMetresPerUnit() const { return metresPerUnit * metresPerUnit; }
    bool hasEmitter() const;
    bool hasSpecular() const;
    bool hasTextures() const;
    const Material& materialOf(const SceneObject& o) const { return materials[size_t(o.material)]; }
};

// Reads and validates a scene file. Throws Error naming the file, object or field on bad input.
Scene loadScene(const std::string& path);

// Parses a camera given on the command line as JSON ({"position": ..., ...}), in the scene's units.
Camera parseCamera(const std::string& json, const Scene& scene, const std::string& where);

}  // namespace penumbra
