// The viewer's drawing of a solved scene (needs a current OpenGL 3.3 context): the diffuse patches
// by their interpolated radiance (textured ones by their light times the texels, as the headless
// radiosity view shows them), and the mirrors and glass from the solution, through probes:
//  - a probe per mirror or glass object: a cube map, rendered once from the object's centre (a
//    sphere's centre, else its box's), of the radiance of everything but the object and of its
//    distance from the centre; rendered twice, the second time with the other mirrors and glass
//    drawn through the first probes (a ball seen in the other ball);
//  - per pixel of the object (fragment shader): the ray from the eye meets the exact sphere (or the
//    patch), follows the same walk as the headless radiosity view (solver/tracer.h
//    specularBranches: a mirror reflects its tint; glass splits by Fresnel into reflection and
//    refraction, through a sphere out at the chord's end, refracted again, up to two reflections
//    inside; other glass is taken as a thin slab), and each ray leaving the object finds what it
//    meets in the probe by the stored distances (a search along the ray for where it passes the
//    surface seen from the centre: Szirmay-Kalos et al. 2005, "Approximate ray-tracing on the GPU
//    with distance impostors"), so that the floor under a ball is mirrored where it lies, not as
//    if infinitely far.
#pragma once

#include <memory>
#include <vector>

#include "mesh/patches.h"
#include "mesh/scene.h"
#include "viewer/gl.h"

namespace penumbra {

class SceneDraw {
public:
    // Floats a vertex: position, radiance B/pi (on a textured object the light E/pi, which its
    // textures multiply), normal, texture coordinates.
    static constexpr int kStride = 11;
    // Whether an object is drawn with its textures: a textured diffuse material on an object with
    // texture coordinates (the patches then carry them). Its vertices hold the light E / pi.
    static bool showsTextures(const Scene& scene, const SceneObject& o);
    // `vertices` (kStride floats each), `triangles` (3 indices each) with `triangleObject` the object
    // of each, `edges` the patch outlines (2 indices each). `textures`: the textured diffuse objects'
    // vertices hold their light and coordinates (else every object is drawn by its radiance).
    // `cullBackFaces` where the scene has double-sided materials (their backs lie closer behind than
    // the depth buffer tells apart).
    SceneDraw(const Scene& scene, const std::vector<float>& vertices, const std::vector<unsigned>& triangles,
              const std::vector<int>& triangleObject, const std::vector<unsigned>& edges, bool textures,
              double sceneSize, bool cullBackFaces);
    ~SceneDraw();

    // Renders the probes (at start; the solution does not change while the window is open).
    void renderProbes();
    // Draws the scene seen from `eye` through `viewProjection` into the bound framebuffer: rgb the
    // linear radiance, alpha the distance from the eye.
    void draw(const Eigen::Matrix4f& viewProjection, const Vec3& eye) const;
    // The patch outlines, black, over what draw() left.
    void drawEdges(const Eigen::Matrix4f& viewProjection) const;
    size_t probes() const;
    // Occlusion culling (render/occlusion.h) of the grid's cells, on unless switched off (to check
    // that it changes nothing); the last draw's cells in view and of those drawn.
    void setOcclusionCulling(bool on);
    std::pair<size_t, size_t> cellsInViewAndDrawn() const;

private:
    // `exclude`: the object not drawn (the probe's own); `probes`: 0 draws mirrors and glass black,
    // else through that generation of probes.
    void drawAll(const Eigen::Matrix4f& viewProjection, const Vec3& eye, int exclude, int probes) const;
    struct State;
    std::unique_ptr<State> s_;
};

}  // namespace penumbra
