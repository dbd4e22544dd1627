// Reads OBJ, PLY, OFF and STL files through OpenMesh's readers into a polygon soup.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "mesh/scene.h"

namespace penumbra {

// Throws Error naming `path` (and `field` for context) when the file is missing, unreadable, or
// holds no faces.
PolygonSoup readPolygonSoup(const std::string& path, const std::string& field);

// Triangles with 8-bit vertex colours as the bytes of a binary PLY, made by OpenMesh's writer in
// memory (the caller writes them with a checked write: io/atomic_file.h).
std::string colouredPly(const std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles,
                        const std::vector<std::array<unsigned char, 3>>& colours);

}  // namespace penumbra
