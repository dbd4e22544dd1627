// Export of a solved scene for other tools: the patches with per-vertex radiance (the corner
// interpolation the views use, B / pi), as glTF 2.0 (tinygltf) or PLY (OpenMesh). Colours are
// tone-mapped with a stated exposure; glTF also keeps the linear radiance in `_RADIANCE`.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "mesh/patches.h"

namespace penumbra {

struct ExportMesh {
    std::vector<Vec3> positions, normals;  // per vertex (patch corners are not shared)
    std::vector<Rgb> radiance;             // per vertex, W sr^-1 m^-2
    std::vector<std::array<int, 3>> triangles;
};

// The mesh of the patches with their radiosity B interpolated to the corners, as radiance B / pi.
ExportMesh exportMesh(const PatchSet& patches, const CornerValues& cornerRadiosity);

// The exposure factor the export uses: middle grey at the log-average vertex luminance, shifted by
// `stops` (as the PNG previews).
double exportExposure(const ExportMesh& mesh, double stops);

// glTF 2.0: binary (.glb) unless the name ends in .gltf. COLOR_0 = min(1, exposure * radiance)
// (linear, as glTF wants), _RADIANCE the radiance itself, an unlit material; the exposure is
// stated in the asset's extras. Written atomically.
void writeGltf(const ExportMesh& mesh, const std::string& path, double exposure);
// PLY with 8-bit sRGB vertex colours of exposure * radiance. Written atomically.
void writePly(const ExportMesh& mesh, const std::string& path, double exposure);

}  // namespace penumbra
