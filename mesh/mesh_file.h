// Reads OBJ, PLY, OFF and STL files through OpenMesh's readers into a polygon soup.
#pragma once

#include <string>

#include "mesh/scene.h"

namespace penumbra {

// Throws Error naming `path` (and `field` for context) when the file is missing, unreadable, or
// holds no faces.
PolygonSoup readPolygonSoup(const std::string& path, const std::string& field);

}  // namespace penumbra
