// Lightmaps for the round trip (`export --lightmap SIZE`, io/export.h): a mesh's triangles laid out
// flat in a SIZE x SIZE image, each texel holding the light at its point of the surface. Debian has
// no atlas library, so the layout is ours:
//  - charts: triangles that share vertices (by index) and lie in one plane (normals within 0.5
//    degree of the chart's first) form a chart, laid flat in that plane's own axes, in metres;
//  - packing: the charts' rectangles, each with `padding` texels around it, on shelves (tallest
//    first, left to right, a new shelf when one is full), at the largest uniform scale (texels a
//    metre, found by bisection) at which they fit: every chart at the same texel density;
//  - a vertex used by triangles of two charts is split in two, as each has its own place in the
//    image (`vertexOf` maps the new vertices to the mesh's own).
#pragma once

#include <array>
#include <functional>
#include <vector>

#include "core/math.h"
#include "mesh/texture.h"

namespace penumbra {

struct LightmapLayout {
    int size = 0;                                 // texels a side
    double texelsPerMetre = 0;                    // the scale every chart is laid at
    std::vector<int> vertexOf;                    // per new vertex: the mesh's vertex it copies
    std::vector<Vec2> uv;                         // per new vertex: its place, in [0, 1] (glTF's: v down)
    std::vector<std::array<int, 3>> triangles;    // the mesh's triangles, in new vertices
    std::vector<int> chartOf;                     // per triangle: its chart
    std::vector<std::array<int, 4>> chartTexels;  // per chart: x, y, width, height in texels, padding included
};

// Lays out a mesh of `positions` (metres) and `triangles` in a `size` x `size` image with `padding`
// texels about each chart. Throws Error if the charts cannot fit even at one texel each.
LightmapLayout layoutLightmap(const std::vector<Vec3>& positions, const std::vector<std::array<int, 3>>& triangles,
                              int size, int padding = 2);

// Places rectangles of `sizes` (width, height) on shelves in a `size` x `size` square, tallest first:
// their corners (x, y) in `at`, or false if they do not fit.
bool packShelves(const std::vector<std::array<int, 2>>& sizes, int size, std::vector<std::array<int, 2>>& at);

// The lightmap's texels, linear: each covered texel the value of `light(point, normal)` at the point
// of the surface under its centre; the texels of each chart's padding take their nearest covered
// neighbour's value (so that bilinear filtering at a chart's edge reads no other chart); the rest 0.
std::vector<Rgb> bakeLightmap(const LightmapLayout& layout, const std::vector<Vec3>& positions,
                              const std::function<Rgb(const Vec3& point, const Vec3& normal)>& light);

}  // namespace penumbra
