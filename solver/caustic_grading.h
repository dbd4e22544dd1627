// A mesh graded where mirrors and glass focus the lamps' light: a caustic on a patch is light the
// patch holds as one number, spread evenly over it, though it arrives in a spot; the light that
// patch sends on is then spread too, and where it goes through a ball (a glass ball images the
// caustic at its foot back onto the lamp, not beside it) that misplaces it. cornell-glass with its
// balls raised 5 cm, the caustic focused on the floor: the ceiling pieces beside the lamp read
// +0.4 .. +1.8% bright at 3,000 patches, +0.04 .. +0.26% at 12,000. Photons from the lamps
// through the mirrors and glass find the patches whose caustic light is brighter than the scene's
// mean irradiance; those are split into four (mesh/refine.h, the 2:1 rule kept), up to `levels`
// times, before the form factors.
#pragma once

#include <cstdint>
#include <memory>

#include "mesh/patches.h"
#include "mesh/scene.h"
#include "solver/visibility.h"

namespace penumbra {

struct CausticGrading {
    int levels = 2;             // most splits of a patch (0: none)
    int64_t photons = 1 << 16;  // photons from the lamps
    double brighter = 1.0;      // split where the caustic's irradiance is above this many times the mean
    int minPhotons = 8;         // fewer photons in a patch say too little about it
    double minArea = 0;         // no patch is split below this area, m^2
    uint64_t seed = 1;
};

// Splits `patches` where caustics fall; `rays` is their ray scene (built if null), and is null on
// return if any patch was split. Returns the patches split, all levels together.
size_t gradeCaustics(const Scene& scene, PatchSet& patches, std::shared_ptr<const RayScene>& rays,
                     const CausticGrading& settings);

}  // namespace penumbra
