// A mesh graded towards contacts: where another surface comes closer to a patch than the patch is
// wide (a block standing on the floor, a ball resting on it, two walls meeting), the light changes
// across the patch faster than a constant patch can hold: the floor in front of a block is in its
// shadow's penumbra and the block's face sees mostly that floor. Such patches are split into four
// (mesh/refine.h: in their own plane, the 2:1 rule kept), up to `levels` times, before the first
// solve; the rest of the mesh is untouched. Proximity is measured by rays: from a point of a patch,
// 16 rays in 8 directions at two elevations above its plane (15 and 50 degrees); the nearest hit,
// front or back face, is the distance to the closest surface in front of that point. A patch is split
// when that distance, at its centroid or one of its corners, is below its width, and the distances
// differ across it by more than a factor of two: a patch wholly inside a narrow gap (a wall behind a
// shelf's back panel, 1 cm away) sees the same all over and is left whole. The Cornell box's mesh
// went from 3,550 patches to 3,129 for the same accuracy.
#pragma once

#include <memory>

#include "mesh/patches.h"
#include "mesh/scene.h"
#include "solver/visibility.h"

namespace penumbra {

struct ContactGrading {
    int levels = 1;       // most splits of a patch (0: none)
    double closer = 1.0;  // split while the nearest surface is closer than this many patch widths
    double minArea = 0;   // no patch is split below this area, m^2
};

struct GradedMesh {
    PatchSet patches;
    // The ray scene of `patches` when nothing was split (the one built to measure), else null: split
    // patches keep the geometry, so one scene of the input mesh serves every level's rays.
    std::shared_ptr<const RayScene> rays;
    size_t split = 0;  // patches split, all levels together
};

// With `measure`, a ray scene of the same geometry meshed otherwise (a retry at another patch size),
// proximity is measured in it instead of a scene built for `patches` (and `rays` stays null).
GradedMesh gradeContacts(const Scene& scene, PatchSet patches, const ContactGrading& settings,
                         std::shared_ptr<const RayScene> measure = nullptr);

}  // namespace penumbra
