// Adaptive refinement of a patch set: chosen patches split into four (quads at their bilinear
// midpoints, triangles at their edge midpoints), keeping neighbours within one level of each other
// (the 2:1 rule), so that a hanging vertex is always the midpoint of a coarser neighbour's edge.
// Split patches stay in the plane (or bilinear surface) of their parent, so the scene's geometry and
// area are unchanged; only the elements that carry radiosity get finer.
#pragma once

#include <array>
#include <vector>

#include "mesh/patches.h"

namespace penumbra {

// A vertex that lies at the midpoint of an edge of a coarser patch without being one of its
// corners: its displayed value must be the mean of that edge's end values, or the shading cracks.
struct HangingVertex {
    int vertex;            // the display vertex
    int patch;             // the coarser patch whose edge it splits
    int cornerA, cornerB;  // that edge's corners in the patch (0..3)
    double edgeLength;     // metres: coarser edges first resolves chains of hanging vertices
};

// All hanging vertices of the patch set, longest edge first.
std::vector<HangingVertex> hangingVertices(const PatchSet& patches);

// Per display vertex, the patches that have it as a corner.
std::vector<std::vector<int>> patchesAround(const PatchSet& patches);

// Gives every hanging vertex the mean of its coarser edge's end values, as the coarser patch's own
// interpolation has along that edge: the displayed shading stays continuous across the join.
// `around` is patchesAround(patches).
void joinHangingVertices(const PatchSet& patches, const std::vector<std::vector<int>>& around, CornerValues& corners,
                         double creaseDeg = 30);

// The four children of patch i, in its own plane (or bilinear surface) and winding: a quad's at the
// midpoints of its edges and its parametric centre, a triangle's at its edge midpoints (the middle
// child last). Triangles repeat their last corner, as in PatchSet.
void childPolygons(const PatchSet& patches, size_t i, std::array<std::array<Vec3, 4>, 4>& out);

// The texture coordinates of childPolygons' corners, in the same order (needs patches.hasUv()).
void childUvs(const PatchSet& patches, size_t i, std::array<std::array<Vec2, 4>, 4>& out);

// The same patches with display vertices shared wherever patches of one object meet at a corner
// (patches made one by one, as the hierarchy's leaves, come with none).
PatchSet shareVertices(const PatchSet& patches);

// Splits the patches with split[i] != 0 into four, adding splits of coarser neighbours wherever the
// 2:1 rule needs them; `split` is updated to the splits made. Unsplit patches keep their order, and
// each split one is replaced, in place, by its four children.
PatchSet splitPatches(const PatchSet& patches, std::vector<char>& split);

}  // namespace penumbra
