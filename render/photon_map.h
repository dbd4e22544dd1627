// The caustic photon map (Jensen 1996): photons leave the emitters in proportion to their power,
// towards the mirrors and glass (PhotonSettings::aim), follow them, and are stored where they first land on a diffuse
// front face after at least one specular bounce. Paths without a specular bounce are the radiosity solution's, so they
// are not stored. A kd-tree (nanoflann) answers k-nearest queries for the density estimate.
// The estimate is precomputed at every few stored photons (Christensen 1999), each valid over the
// disc its k photons cover; a lookup then reads the nearest such point, one short query instead of
// a k-nearest search and sum at every shading point.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "core/math.h"
#include "core/rng.h"
#include "solver/tracer.h"

namespace penumbra {

struct PhotonSettings {
    int64_t photons = 1000000;  // photons emitted
    int nearest = 50;           // k of the k-nearest density estimate
    double maxRadius = 0.02;    // largest gather radius, as a fraction of the scene's diagonal
    int maxDepth = 64;          // specular bounces before a photon is dropped
    int precompute = 4;         // precompute the estimate at every this-many stored photons; 0: never
    // Aim the photons at spheres around the mirrors and glass (Jensen's projection map): a photon
    // that first meets a diffuse surface is never stored, so only the directions towards them
    // need tracing. Falls back to plain emission where a lamp lies within such a sphere or they
    // fill half of what the lamps see.
    bool aim = true;
    uint64_t seed = 1;
};

struct PhotonStats {
    int64_t emitted = 0, stored = 0;
    int64_t aimed = 0;               // photons traced towards the mirrors and glass (0: plain emission)
    Rgb emittedPower = Rgb::Zero();  // sum of the emitted photons' powers, W (aimed: the lamps' power)
    Rgb aimedPower = Rgb::Zero();    // sum of the aimed photons' powers: what the lamps send at the spheres
    Rgb storedPower = Rgb::Zero();   // sum of the stored photons' powers, W
    double seconds = 0;
};

// Where a caustic photon landed: the first diffuse front face it met after at least one specular
// bounce, the direction it arrived along, and its power (W).
struct PhotonLanding {
    SurfaceHit hit;
    Vec3 dir;
    Rgb power;
};

// The caustic photons' pass, which the map stores and the path tracer's light paths join to the
// eye (render/path_tracer.h): settings.photons emitted, aimed at the mirrors and glass where that
// pays, each from its own stream of `stream` and the seed, in chunks. `begin(chunks)` is called once
// first; then `land(chunk, landings)` with each chunk's landings in the order traced, from the worker
// threads (each chunk once), so that a caller that keeps each chunk's share apart and merges them in
// chunk order gets one result whatever the thread count, and no more than a chunk's landings are
// held at a time. `title` names the progress bar. Returns all of PhotonStats but the seconds.
PhotonStats traceCausticPhotons(const SceneTracer& tracer, const PhotonSettings& settings, Stream stream,
                                const char* title, const std::function<void(int64_t chunks)>& begin,
                                const std::function<void(int64_t chunk, const std::vector<PhotonLanding>&)>& land);

class PhotonMap {
public:
    // Traces the photons (in parallel, independent of the thread count) and builds the tree.
    PhotonMap(const SceneTracer& tracer, const PhotonSettings& settings);
    ~PhotonMap();
    PhotonMap(const PhotonMap&) = delete;
    PhotonMap& operator=(const PhotonMap&) = delete;

    // Caustic irradiance (W/m^2) at a point of a diffuse surface with unit normal n: the k nearest
    // photons on surfaces facing the same way, cone-filtered (Jensen's k = 1.1); read from the
    // nearest precomputed estimate when there are any.
    Rgb irradiance(const Vec3& x, const Vec3& n) const;
    // The same estimate computed afresh from the k nearest photons; `radius` gets the disc it used.
    // `exclude`: a stored photon to leave out (the estimate at its own position).
    Rgb estimate(const Vec3& x, const Vec3& n, double* radius = nullptr, size_t exclude = size_t(-1)) const;
    const PhotonStats& stats() const { return stats_; }
    // The stored photons, in the order stored (for tests and figures).
    struct Stored {
        Vec3 position, normal;
        Rgb power;  // W
    };
    std::vector<Stored> storedPhotons() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
    PhotonStats stats_;
    int nearest_;
    double maxRadius_;
};

}  // namespace penumbra
