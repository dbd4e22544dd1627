// Wavefront OBJ + MTL scenes, read by tinyobjloader (Debian's libtinyobjloader-dev) and mapped onto
// our scene (docs/import.md): positions in metres, faces as written (quads stay quads), one object per
// `o`/`g` and material, materials from the MTL (Kd, Ke, a mirror by illum 3 or Ns >= 900, glass by
// illum 4/6/7 and Ni). OBJ has no camera: render with --camera.
#pragma once

#include <string>

#include "mesh/scene.h"

namespace penumbra {

// Throws Error naming the file and the shape or material at fault.
Scene loadObjScene(const std::string& path);
// The file's objects and materials as read, before the lengths are normalised (readGltfScene).
Scene readObjScene(const std::string& path);

// Whether `path` names an OBJ file (.obj, any case).
bool isObjPath(const std::string& path);

}  // namespace penumbra
