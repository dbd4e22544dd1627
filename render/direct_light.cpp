#include "render/direct_light.h"

#include <atomic>
#include <cmath>
#include <type_traits>

#include "core/parallel.h"
#include "solver/radiosity/form_factor_kernel.h"
#include "solver/radiosity/system.h"
#include "solver/shafts.h"

namespace penumbra {

DirectLight::DirectLight(const Scene& scene, const PatchSet& patches) {
    const std::vector<char> small = smallSources(buildSystem(scene, patches));
    std::vector<char> whole(scene.objects.size(), 0);  // objects taken as one polygon
    for (size_t i = 0; i < small.size(); ++i) {
        if (!small[i]) continue;
        const int o = patches.object[i];
        const SceneObject& object = scene.objects[size_t(o)];
        const bool polygon = object.type == ShapeType::Quad || object.type == ShapeType::Triangle;
        if (polygon && whole[size_t(o)]) continue;
        Source s;
        if (polygon) {
            whole[size_t(o)] = 1;
            s.object = o;
            s.count = int(object.vertices.size());
            for (int k = 0; k < s.count; ++k) s.corner[size_t(k)] = object.vertices[size_t(k)];
        } else {
            s.count = patches.cornerCount[i];
            s.corner = patches.corners[i];
        }
        s.normal = patches.normal[i];  // the front the patches emit from
        s.centre = Vec3::Zero();
        for (int k = 0; k < s.count; ++k) s.centre += s.corner[size_t(k)] / double(s.count);
        s.exitance = kPi * scene.materialOf(object).emissionAt(nullptr);  // a textured lamp: its mean
        if (s.count == 4) {
            const double a = (s.corner[1] - s.corner[0]).cross(s.corner[2] - s.corner[0]).norm();
            const double b = (s.corner[2] - s.corner[0]).cross(s.corner[3] - s.corner[0]).norm();
            s.split = a + b > 0 ? a / (a + b) : 1;
        }
        sources_.push_back(s);
    }
}

Vec3 DirectLight::pointOn(const Source& s, double u1, double u2) const {
    int b = 1;
    if (u1 < s.split) {
        u1 /= s.split;
    } else {
        u1 = (u1 - s.split) / (1 - s.split);
        b = 2;
    }
    const double r = std::sqrt(u1);
    const Vec3& a = s.corner[0];
    return a + r * (1 - u2) * (s.corner[size_t(b)] - a) + r * u2 * (s.corner[size_t(b + 1)] - a);
}

double DirectLight::proveClearShafts(const SceneTracer& tracer) {
    const Scene& scene = tracer.scene();
    const PatchSet& patches = tracer.patches();
    clear_.clear();
    static_assert(kMostPolygons <= 64, "a source's proof is one bit of a 64-bit mask per patch");
    if (sources_.empty() || sources_.size() > kMostPolygons) return 0;
    std::vector<RaySphere> spheres;
    std::vector<char> replaced(patches.size(), 0);
    for (size_t o = 0; o < scene.objects.size(); ++o)
        if (const RaySphere* sphere = tracer.exactSphere(int(o))) spheres.push_back(*sphere);
    for (size_t i = 0; i < patches.size(); ++i) replaced[i] = tracer.exactSphere(patches.object[i]) != nullptr;
    const ClearShafts shafts(patches, spheres, replaced);
    clear_.assign(patches.size(), 0);
    std::atomic<uint64_t> facing{0}, proved{0};
    parallelFor(
        int64_t(patches.size()),
        [&](int64_t begin, int64_t end) {
            uint64_t myFacing = 0, myProved = 0;
            for (int64_t ii = begin; ii < end; ++ii) {
                const size_t i = size_t(ii);
                if (replaced[i]) continue;
                const SceneObject& object = scene.objects[size_t(patches.object[i])];
                // The segments start where the shadow rays do: off the surface by the tracer's epsilon.
                ShaftEnd a = patchEnd(patches, i, tracer.epsilon());
                const bool flat = object.type == ShapeType::Quad || object.type == ShapeType::Triangle;
                a.object = flat ? patches.object[i] : -1;
                for (size_t k = 0; k < sources_.size(); ++k) {
                    const Source& s = sources_[k];
                    if (!(s.normal.dot(patches.centroid[i] - s.centre) > 0) ||
                        !(a.normal.dot(s.centre - patches.centroid[i]) > 0))
                        continue;
                    ++myFacing;
                    ShaftEnd b;
                    b.count = s.count;
                    b.corner = s.corner;
                    b.normal = s.normal;
                    b.object = s.object;
                    if (shafts.clear(a, b)) clear_[i] |= uint64_t(1) << k, ++myProved;
                }
            }
            facing += myFacing, proved += myProved;
        },
        64);
    return facing > 0 ? double(proved) / double(facing) : 0;
}

template <typename Generator>
Rgb DirectLight::irradiance(const SceneTracer& tracer, const Vec3& x, const Vec3& n, int rays, Generator& rng,
                            int patch) const {
    const uint64_t proved = patch >= 0 && size_t(patch) < clear_.size() ? clear_[size_t(patch)] : 0;
    if (sources_.size() > kMostPolygons) {
        // Too many polygons to sum in closed form at every point (a lamp meshed finely): emitter
        // sampling, unbiased, noisy in full light too.
        Rgb sum = Rgb::Zero();
        for (int r = 0; r < rays; ++r) {
            const LightSample l = tracer.sampleLight(x, n, rng);
            if (l.found()) sum += l.radiance * (l.cosine / l.pdf);
        }
        return sum / rays;
    }
    thread_local std::vector<Rgb> full;
    thread_local std::vector<double> cumulative;
    const size_t count = sources_.size();
    full.resize(count);
    cumulative.resize(count);
    double total = 0;
    for (size_t k = 0; k < count; ++k) {
        const Source& s = sources_[k];
        // Only a source's front lights x (a ceiling above a lamp hung below it sees its back).
        const bool front = s.normal.dot(x - s.centre) > 0;
        const double f = front ? pointPolygonFormFactor(x, n, s.corner.data(), s.count) : 0;
        full[k] = f > 0 ? Rgb(f * s.exitance) : Rgb::Zero();
        total += full[k].sum();
        cumulative[k] = total;
    }
    if (!(total > 0)) return Rgb::Zero();
    // The rays stratified over the sources laid end to end by their unoccluded light, and within each
    // over its area: one source and a square count of rays make a jittered grid on it. A source's
    // visible share is that of its rays' points in front of x, each weighed by the kernel
    // cos cos / r^2 of the closed form (uniform weights read a penumbra 10-20% off where the kernel
    // changes across a lamp 0.5 m wide at 1 m); the closed form leaves out the part of a source
    // behind x's plane, and rays to it would find x's own surface in the way. A source no such ray
    // reached takes the share of all the rays.
    thread_local std::vector<std::array<double, 2>> seen;  // per source: weight in front of x, and of it arrived
    seen.assign(count, {0, 0});
    const int side = stratumSide(rays);
    const bool grid = count == 1 && side * side == rays;
    constexpr bool shifted = std::is_same_v<Generator, PixelSampler>;
    double shift[2] = {0, 0};
    if (shifted && grid) shift[0] = rng.uniform(), shift[1] = rng.uniform();
    size_t k = 0;
    for (int r = 0; r < rays; ++r) {
        double u1, u2;
        if (grid) {
            u1 = ((r % side) + (shifted ? shift[0] : rng.uniform())) / side;
            u2 = ((r / side) + (shifted ? shift[1] : rng.uniform())) / side;
        } else {
            const double u = (r + rng.uniform()) / rays * total;
            while (k + 1 < count && cumulative[k] <= u) ++k;
            const double low = k > 0 ? cumulative[k - 1] : 0;
            u1 = std::clamp((u - low) / (cumulative[k] - low), 0.0, 1.0 - 1e-12);
            u2 = rng.uniform();
        }
        const Source& s = sources_[k];
        const Vec3 y = pointOn(s, u1, u2);
        const double w = sourceKernel(x, n, y, s.normal);
        if (!(w > 0)) continue;
        seen[k][0] += w;
        // The ray gives up the last thousandth of its length at the lamp: a point of a quad lamp that
        // is not quite flat lies a little off the triangles Embree traces it as (as the display's
        // vertex rays do, vertex_radiosity.h).
        if (((proved >> k) & 1) || tracer.visible(x, y + 1e-3 * (x - y))) seen[k][1] += w;
    }
    double front = 0, arrived = 0;
    for (const auto& c : seen) front += c[0], arrived += c[1];
    const double share = front > 0 ? arrived / front : 1;
    Rgb E = Rgb::Zero();
    for (size_t j = 0; j < count; ++j) E += full[j] * (seen[j][0] > 0 ? seen[j][1] / seen[j][0] : share);
    return E;
}

template Rgb DirectLight::irradiance(const SceneTracer&, const Vec3&, const Vec3&, int, Rng&, int) const;
template Rgb DirectLight::irradiance(const SceneTracer&, const Vec3&, const Vec3&, int, PixelSampler&, int) const;

}  // namespace penumbra
