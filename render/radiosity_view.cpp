#include "render/radiosity_view.h"

#include "render/camera.h"
#include "render/film.h"
#include "render/visibility_buffer.h"
#include "solver/tracer.h"

namespace penumbra {

Rgb interpolateAt(const PatchSet& patches, size_t patch, double u, double v, const std::array<Rgb, 4>& c) {
    if (patches.isTriangle(patch)) return (1 - u - v) * c[0] + u * c[1] + v * c[2];
    return (1 - u) * (1 - v) * c[0] + u * (1 - v) * c[1] + u * v * c[2] + (1 - u) * v * c[3];
}

CornerValues cornerIrradiance(const Scene& scene, const PatchSet& patches, const CornerValues& corners) {
    CornerValues out(patches.size());
    for (size_t i = 0; i < patches.size(); ++i) {
        const Rgb rho = meanReflectance(scene, patches, i), E = kPi * meanEmission(scene, patches, i);
        for (size_t k = 0; k < 4; ++k)
            for (int c = 0; c < 3; ++c)
                out[i][k][c] = rho[c] > 0 ? std::max(0.0, corners[i][k][c] - E[c]) / rho[c] : 0.0;
    }
    return out;
}

Rgb radianceFromIrradiance(const Scene& scene, const PatchSet& patches, size_t p, double u, double v,
                           const std::array<Rgb, 4>& cornerIrradiance) {
    const SceneObject& o = scene.objects[size_t(patches.object[p])];
    const Material& m = scene.materialOf(o);
    const bool at = patches.hasUv() && o.hasUv();
    const Vec2 uv = at ? patches.uvAtHit(p, u, v) : Vec2::Zero();
    return m.emissionAt(at ? &uv : nullptr) +
           m.reflectanceAt(at ? &uv : nullptr) * interpolateAt(patches, p, u, v, cornerIrradiance) * kInvPi;
}

namespace {

// Texture detail finer than the patches: a textured patch shows the irradiance at its corners
// (cornerIrradiance), interpolated across it, times the texel's reflectance over pi, plus its emission
// texel. Dividing the interpolated radiosity by the patch's mean reflectance instead smeared a dark
// patch's light onto a bright one (a checker floor's dark blocks read 1.1-2.2 times their closed
// form, its bright ones 0.67-0.97).
class TextureDetail {
public:
    TextureDetail(const Scene& scene, const PatchSet& patches, const CornerValues& corners)
        : scene_(scene), patches_(patches) {
        if (patches.hasUv() && scene.hasTextures()) irradiance_ = cornerIrradiance(scene, patches, corners);
    }
    // Radiance `L` interpolated from the solution at Embree's (u, v) on patch p, with the texture.
    Rgb operator()(size_t p, double u, double v, const Rgb& L) const {
        if (irradiance_.empty() || !textured(p)) return L;
        return radianceFromIrradiance(scene_, patches_, p, u, v, irradiance_[p]);
    }

private:
    const Material& material(size_t p) const { return scene_.materialOf(scene_.objects[size_t(patches_.object[p])]); }
    bool textured(size_t p) const {
        return material(p).textured() && scene_.objects[size_t(patches_.object[p])].hasUv();
    }
    const Scene& scene_;
    const PatchSet& patches_;
    CornerValues irradiance_;  // W m^-2 at each patch corner, where the scene has textures
};

// What the view shows along a ray that may meet mirrors and glass: both branches at each (Fresnel's
// reflection and refraction, or total internal reflection), weighted as the final gather's camera
// rays are, until a diffuse front face shows its interpolated radiosity B / pi; `carried` is what the
// camera's ray carries here, and a branch that would carry less than settings.minThroughput is
// dropped (glass's internal reflections, 4% each, end after two or three). No random numbers: the
// picture is as smooth as the radiosity it shows.
Rgb throughSpecular(const SceneTracer& tracer, const std::vector<std::array<Rgb, 4>>& corners,
                    const TextureDetail& detail, const SurfaceHit& hit, const Vec3& dir, const ViewSettings& settings,
                    int depth, const Rgb& carried);

// The same along origin + t dir, its first surface found by the tracer.
Rgb throughSpecular(const SceneTracer& tracer, const std::vector<std::array<Rgb, 4>>& corners,
                    const TextureDetail& detail, const Vec3& origin, const Vec3& dir, const ViewSettings& settings,
                    int depth, const Rgb& carried) {
    return throughSpecular(tracer, corners, detail, tracer.trace(origin, dir), dir, settings, depth, carried);
}

Rgb throughSpecular(const SceneTracer& tracer, const std::vector<std::array<Rgb, 4>>& corners,
                    const TextureDetail& detail, const SurfaceHit& hit, const Vec3& dir, const ViewSettings& settings,
                    int depth, const Rgb& carried) {
    if (!hit.found) return Rgb::Zero();
    if (hit.material->type == MaterialType::Diffuse) {
        if (!hit.frontFacing(dir) || hit.patch < 0) return Rgb::Zero();
        const size_t p = size_t(hit.patch);
        return detail(p, hit.u, hit.v, interpolateAt(tracer.patches(), p, hit.u, hit.v, corners[p]) * kInvPi);
    }
    if (depth >= settings.maxSpecularDepth) return Rgb::Zero();
    SpecularBranch branches[2];
    const int count = specularBranches(hit, dir, branches);
    Rgb L = Rgb::Zero();
    for (int b = 0; b < count; ++b) {
        const Rgb next = carried * branches[b].weight;
        if (next.maxCoeff() >= settings.minThroughput)
            L += branches[b].weight * throughSpecular(tracer, corners, detail, tracer.offset(hit, branches[b].dir),
                                                      branches[b].dir, settings, depth + 1, next);
    }
    return L;
}

}  // namespace

struct RadiosityView::Shared {
    const Scene& scene;
    const PatchSet& patches;
    std::shared_ptr<const RayScene> rays;
    const CornerValues& corners;
    ViewSettings settings;
    // Mirrors and glass are followed by the tracer, which knows the materials (and the exact spheres).
    std::unique_ptr<const SceneTracer> tracer;
    TextureDetail detail;
    std::vector<char> diffuse;  // per patch: its material diffuse
};

RadiosityView::RadiosityView(const Scene& scene, const PatchSet& patches, std::shared_ptr<const RayScene> rays,
                             const CornerValues& corners, const ViewSettings& settings) {
    std::unique_ptr<const SceneTracer> tracer =
        scene.hasSpecular() ? std::make_unique<const SceneTracer>(scene, patches, rays) : nullptr;
    std::vector<char> diffuse(patches.size());
    for (size_t p = 0; p < patches.size(); ++p)
        diffuse[p] = scene.materialOf(scene.objects[size_t(patches.object[p])]).type == MaterialType::Diffuse;
    shared_.reset(new Shared{scene, patches, std::move(rays), corners, settings, std::move(tracer),
                             TextureDetail(scene, patches, corners), std::move(diffuse)});
}

RadiosityView::~RadiosityView() = default;

Image RadiosityView::render(const Camera& camera) const {
    const Shared& s = *shared_;
    const auto diffuse = [&](size_t p, double u, double v, const Vec3& dir) -> Rgb {
        if (s.patches.normal[p].dot(dir) >= 0) return Rgb::Zero();  // back face: black
        return s.detail(p, u, v, interpolateAt(s.patches, p, u, v, s.corners[p]) * kInvPi);
    };
    const SampledRadianceFn radiance = [&](const Vec3& origin, const Vec3& dir, PixelSampler&) -> Rgb {
        // With mirrors or glass one ray of the tracer's (the exact spheres) serves every sample.
        if (s.tracer) return throughSpecular(*s.tracer, s.corners, s.detail, origin, dir, s.settings, 0, Rgb::Ones());
        const Hit hit = s.rays->intersect(origin, dir);
        return hit.patch < 0 ? Rgb::Zero() : diffuse(size_t(hit.patch), hit.u, hit.v, dir);
    };
    // The camera's samples see their first surfaces without rays (a pinhole camera outside the exact
    // spheres); rays remain for what mirrors and glass show.
    if (VisibilityBuffer::eyeInsideSphere(*s.rays, camera))
        return renderPixelsSampled(camera, s.settings.samplesPerPixel, s.settings.seed, "view", radiance, true);
    const VisibilityBuffer buffer(s.patches, *s.rays, camera);
    const PinholeCamera::ImagePlane image = PinholeCamera(camera).imagePlane();  // as the buffer's t counts
    const BatchRadianceFn batch = [&](const std::vector<CameraSample>& samples, std::vector<Rgb>& L) {
        const std::vector<BufferHit> hits = buffer.firstHits(samples);
        for (size_t k = 0; k < samples.size(); ++k) {
            const BufferHit& hit = hits[k];
            const Vec3 D = image.corner + samples[k].at.x() * image.perX + samples[k].at.y() * image.perY;
            const Vec3 dir = D.normalized();
            if (hit.sphere >= 0 || (hit.patch >= 0 && !s.diffuse[size_t(hit.patch)])) {
                // Mirrors and glass: their first surface as the buffer found it, the rest by rays.
                Hit first;
                first.patch = hit.patch, first.sphere = hit.sphere;
                first.t = hit.t * D.norm(), first.u = hit.u, first.v = hit.v;
                L[k] = throughSpecular(*s.tracer, s.corners, s.detail, s.tracer->surfaceAt(first, camera.position, dir),
                                       dir, s.settings, 0, Rgb::Ones());
            } else {
                L[k] = hit.patch < 0 ? Rgb::Zero() : diffuse(size_t(hit.patch), hit.u, hit.v, dir);
            }
        }
    };
    return renderPixelsSampled(camera, s.settings.samplesPerPixel, s.settings.seed, "view", radiance, true, batch);
}

Image renderRadiosityView(const Scene& scene, const Camera& camera, const PatchSet& patches,
                          const std::shared_ptr<const RayScene>& rays, const CornerValues& corners,
                          const ViewSettings& settings) {
    return RadiosityView(scene, patches, rays, corners, settings).render(camera);
}

}  // namespace penumbra
