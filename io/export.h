// Export of a solved scene for other tools: the patches with per-vertex radiance (the corner
// interpolation the views use, B / pi), as glTF 2.0 (tinygltf) or PLY (OpenMesh). Colours are
// tone-mapped with a stated exposure; glTF also keeps the linear radiance in `_RADIANCE`.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "mesh/patches.h"
#include "mesh/scene.h"
#include "solver/solve.h"

namespace penumbra {

struct ExportMesh {
    std::vector<Vec3> positions, normals;  // per vertex (patch corners are not shared)
    std::vector<Rgb> radiance;             // per vertex, W sr^-1 m^-2
    std::vector<std::array<int, 3>> triangles;
    // With the scene: each triangle's material (index into `materials`); else empty (all shown by
    // their radiance).
    std::vector<int> triangleMaterial;
    std::vector<Material> materials;
};

// The mesh of the patches with their radiosity B interpolated to the corners, as radiance B / pi;
// with `scene` (the one solved), each triangle's material too.
ExportMesh exportMesh(const PatchSet& patches, const CornerValues& cornerRadiosity, const Scene* scene = nullptr);

// The exposure factor the export uses: middle grey at the log-average vertex luminance, shifted by
// `stops` (as the PNG previews).
double exportExposure(const ExportMesh& mesh, double stops);

// glTF 2.0: binary (.glb) unless the name ends in .gltf. COLOR_0 = min(1, exposure * radiance)
// (linear, as glTF wants), _RADIANCE the radiance itself, an unlit material; the exposure is
// stated in the asset's extras. Mirrors and glass (with the mesh's materials) are primitives of
// their own, without colours, in glTF's materials: a mirror metallic 1, roughness 0, its tint the
// base colour; glass KHR_materials_transmission 1 with KHR_materials_ior, its transmittance the base
// colour (issue 18: a glTF viewer shows them, and our importer maps them back). Written atomically.
void writeGltf(const ExportMesh& mesh, const std::string& path, double exposure);
// The round trip (issue 17): the glTF file `scene` was read from, written again with its own nodes,
// names, materials, UVs and images, each primitive given per vertex
//   COLOR_0 = min(1, exposure x E / pi): the light falling there (E the irradiance at the vertex: the
//             solution's corner radiosity less the patch's mean emission, over its mean reflectance),
//             which a viewer multiplies by the material's base colour (texture included) to show the
//             radiance; the diffuse materials marked KHR_materials_unlit, so that it is not lit again;
//   _RADIANCE = B / pi at the vertex, linear, W sr^-1 m^-2.
// A vertex takes the values of the patch corners at its point (the meshing keeps the file's vertices
// as corners), else of the nearest corner of its object. A mesh used by several nodes is copied for
// each, as each is lit differently. `exposure` as exportExposure, from the vertices' radiance.
//
// With `lightmap` > 0, each primitive also gets a lightmap of lightmap x lightmap texels (io/lightmap.h:
// its own layout on TEXCOORD_1, vertices split where charts meet), each texel the same light as
// COLOR_0 at its point of the surface, interpolated within the patch under it (found by a ray along
// the surface's normal), as an sRGB PNG embedded in the file; the primitive's extras name it:
// {"penumbra_lightmap": {"texture": T, "texCoord": 1, "texels_per_metre": D, "holds": H}}.
// What the texels hold (H): the light, as COLOR_0 (for a renderer that multiplies it by the base
// colour and its texture at their own resolution), or the radiance B/pi = rho(x) E/pi + emission, the
// surface as it looks (its texture baked in at the lightmap's resolution), for an emission slot.
enum class LightmapHolds { Light, Radiance };

struct RoundTrip {
    size_t nodes = 0, primitives = 0, vertices = 0, meshesCopied = 0;
    size_t verticesOffCorners = 0;  // vertices that took the nearest corner (no corner at their point)
    double exposure = 1;
    size_t lightmaps = 0, texelsMissed = 0;  // texels whose ray found no patch of their object (left 0)
    double texelsPerMetre = 0;               // the lowest density of the lightmaps
};
RoundTrip writeGltfRoundTrip(const Scene& scene, const SolveResult& stored, const std::string& path, double stops,
                             int lightmap = 0, LightmapHolds holds = LightmapHolds::Light);

// PLY with 8-bit sRGB vertex colours of exposure * radiance. Written atomically.
void writePly(const ExportMesh& mesh, const std::string& path, double exposure);

}  // namespace penumbra
