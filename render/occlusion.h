// Occlusion culling on the CPU for the viewer: the scene's opaque polygons drawn into a small
// buffer, and a box (a cell of the viewer's grid of triangles) found hidden when no pixel centre of
// the picture that it may reach could show it. Conservative, so that culling never changes the
// picture: each buffer pixel stands for 8 x 8 pixels of the picture and holds which of their centres
// (where OpenGL samples) the polygons cover, a bit each, and the farthest depth the polygons that
// covered them have over it; a box counts from its nearest corner over every buffer pixel its
// corners' bounds touch, and is hidden only where all 64 centres are covered nearer. Polygons that
// meet along an edge (a wall and the floor, the pieces of a wall around a door) cover the centres
// on both sides of it together. Depth is clip-space w (the distance along the view axis); polygons
// are clipped to the near and far planes as OpenGL clips what it draws. After the masked occlusion
// culling of Andersson, Hasselgren and Akenine-Moller (2015), with one layer per buffer pixel.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

namespace penumbra {

class OcclusionBuffer {
public:
    // A buffer over a width x height picture seen through `viewProjection` (OpenGL's clip space).
    OcclusionBuffer(const Eigen::Matrix4d& viewProjection, int width, int height);
    // Draws a planar convex polygon (world space, 3 to 6 corners in order); with `frontOnly`, only
    // if its corners run counter-clockwise in the picture (OpenGL's front face), as where back faces
    // are culled a polygon seen from behind is not drawn and hides nothing. Draw the nearest first:
    // a tile covered whole nearer than a polygon stops it.
    void occlude(const std::vector<Eigen::Vector3d>& polygon, bool frontOnly = false);
    // True if no pixel centre of the picture can show a point of `box` in front of the polygons drawn
    // (by more than a thousandth of its depth: OpenGL's depth test cannot tell surfaces closer apart).
    bool hidden(const Eigen::AlignedBox3d& box) const;

private:
    static constexpr int kTile = 8;  // a buffer pixel is kTile x kTile pixels of the picture
    // The tile holding picture coordinate v (x or y, in pixels), within [0, count).
    static int tileOf(double v, int count);
    Eigen::Matrix4d vp_;
    int width_, height_, columns_, rows_;
    std::vector<uint64_t> mask_;  // per buffer pixel: bit 8 y + x for the centre of picture pixel (x, y) in it
    std::vector<double> depth_;   // per buffer pixel: the farthest depth of the polygons that covered its bits
};

}  // namespace penumbra
