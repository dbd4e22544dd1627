// glTF 2.0 scenes (.glb, .gltf), read by tinygltf and mapped onto our scene (docs/import.md):
// every node of the default scene with a mesh, its matrix or TRS chain applied, in metres; each
// triangle primitive an object named after its node; materials by their glTF factors (a mirror, a
// dielectric, else diffuse with its emission); the first perspective camera. What is not used is named
// once in the log; what cannot be honoured (other primitive modes, punctual lights) is refused.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "mesh/scene.h"

namespace tinygltf {
class Model;
}

namespace penumbra {

// Reads a glTF file into tinygltf's model (its images decoded), or throws Error naming the file.
void readGltfModel(const std::string& path, tinygltf::Model& model);
// The POSITION values of primitive `primitive` of mesh `mesh`, in the file's own frame (before any
// node's transform); throws Error naming the file and the accessor at fault.
std::vector<Vec3> gltfPrimitivePositions(const tinygltf::Model& model, int mesh, int primitive,
                                         const std::string& path);
// Where the scene reader places a vertex at `local` of a node placed by `toWorld` (metres): its
// coordinates as the decimals the file's floats stand for.
Vec3 gltfWorldPosition(const Eigen::Affine3d& toWorld, const Vec3& local);
// Its triangles, as vertex indices (its index accessor, or the vertices in order without one).
std::vector<std::array<int, 3>> gltfPrimitiveTriangles(const tinygltf::Model& model, int mesh, int primitive,
                                                       const std::string& path);

// Throws Error naming the file and the node, mesh or material at fault.
Scene loadGltfScene(const std::string& path);
// The file's objects (world space, the file's own lengths), materials and camera as read, before the
// lengths are normalised (Scene::metresPerUnit): what a JSON mesh object with "materials": "from-file"
// takes in.
Scene readGltfScene(const std::string& path);

// Whether `path` names a glTF file (.glb or .gltf, any case).
bool isGltfPath(const std::string& path);

}  // namespace penumbra
