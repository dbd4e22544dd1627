#include "solver/tracer.h"

#include <algorithm>

#include "core/error.h"
#include "core/optics.h"

namespace penumbra {

std::optional<RaySphere> exactSphereOf(const Scene& scene, const SceneObject& o) {
    if (o.type != ShapeType::Sphere || scene.materialOf(o).type == MaterialType::Diffuse) return std::nullopt;
    const Eigen::Matrix3d L = o.toWorld.linear();
    const Eigen::Matrix3d G = L.transpose() * L;
    const double s2 = G.trace() / 3;
    if ((G - s2 * Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-9 * s2) return std::nullopt;
    return RaySphere{o.toWorld * o.center, o.radius * std::sqrt(s2)};
}

namespace {

bool exactSphere(const Scene& scene, const SceneObject& o, RaySphere& out) {
    const std::optional<RaySphere> s = exactSphereOf(scene, o);
    if (s) out = *s;
    return s.has_value();
}

// The exact spheres of a scene, with the object each stands for (-1 per object that has none).
struct ExactSpheres {
    std::vector<RaySphere> spheres;
    std::vector<int> sphereObject;  // per sphere
    std::vector<int> objectSphere;  // per object
};

ExactSpheres findExactSpheres(const Scene& scene) {
    ExactSpheres out;
    out.objectSphere.assign(scene.objects.size(), -1);
    for (size_t o = 0; o < scene.objects.size(); ++o) {
        RaySphere s;
        if (!exactSphere(scene, scene.objects[o], s)) continue;
        out.objectSphere[o] = int(out.spheres.size());
        out.spheres.push_back(s);
        out.sphereObject.push_back(int(o));
    }
    return out;
}

// The point of triangle (a, b, c) nearest p (Ericson, Real-Time Collision Detection, 5.1.5).
Vec3 closestOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
    const Vec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = ab.dot(ap), d2 = ac.dot(ap);
    if (d1 <= 0 && d2 <= 0) return a;
    const Vec3 bp = p - b;
    const double d3 = ab.dot(bp), d4 = ac.dot(bp);
    if (d3 >= 0 && d4 <= d3) return b;
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
    const Vec3 cp = p - c;
    const double d5 = ab.dot(cp), d6 = ac.dot(cp);
    if (d6 >= 0 && d5 <= d6) return c;
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
    const double denom = 1 / (va + vb + vc);
    return a + ab * (vb * denom) + ac * (vc * denom);
}

// Whether nothing but the sphere itself lies inside exact sphere k: no patch the Exact view traces
// (the quads as Embree splits them, (c0, c1, c3) and (c2, c3, c1)) and no other exact sphere
// reaches into it. A ray from inside such a sphere meets only the sphere.
bool hollowSphere(const PatchSet& patches, const ExactSpheres& exact, size_t k) {
    const RaySphere& s = exact.spheres[k];
    const double inside = s.radius * (1 - 1e-9);
    for (size_t j = 0; j < exact.spheres.size(); ++j)
        if (j != k && (exact.spheres[j].center - s.center).norm() < inside + exact.spheres[j].radius) return false;
    for (size_t i = 0; i < patches.size(); ++i) {
        if (exact.objectSphere[size_t(patches.object[i])] >= 0) continue;  // a facet: not in the Exact view
        const auto& c = patches.corners[i];
        Vec3 lo = c[0], hi = c[0];
        for (const Vec3& p : c) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
        if ((lo.array() > (s.center.array() + s.radius)).any() || (hi.array() < (s.center.array() - s.radius)).any())
            continue;  // its box clear of the sphere's
        if ((closestOnTriangle(s.center, c[0], c[1], c[3]) - s.center).norm() < inside ||
            (closestOnTriangle(s.center, c[2], c[3], c[1]) - s.center).norm() < inside)
            return false;
    }
    return true;
}

}  // namespace

std::shared_ptr<const RayScene> buildRayScene(const Scene& scene, const PatchSet& patches) {
    const ExactSpheres exact = findExactSpheres(scene);
    std::vector<char> replaced(patches.size(), 0);
    for (size_t i = 0; i < patches.size(); ++i) replaced[i] = exact.objectSphere[size_t(patches.object[i])] >= 0;
    return std::make_shared<const RayScene>(patches, exact.spheres, replaced);
}

int specularBranches(const SurfaceHit& hit, const Vec3& dir, SpecularBranch out[2]) {
    const Material& m = *hit.material;
    const bool front = hit.frontFacing(dir);
    if (m.type == MaterialType::Mirror) {
        if (!front) return 0;
        out[0] = {reflect(dir, hit.normal), m.reflectance, 1.0};
        return 1;
    }
    // Glass: the front side faces air; inside a closed glass object rays meet the back sides.
    const Vec3 n = front ? hit.normal : Vec3(-hit.normal);
    const double etaFrom = front ? 1.0 : m.ior, etaTo = front ? m.ior : 1.0;
    const double F = fresnelDielectric(-dir.dot(n), etaFrom, etaTo);
    const std::optional<Vec3> t = refract(dir, n, etaFrom, etaTo);
    if (!t || F >= 1) {
        out[0] = {reflect(dir, n), Rgb::Ones(), 1.0};
        return 1;
    }
    out[0] = {reflect(dir, n), Rgb::Constant(F), F};
    // The tint applies once per passage through the glass: on the way in.
    out[1] = {*t, (1 - F) * (front ? m.transmittance : Rgb::Ones()), 1 - F};
    return 2;
}

Vec3 samplePatchPoint(const PatchSet& patches, size_t i, double u1, double u2, double /*u3: unused*/) {
    return PatchPointSampler(patches, i)(u1, u2);
}

PatchPointSampler::PatchPointSampler(const PatchSet& patches, size_t i) {
    const auto& c = patches.corners[i];
    a_[0] = c[0], b_[0] = c[1], d_[0] = c[2];
    if (patches.isTriangle(i)) return;
    // The two triangles Embree traces a quad as, (c0, c1, c3) and (c2, c3, c1): on a quad that is
    // not quite flat (the Cornell box's walls) a point of the other diagonal's triangles lies off
    // the traced surface, half the time behind it, where its ray meets its own patch's back.
    const double first = 0.5 * (c[1] - c[0]).cross(c[3] - c[0]).norm();
    const double second = 0.5 * (c[3] - c[2]).cross(c[1] - c[2]).norm();
    // The triangle by u1, its share of u1's range the share of its area: a stratified (u1, u2)
    // stays stratified over the whole quad (a random pick per point, by u3, left each triangle
    // holding a binomial number of them: the Cornell box's ray origins were stratified within
    // each triangle, not over the patch).
    split_ = first / (first + second);
    inverse_[0] = split_ > 0 ? 1 / split_ : 0, inverse_[1] = split_ < 1 ? 1 / (1 - split_) : 0;
    d_[0] = c[3];
    a_[1] = c[2], b_[1] = c[3], d_[1] = c[1];
}

Vec3 PatchPointSampler::operator()(double u1, double u2) const {
    int t = 0;
    if (u1 >= split_) {
        t = 1;
        u1 = (u1 - split_) * inverse_[1];
    } else {
        u1 = u1 * inverse_[0];
    }
    const double r = std::sqrt(u1);
    return (1 - r) * a_[t] + r * (1 - u2) * b_[t] + r * u2 * d_[t];
}

SceneTracer::SceneTracer(const Scene& scene, const PatchSet& patches, std::shared_ptr<const RayScene> rays)
    : scene_(scene), patches_(patches), rays_(rays ? std::move(rays) : buildRayScene(scene, patches)) {
    ExactSpheres exact = findExactSpheres(scene);
    for (size_t k = 0; k < exact.spheres.size(); ++k) hollow_.push_back(hollowSphere(patches, exact, k));
    spheres_ = std::move(exact.spheres);
    sphereObject_ = std::move(exact.sphereObject);
    PENUMBRA_CHECK_OP(rays_->patchCount(), ==, patches.size());
    PENUMBRA_CHECK_OP(rays_->sphereCount(), ==, spheres_.size());
    for (const SceneObject& o : scene.objects)
        hasSpecular_ = hasSpecular_ || scene.materialOf(o).type != MaterialType::Diffuse;
    diagonal_ = patches.size() ? patchBounds(patches).diagonal().norm() : 1.0;
    // Offsets off surfaces: far above float rounding of the geometry, far below any feature.
    epsilon_ = 1e-6 * std::max(diagonal_, 1e-3);

    emitterPdf_.assign(patches.size(), 0);
    double total = 0;
    std::vector<double> cdf;
    for (size_t i = 0; i < patches.size(); ++i) {
        const Material& m = scene.materialOf(scene.objects[size_t(patches.object[i])]);
        if (m.type != MaterialType::Diffuse || !m.emits()) continue;
        const Rgb emission = m.emissionTexture ? meanEmission(scene, patches, i) : m.emission;
        if (!(emission > 0).any()) continue;
        emitterPatch_.push_back(int(i));
        total += patches.area[i] * emission.sum();
        cdf.push_back(total);
        emittedPower_ += kPi * patches.area[i] * emission;
    }
    for (size_t k = 0; k < emitterPatch_.size(); ++k) {
        const size_t i = size_t(emitterPatch_[k]);
        cdf[k] /= total;
        const double p = (cdf[k] - (k ? cdf[k - 1] : 0.0));
        emitterPdf_[i] = p / patches.area[i];
    }
    if (!cdf.empty()) cdf.back() = 1;
    emitterCdf_ = CumulativeTable(std::move(cdf));
}

SurfaceHit SceneTracer::trace(const Vec3& origin, const Vec3& dir, double tMin) const {
    // From inside a hollow exact sphere (light refracted into a glass ball, or reflected inside it)
    // the ray meets the sphere from within: solved here, not traced.
    for (size_t k = 0; k < spheres_.size(); ++k) {
        if (!hollow_[k]) continue;
        const RaySphere& sphere = spheres_[k];
        const Vec3 d = origin - sphere.center;
        const double c = d.squaredNorm() - sphere.radius * sphere.radius;
        if (!(c < 0)) continue;
        const double b = d.dot(dir);
        const double t = -b + std::sqrt(std::max(0.0, b * b - c));
        if (!(t > tMin)) break;
        SurfaceHit s;
        s.found = true;
        s.t = t;
        s.object = sphereObject_[k];
        s.normal = (origin + t * dir - sphere.center).normalized();
        s.point = sphere.center + sphere.radius * s.normal;
        shade(s);
        return s;
    }
    return surfaceAt(rays_->intersect(origin, dir, tMin, 1e30, RayView::Exact), origin, dir);
}

SurfaceHit SceneTracer::surfaceAt(const Hit& h, const Vec3& origin, const Vec3& dir) const {
    SurfaceHit s;
    if (!h.found()) return s;
    s.found = true;
    s.t = h.t;
    s.point = origin + h.t * dir;
    if (h.patch >= 0) {
        s.patch = h.patch;
        s.u = h.u;
        s.v = h.v;
        s.object = patches_.object[size_t(h.patch)];
        s.normal = patches_.normal[size_t(h.patch)];
    } else {
        const RaySphere& sphere = spheres_[size_t(h.sphere)];
        s.object = sphereObject_[size_t(h.sphere)];
        s.normal = (s.point - sphere.center).normalized();
        // Put the point back on the sphere: the float hit distance is off by ~1e-7 of the radius.
        s.point = sphere.center + sphere.radius * s.normal;
    }
    shade(s);
    return s;
}

void SceneTracer::shade(SurfaceHit& s) const {
    const SceneObject& o = scene_.objects[size_t(s.object)];
    s.material = &scene_.materialOf(o);
    if (!s.material->textured() || s.patch < 0 || !patches_.hasUv() || !o.hasUv()) {
        s.reflectance = s.material->reflectanceAt(nullptr);
        s.emission = s.material->emissionAt(nullptr);
        return;
    }
    const Vec2 uv = patches_.uvAtHit(size_t(s.patch), s.u, s.v);
    s.reflectance = s.material->reflectanceAt(&uv);
    s.emission = s.material->emissionAt(&uv);
}

bool SceneTracer::visible(const Vec3& a, const Vec3& b) const { return !rays_->occluded(a, b, 1e-7, RayView::Exact); }

LightSample SceneTracer::sampleLight(const Vec3& x, const Vec3& n, double u, double u1, double u2) const {
    const EmitterSample e = sampleEmitter(u, u1, u2);
    LightSample l;
    Vec3 w = e.point - x;
    const double d2 = w.squaredNorm();
    w /= std::sqrt(d2);
    const double cosX = n.dot(w), cosL = -e.normal.dot(w);
    if (cosX <= 0 || cosL <= 0) return l;
    if (!visible(x + epsilon_ * n, e.point + epsilon_ * e.normal)) return l;
    l.radiance = e.radiance;
    l.dir = w;
    l.cosine = cosX;
    l.pdf = e.pdfArea * d2 / cosL;
    return l;
}

EmitterSample SceneTracer::sampleEmitter(double u, double u1, double u2) const {
    PENUMBRA_CHECK(!emitterCdf_.empty());
    double within = 0;
    const size_t i = size_t(emitterPatch_[emitterCdf_.pick(u, within)]);
    EmitterSample e;
    e.point = samplePatchPoint(patches_, i, u1, u2, 0);
    e.normal = patches_.normal[i];
    const SceneObject& o = scene_.objects[size_t(patches_.object[i])];
    const Material& m = scene_.materialOf(o);
    if (m.emissionTexture && patches_.hasUv() && o.hasUv()) {
        const Vec2 uv = patches_.uvAtPoint(i, e.point);
        e.radiance = m.emissionAt(&uv);
    } else {
        e.radiance = m.emissionAt(nullptr);
    }
    e.pdfArea = emitterPdf_[i];
    e.patch = int(i);
    return e;
}

}  // namespace penumbra
