// Patches: the flat, contiguous surface elements that the radiosity solver works on. Each patch is
// a planar (or nearly planar) quad or triangle of one scene object; triangles repeat their last
// corner (corner[3] == corner[2]) so every patch is handled as four corners. Lengths in metres.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/math.h"
#include "mesh/scene.h"

namespace penumbra {

struct PatchSet {
    std::vector<std::array<Vec3, 4>> corners;
    std::vector<uint8_t> cornerCount;  // 3 or 4
    std::vector<Vec3> normal;          // unit, front side
    std::vector<Vec3> centroid;
    std::vector<double> area;    // m^2
    std::vector<int> object;     // index into Scene::objects
    std::vector<double> radius;  // smallest sphere about the centroid holding the patch
    // Display mesh: corners index shared vertices, so that radiosity can be interpolated per
    // surface. Vertices are never shared between objects.
    std::vector<std::array<int, 4>> cornerVertex;
    std::vector<Vec3> vertices;
    // Texture coordinates of each patch's corners (mesh/texture.h), where the scene has textures;
    // else empty. Zero on objects without coordinates (SceneObject::hasUv).
    std::vector<std::array<Vec2, 4>> uv;

    size_t size() const { return area.size(); }
    bool isTriangle(size_t i) const { return cornerCount[i] == 3; }
    double boundingRadius(size_t i) const { return radius[i]; }
    // Point at parameters (u, v) in [0,1]^2: bilinear on quads, collapsed (Duffy) on triangles.
    Vec3 pointAt(size_t i, double u, double v) const;
    // |dP/du x dP/dv| at (u, v): the area element of pointAt.
    double jacobian(size_t i, double u, double v) const;
    // Adds one patch and its display vertices (by index into `vertices`), and with `cornerUv` its
    // texture coordinates (given for every patch or for none).
    void add(const std::array<Vec3, 4>& c, int count, int objectIndex, const std::array<int, 4>& vertexIds,
             const std::array<Vec2, 4>* cornerUv = nullptr);
    bool hasUv() const { return !uv.empty(); }
    // Texture coordinates at parameters (u, v), as pointAt places the point (needs hasUv()).
    Vec2 uvAt(size_t i, double u, double v) const;
    // Texture coordinates at a point of the patch (Embree's quad parameters `u`, `v` of a hit on it).
    Vec2 uvAtHit(size_t i, double u, double v) const;
    // Texture coordinates at a point on patch i, as Embree's triangles of it hold the point.
    Vec2 uvAtPoint(size_t i, const Vec3& x) const;
    // Each object's patches, in order, indexed by object (as many as `objects`, or one past the
    // largest object index if that is more).
    std::vector<std::vector<size_t>> byObject(size_t objects = 0) const;
};

struct MeshingOptions {
    int targetPatches = 3000;  // about this many patches in all
    double patchSize = 0;      // if > 0: target edge length in metres, overrides targetPatches
    // The default's floor, per object: a scene of many small objects (the building's 9,553 quads, most
    // of them books) takes one patch for each and leaves its large surfaces the rest; at 3,000 in all
    // its ceilings had one patch a square metre and read 5% dark. An explicit --patches sets it to 0.
    // Four, not three: the building's large surfaces (0.32 m patches, not 0.37 m) missed 1% of a
    // converged reference 0.875 times a solve over 8 seeds, not 1.75, for stages of 6.8-7.9 s.
    int patchesPerObject = 4;
};

// Patch i's mean diffuse reflectance and mean emitted radiance over its area: the material's
// factors, times its textures integrated over the patch (a midpoint rule in the patch's parameters,
// weighted by the area element, with samples no farther apart than half a texel, up to 64 x 64), or
// times their means where the patch has no texture coordinates. Zero for mirrors and glass.
Rgb meanReflectance(const Scene& scene, const PatchSet& patches, size_t i);
Rgb meanEmission(const Scene& scene, const PatchSet& patches, size_t i);

// The number of patches `options` ask of the scene: targetPatches, and at least patchesPerObject
// for each of its objects.
int patchTarget(const Scene& scene, const MeshingOptions& options);

// Meshes every object of the scene (OpenMesh) into patches.
PatchSet meshScene(const Scene& scene, const MeshingOptions& options);

// The axis-aligned box around all patch corners, metres (empty for no patches).
Eigen::AlignedBox3d patchBounds(const PatchSet& patches);

// Total surface area of the scene's objects, m^2 (spheres exactly, before tessellation).
double sceneArea(const Scene& scene);

// A value at each corner of each patch (corner 3 repeats corner 2 on triangles): what the display
// interpolates across a patch.
using CornerValues = std::vector<std::array<Rgb, 4>>;

// Per-corner radiosity for display: the area-weighted mean of the values of the patches of the same
// object that share the corner's vertex and whose normals lie within `creaseDeg` of the patch's.
CornerValues interpolateCorners(const PatchSet& patches, const std::vector<Rgb>& value, double creaseDeg = 30);

}  // namespace penumbra
