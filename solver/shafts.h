// Proofs that nothing stands between two polygons: the shaft (the convex hull of both) separated
// from every surface of the scene by a plane. Where the proof holds, every segment from a point of
// one to a point of the other is clear, and the shadow rays that would find it so need not be cast:
// the final gather's direct light (render/direct_light.h) and the solve's lamp columns read the
// closed form alone there. Conservative: a surface the test cannot separate (one that touches the
// shaft, or that it has no axis for) leaves the pair to the rays, never the other way round.
#pragma once

#include <array>
#include <vector>

#include "core/math.h"
#include "mesh/patches.h"
#include "solver/visibility.h"

namespace penumbra {

// One end of a shaft: a polygon (3 or 4 corners; the segments start or end anywhere in their convex
// hull) whose front, of unit normal `normal`, faces the other end, and the object whose patches are
// not taken as occluders of it (its own surface, when that is a quad or triangle object, which a ray
// leaving its front does not meet again; -1: every patch may occlude).
struct ShaftEnd {
    std::array<Vec3, 4> corner{Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
    int count = 4;
    Vec3 normal = Vec3::UnitZ();
    int object = -1;
};

// Patch i as a shaft end, its corners lifted `lift` metres along its normal (where rays start off it);
// every patch may occlude it.
ShaftEnd patchEnd(const PatchSet& patches, size_t i, double lift = 0);

class ClearShafts {
public:
    // The occluders as the ray scene's Exact view has them: every patch (the hull of its corners holds
    // the quad Embree traces) but those with replaced[i] set, and the exact spheres.
    // `margin`: metres by which an occluder must clear the shaft (at least the scene's float
    // precision): segments whose ends lie off the polygons by less than it are proved clear too.
    ClearShafts(const PatchSet& patches, const std::vector<RaySphere>& spheres, const std::vector<char>& replaced,
                double margin = 0);

    // Whether no occluder but the ends' own objects' patches meets any segment from a point of `a` to
    // a point of `b`. False (no proof) also when either end is not wholly in front of the other, or an
    // occluder touches the shaft.
    bool clear(const ShaftEnd& a, const ShaftEnd& b) const;

    size_t pieces() const { return pieces_.size(); }

private:
    struct Piece {
        std::array<Vec3, 4> corner{Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
        int count = 0;  // 0: a sphere (centre corner[0], radius `radius`)
        double radius = 0;
        int object = -1;
        Vec3 low = Vec3::Zero(), high = Vec3::Zero();  // bounding box
    };
    struct Node {
        Vec3 low = Vec3::Zero(), high = Vec3::Zero();
        int first = 0, count = 0;  // leaf: pieces [first, first + count); inner: count 0, children first, first + 1
    };
    void build(int node, int first, int count);
    bool separated(const Piece& p, const Vec3* hull, int count, const std::vector<std::array<double, 4>>& faces) const;

    std::vector<Piece> pieces_;
    std::vector<Node> nodes_;
    double tolerance_ = 0;  // metres: the scene's float precision (in a plane, behind it)
    double margin_ = 0;     // metres: closer than this counts as touching
};

}  // namespace penumbra
