// The scene as the ray tracers see it: the patches, with mirror and glass spheres as exact spheres
// (their facets would show in reflections and scatter caustics), materials at every hit, and
// sampling of the emitting surfaces by power. Shared by the specular transport of the solve, the
// photon pass and both integrators, so all of them see one geometry.
#pragma once

#include <memory>
#include <optional>
#include <vector>

#include "core/cumulative.h"
#include "core/math.h"
#include "core/rng.h"
#include "mesh/patches.h"
#include "mesh/scene.h"
#include "solver/visibility.h"

namespace penumbra {

struct SurfaceHit {
    bool found = false;
    Vec3 point = Vec3::Zero();
    Vec3 normal = Vec3::UnitZ();  // unit normal of the front side (outward on spheres)
    double t = 0;
    int patch = -1;       // patch hit; -1 on exact spheres
    double u = 0, v = 0;  // Embree's coordinates on the patch
    int object = -1;
    const Material* material = nullptr;
    // The diffuse reflectance and emitted radiance at the point: the material's, times the texel of
    // its textures there (Material::reflectanceAt).
    Rgb reflectance = Rgb::Zero();
    Rgb emission = Rgb::Zero();
    // True if a ray travelling along `dir` arrived on the front side.
    bool frontFacing(const Vec3& dir) const { return normal.dot(dir) < 0; }
};

// Light from one point on the emitters as seen from a surface point: what next-event estimation,
// the final gather's direct light and the caustic region all use.
struct LightSample {
    Rgb radiance = Rgb::Zero();  // L_e arriving along `dir`
    Vec3 dir = Vec3::Zero();     // unit, from the surface point to the emitter point
    double cosine = 0;           // of `dir` with the surface's normal
    double pdf = 0;              // solid-angle density of `dir`; 0 when the point is not seen
    bool found() const { return pdf > 0; }
};

struct EmitterSample {
    Vec3 point, normal;  // on an emitting patch, its front normal
    Rgb radiance;        // L_e
    double pdfArea = 0;  // density of this point per m^2 over all emitters
    int patch = -1;
};

// The one ray scene of a mesh: its patches, and exact spheres for the mirror and glass balls whose
// transform keeps them spheres (in place of their patches, in the Exact view). Built once per mesh
// and run, and shared by all that trace it: the form factors and the vertex gather (Patches view),
// the specular transport, the photon pass and the integrators (Exact, through a SceneTracer).
std::shared_ptr<const RayScene> buildRayScene(const Scene& scene, const PatchSet& patches);

class SceneTracer {
public:
    // Over the mesh's ray scene `rays` (buildRayScene of the same scene and patches); with none,
    // builds its own.
    SceneTracer(const Scene& scene, const PatchSet& patches, std::shared_ptr<const RayScene> rays = nullptr);

    const Scene& scene() const { return scene_; }
    const PatchSet& patches() const { return patches_; }

    // Nearest surface along origin + t dir (dir unit), t > tMin.
    SurfaceHit trace(const Vec3& origin, const Vec3& dir, double tMin = 0) const;
    // The surface at the Exact view's hit `h` along origin + t dir (dir unit), found by other means
    // than trace (a visibility buffer).
    SurfaceHit surfaceAt(const Hit& h, const Vec3& origin, const Vec3& dir) const;
    // Nothing between a and b (both already offset off their surfaces).
    bool visible(const Vec3& a, const Vec3& b) const;
    // A point just off the surface at `hit`, on the side that `dir` leaves towards.
    Vec3 offset(const SurfaceHit& hit, const Vec3& dir) const {
        return hit.point + (hit.normal.dot(dir) > 0 ? epsilon_ : -epsilon_) * hit.normal;
    }
    double epsilon() const { return epsilon_; }
    // Length of the diagonal of the box around the scene, metres (1 for an empty scene).
    double diagonal() const { return diagonal_; }

    bool hasEmitters() const { return !emitterCdf_.empty(); }
    // True if some object is a mirror or glass.
    bool hasSpecular() const { return hasSpecular_; }
    // A point on the emitters, chosen in proportion to emitted power (sum over channels).
    // Four numbers from `g` (an Rng or a PixelSampler): the emitter, two for the point on it, and one
    // left unused (the draws of earlier versions, kept so that results stay bit for bit).
    template <typename Generator>
    EmitterSample sampleEmitter(Generator& g) const {
        const double u = g.uniform(), u1 = g.uniform(), u2 = g.uniform();
        g.uniform();
        return sampleEmitter(u, u1, u2);
    }
    EmitterSample sampleEmitter(double u, double u1, double u2) const;
    // A point on the emitters (sampleEmitter) as seen from x on a surface of unit normal n: not found
    // when it lies behind the surface, faces away from x, or something hides it.
    template <typename Generator>
    LightSample sampleLight(const Vec3& x, const Vec3& n, Generator& g) const {
        const double u = g.uniform(), u1 = g.uniform(), u2 = g.uniform();
        g.uniform();
        return sampleLight(x, n, u, u1, u2);
    }
    LightSample sampleLight(const Vec3& x, const Vec3& n, double u, double u1, double u2) const;
    // The density per m^2 with which sampleEmitter picks points on `patch` (0 if it does not emit).
    double emitterPdfArea(int patch) const { return patch >= 0 ? emitterPdf_[size_t(patch)] : 0; }
    // Power emitted by all surfaces, W per channel.
    const Rgb& emittedPower() const { return emittedPower_; }
    // Number of exact spheres standing in for mirror and glass sphere objects.
    size_t exactSpheres() const { return sphereObject_.size(); }
    // The exact sphere standing in for `object`, or null where its patches are traced.
    const RaySphere* exactSphere(int object) const {
        for (size_t k = 0; k < sphereObject_.size(); ++k)
            if (sphereObject_[k] == object) return &spheres_[k];
        return nullptr;
    }

private:
    // Sets the hit's material and its reflectance and emission there.
    void shade(SurfaceHit& s) const;

    const Scene& scene_;
    const PatchSet& patches_;
    std::shared_ptr<const RayScene> rays_;
    std::vector<RaySphere> spheres_;
    std::vector<int> sphereObject_;
    std::vector<char> hollow_;  // per sphere: nothing else inside it (a ray from within is solved, not traced)
    std::vector<int> emitterPatch_;
    CumulativeTable emitterCdf_;      // by power
    std::vector<double> emitterPdf_;  // per patch, per m^2
    Rgb emittedPower_ = Rgb::Zero();
    bool hasSpecular_ = false;
    double diagonal_ = 1;
    double epsilon_ = 1e-6;
};

// The exact sphere a mirror or glass sphere object is traced as (centre and radius in the scene's
// inside units): when its transform keeps it a sphere (rotation and uniform scale); an ellipsoid
// keeps its facets (empty).
std::optional<RaySphere> exactSphereOf(const Scene& scene, const SceneObject& o);

// Where light arriving along `dir` at a mirror or glass hit goes: reflection and (glass) refraction
// with their Fresnel-weighted tints. `probability` is the share to pick a branch with when
// following one path; `weight` the factor of the light it carries. The back of a mirror absorbs.
struct SpecularBranch {
    Vec3 dir;
    Rgb weight;
    double probability = 0;
};
int specularBranches(const SurfaceHit& hit, const Vec3& dir, SpecularBranch out[2]);
// One branch for a path that follows one: chosen with its probability, its `weight` already
// divided by it (the factor the path's throughput takes). Empty where the light is absorbed. Draws a
// number from `g` (an Rng or a PixelSampler) only where there are two branches to choose from.
template <typename Generator>
std::optional<SpecularBranch> sampleSpecular(const SurfaceHit& hit, const Vec3& dir, Generator& g) {
    SpecularBranch branches[2];
    const int count = specularBranches(hit, dir, branches);
    if (count == 0) return std::nullopt;
    SpecularBranch b = count == 1 || g.uniform() < branches[0].probability ? branches[0] : branches[1];
    b.weight /= b.probability;
    return b;
}

// How a walk through mirrors and glass ended.
enum class WalkEnd {
    Diffuse,   // on a diffuse surface (front or back face: see `hit`)
    Escaped,   // out of the scene
    Absorbed,  // on the back of a mirror
    TooDeep,   // more bounces than allowed, or too little throughput left
};

struct SpecularWalk {
    WalkEnd end = WalkEnd::Escaped;
    SurfaceHit hit;           // the diffuse surface reached (End::Diffuse), else the last specular hit
    Vec3 dir = Vec3::Zero();  // the direction that arrived there (or left the scene)
    Rgb throughput = Rgb::Ones();
    int bounces = 0;    // specular bounces taken
    double length = 0;  // metres travelled, from the first hit's ray origin
};

// The one specular walk every light path uses (the solve's transport, the photons, the gather rays,
// the path tracer, the tests): from `first`, the surface a ray along `dir` met, on through mirrors and
// glass one branch at a time (sampleSpecular) until a diffuse surface, the open scene, an absorbing
// back face, `maxBounces` bounces, or a throughput below `minThroughput`. `onLoss(object, share)`, if
// given, is told the throughput each mirror or glass tint absorbs. A diffuse `first` returns at once.
template <typename Generator, typename OnLoss>
SpecularWalk walkSpecular(const SceneTracer& tracer, SurfaceHit first, Vec3 dir, Generator& rng, int maxBounces,
                          double minThroughput, const OnLoss& onLoss) {
    SpecularWalk w;
    w.hit = std::move(first);
    w.dir = dir;
    w.length = w.hit.t;
    for (;;) {
        if (!w.hit.found) {
            w.end = WalkEnd::Escaped;
            return w;
        }
        if (w.hit.material->type == MaterialType::Diffuse) {
            w.end = WalkEnd::Diffuse;
            return w;
        }
        if (w.bounces >= maxBounces) {
            w.end = WalkEnd::TooDeep;
            return w;
        }
        const std::optional<SpecularBranch> b = sampleSpecular(w.hit, w.dir, rng);
        if (!b) {
            w.end = WalkEnd::Absorbed;
            return w;
        }
        if ((b->weight < 1).any()) onLoss(w.hit.object, Rgb(w.throughput * (1 - b->weight).max(0.0)));
        w.throughput *= b->weight;
        ++w.bounces;
        if (w.throughput.maxCoeff() < minThroughput) {
            w.end = WalkEnd::TooDeep;
            return w;
        }
        w.dir = b->dir;
        w.hit = tracer.trace(tracer.offset(w.hit, w.dir), w.dir);
        w.length += w.hit.t;
    }
}
template <typename Generator>
SpecularWalk walkSpecular(const SceneTracer& tracer, SurfaceHit first, const Vec3& dir, Generator& rng, int maxBounces,
                          double minThroughput = 0) {
    return walkSpecular(tracer, std::move(first), dir, rng, maxBounces, minThroughput, [](int, const Rgb&) {});
}

// A uniformly distributed point on a patch: a quad's two triangles by u1, in proportion to their
// areas, so that points stratified in (u1, u2) are stratified over the whole patch. u3 is unused (it
// chose the triangle once; callers still pass it).
Vec3 samplePatchPoint(const PatchSet& patches, size_t patch, double u1, double u2, double u3);

// samplePatchPoint for many points of one patch, its triangles and their split found once.
class PatchPointSampler {
public:
    PatchPointSampler(const PatchSet& patches, size_t patch);
    Vec3 operator()(double u1, double u2) const;

private:
    Vec3 a_[2], b_[2], d_[2];
    double split_ = 1;            // u1 below it: the first triangle
    double inverse_[2] = {1, 0};  // 1 / split_ and 1 / (1 - split_), or 0 where that is 0
};

}  // namespace penumbra
