#include "render/photon_map.h"

#include <array>
#include <cmath>
#include <nanoflann.hpp>

#include "core/cluster.h"
#include "core/counters.h"
#include "core/log.h"
#include "core/optics.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "core/timer.h"

namespace penumbra {
namespace {

const Counter g_photonsEmitted("photons.emitted", "caustic photons emitted from the lights");
const Counter g_photonsStored("photons.stored",
                              "caustic photons stored (landed on a diffuse surface after a specular bounce)");

struct Photon {
    Eigen::Vector3f position;
    Eigen::Vector3f normal;  // of the surface it landed on
    Eigen::Vector3f power;   // W per channel
};

// The estimate precomputed at a stored photon, valid within sqrt(radius2) of it.
struct IrradiancePoint {
    Eigen::Vector3f position, normal, irradiance;
    float radius2;
};

// nanoflann's view of an array of photons or of precomputed points.
template <typename Point>
struct PointCloud {
    std::vector<Point> points;
    size_t kdtree_get_point_count() const { return points.size(); }
    float kdtree_get_pt(size_t i, size_t d) const { return points[i].position[Eigen::Index(d)]; }
    template <class Box>
    bool kdtree_get_bbox(Box&) const {
        return false;
    }
};
template <typename Point>
using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, PointCloud<Point>>,
                                                   PointCloud<Point>, 3, uint32_t>;

constexpr int64_t kChunk = 4096;  // photons per work item; the merge order is the chunk order

// The spheres photons are aimed at: one around each mirror or glass object (its exact sphere, or the
// smallest ball about its corners' box centre), a hair larger.
struct Target {
    Vec3 centre;
    double radius;
};
std::vector<Target> specularTargets(const SceneTracer& tracer) {
    const Scene& scene = tracer.scene();
    const PatchSet& p = tracer.patches();
    const std::vector<std::vector<size_t>> byObject = p.byObject(scene.objects.size());
    const double hair = 1e-6 * tracer.diagonal();
    std::vector<Target> targets;
    for (size_t o = 0; o < scene.objects.size(); ++o) {
        if (scene.materialOf(scene.objects[o]).type == MaterialType::Diffuse) continue;
        if (const RaySphere* sphere = tracer.exactSphere(int(o))) {
            targets.push_back({sphere->center, sphere->radius * (1 + 1e-6) + hair});
            continue;
        }
        Eigen::AlignedBox3d box;
        for (size_t i : byObject[o])
            for (int k = 0; k < p.cornerCount[i]; ++k) box.extend(p.corners[i][size_t(k)]);
        if (box.isEmpty()) continue;
        const Vec3 centre = box.center();
        double radius = 0;
        for (size_t i : byObject[o])
            for (int k = 0; k < p.cornerCount[i]; ++k)
                radius = std::max(radius, (p.corners[i][size_t(k)] - centre).norm());
        targets.push_back({centre, radius * (1 + 1e-6) + hair});
    }
    return targets;
}

// The cones from a lamp's point x (front normal n) that hold the targets, and a density over their
// directions: cone s taken with a weight of its solid angle times the most cosine any of it can have
// (none behind the lamp), uniform within. Directions in two cones have both's density.
class Aim {
public:
    static constexpr size_t kMostTargets = 16;
    Aim(const std::vector<Target>& targets, const Vec3& x, const Vec3& n) : count_(targets.size()) {
        total_ = 0;
        for (size_t s = 0; s < count_; ++s) {
            Cone& c = cone_[s];
            const Vec3 d = targets[s].centre - x;
            const double distance = d.norm(), sin2 = std::min(1.0, std::pow(targets[s].radius / distance, 2));
            c.axis = d / distance;
            c.cosMax = std::sqrt(1 - sin2);
            c.oneMinusCos = sin2 / (1 + c.cosMax);  // 1 - cos, without cancellation for small cones
            c.solidAngle = 2 * kPi * c.oneMinusCos;
            // The most cosine within the cone: cos(angle to the axis - the cone's half-angle).
            const double cosAxis = n.dot(c.axis), sinAxis = std::sqrt(std::max(0.0, 1 - cosAxis * cosAxis));
            const double most = cosAxis * c.cosMax + sinAxis * std::sqrt(sin2);
            c.weight = most > 0 ? c.solidAngle * std::min(1.0, most) : 0;
            total_ += c.weight;
        }
    }
    // The cosine-weighted share of the hemisphere the cones can hold, at most (sizes the pass).
    double share() const {
        double sum = 0;
        for (size_t s = 0; s < count_; ++s) sum += cone_[s].weight / kPi;
        return sum;
    }
    bool empty() const { return !(total_ > 0); }
    Vec3 sample(double u, double u1, double u2) const {
        size_t s = 0;
        double pick = u * total_;
        while (s + 1 < count_ && pick >= cone_[s].weight) pick -= cone_[s].weight, ++s;
        const Cone& c = cone_[s];
        const double cosT = 1 - u1 * c.oneMinusCos, sinT = std::sqrt(std::max(0.0, 1 - cosT * cosT));
        const double phi = 2 * kPi * u2;
        Vec3 t, b;
        orthonormalBasis(c.axis, t, b);
        return (cosT * c.axis + sinT * std::cos(phi) * t + sinT * std::sin(phi) * b).normalized();
    }
    double pdf(const Vec3& d) const {
        double p = 0;
        for (size_t s = 0; s < count_; ++s)
            if (cone_[s].weight > 0 && d.dot(cone_[s].axis) >= cone_[s].cosMax)
                p += cone_[s].weight / total_ / cone_[s].solidAngle;
        return p;
    }

private:
    struct Cone {
        Vec3 axis;
        double cosMax, oneMinusCos, solidAngle, weight;
    };
    size_t count_;
    std::array<Cone, kMostTargets> cone_;
    double total_;
};

// How many photons to aim for `n` emitted: n times the share of the lamps' light the cones can hold
// (over emitter points drawn by power), or 0 where aiming does not pay or cannot be done.
int64_t aimedPhotons(const SceneTracer& tracer, const std::vector<Target>& targets, int64_t n, uint64_t seed) {
    if (targets.empty() || targets.size() > Aim::kMostTargets || n <= 0) return 0;
    // A lamp point inside a sphere sees it in every direction: no cone holds it. Any lamp patch
    // within reach of a sphere (its centroid nearer than the two radii) keeps plain emission.
    const PatchSet& p = tracer.patches();
    for (size_t i = 0; i < p.size(); ++i)
        if (tracer.emitterPdfArea(int(i)) > 0)
            for (const Target& t : targets)
                if ((p.centroid[i] - t.centre).norm() <= t.radius + p.radius[i]) return 0;
    constexpr int kPoints = 1024;
    double share = 0;
    for (int j = 0; j < kPoints; ++j) {
        Rng rng = streamRng(seed, Stream::PhotonAim, uint64_t(j));
        const EmitterSample e = tracer.sampleEmitter(rng);
        share += std::min(1.0, Aim(targets, e.point, e.normal).share()) / kPoints;
    }
    if (!(share < 0.5)) return 0;
    return std::max<int64_t>(1, int64_t(std::ceil(double(n) * share)));
}

}  // namespace

struct PhotonMap::Impl {
    PointCloud<Photon> cloud;
    std::unique_ptr<KdTree<Photon>> tree;
    PointCloud<IrradiancePoint> precomputed;
    std::unique_ptr<KdTree<IrradiancePoint>> precomputedTree;
};

PhotonStats traceCausticPhotons(const SceneTracer& tracer, const PhotonSettings& settings, Stream stream,
                                const char* title, const std::function<void(int64_t chunks)>& begin,
                                const std::function<void(int64_t chunk, const std::vector<PhotonLanding>&)>& land) {
    PhotonStats stats;
    const int64_t emitting = tracer.hasEmitters() ? settings.photons : 0;
    const std::vector<Target> targets = settings.aim ? specularTargets(tracer) : std::vector<Target>{};
    const int64_t aimed = settings.aim ? aimedPhotons(tracer, targets, emitting, settings.seed) : 0;
    const int64_t n = aimed > 0 ? aimed : emitting;  // photons traced
    const int64_t chunks = (n + kChunk - 1) / kChunk;
    begin(chunks);
    std::vector<Rgb> emitted(static_cast<size_t>(chunks), Rgb::Zero()), stored(emitted);
    std::vector<int64_t> count(static_cast<size_t>(chunks), 0);
    // Under mpirun each rank traces its own chunks (cluster::owns) and the callers share what they kept.
    const CounterValues before = counterValues();
    std::vector<int64_t> own;
    for (int64_t c = 0; c < chunks; ++c)
        if (cluster::owns(c)) own.push_back(c);
    Progress progress(title, int64_t(own.size()));
    parallelFor(int64_t(own.size()), [&](int64_t k0, int64_t k1) {
        prepareTracingThread();
        std::vector<PhotonLanding> landings;
        for (int64_t kc = k0; kc < k1; ++kc) {
            const int64_t c = own[size_t(kc)];
            landings.clear();
            for (int64_t k = c * kChunk; k < std::min(n, (c + 1) * kChunk); ++k) {
                Rng rng = streamRng(settings.seed, stream, uint64_t(k));
                const EmitterSample e = tracer.sampleEmitter(rng);
                Rgb power;
                Vec3 d;
                if (aimed > 0) {
                    // Towards the spheres: the power is L_e cos / (pdf_area pdf_direction N).
                    const Aim aim(targets, e.point, e.normal);
                    if (aim.empty()) continue;
                    const double u = rng.uniform(), u1 = rng.uniform(), u2 = rng.uniform();
                    d = aim.sample(u, u1, u2);
                    const double cosine = e.normal.dot(d), pdf = aim.pdf(d);
                    if (!(cosine > 0) || !(pdf > 0)) continue;
                    power = e.radiance * cosine / (e.pdfArea * pdf * double(n));
                } else {
                    // Cosine-distributed emission: the power is pi L_e / (pdf_area N).
                    power = kPi * e.radiance / (e.pdfArea * double(n));
                    d = cosineDirection(e.normal, rng);
                }
                emitted[size_t(c)] += power;
                SpecularWalk w = walkSpecular(tracer, tracer.trace(e.point + tracer.epsilon() * e.normal, d), d, rng,
                                              settings.maxDepth);
                if (w.end == WalkEnd::Diffuse && w.bounces > 0 && w.hit.frontFacing(w.dir)) {
                    landings.push_back({std::move(w.hit), w.dir, Rgb(power * w.throughput)});
                    stored[size_t(c)] += landings.back().power;
                }
            }
            count[size_t(c)] = int64_t(landings.size());
            land(c, landings);
            progress.update();
        }
    });
    progress.done();
    cluster::shareValues(emitted);
    cluster::shareValues(stored);
    cluster::shareValues(count);
    cluster::shareCounters(before);
    for (size_t c = 0; c < emitted.size(); ++c) {
        (aimed > 0 ? stats.aimedPower : stats.emittedPower) += emitted[c];
        stats.storedPower += stored[c];
        stats.stored += count[c];
    }
    stats.emitted = emitting;
    stats.aimed = aimed;
    if (aimed > 0) stats.emittedPower = tracer.emittedPower();
    return stats;
}

PhotonMap::PhotonMap(const SceneTracer& tracer, const PhotonSettings& settings)
    : impl_(std::make_unique<Impl>()), nearest_(settings.nearest) {
    Timer timer;
    maxRadius_ = settings.maxRadius * tracer.diagonal();
    std::vector<std::vector<Photon>> stored;
    stats_ = traceCausticPhotons(
        tracer, settings, Stream::Photons, "photons", [&](int64_t chunks) { stored.resize(size_t(chunks)); },
        [&](int64_t c, const std::vector<PhotonLanding>& landings) {
            for (const PhotonLanding& l : landings)
                stored[size_t(c)].push_back(
                    {l.hit.point.cast<float>(), l.hit.normal.cast<float>(), l.power.matrix().cast<float>()});
        });
    cluster::shareChunks(stored);
    for (const std::vector<Photon>& chunk : stored)
        impl_->cloud.points.insert(impl_->cloud.points.end(), chunk.begin(), chunk.end());
    g_photonsEmitted.add(uint64_t(stats_.emitted));
    g_photonsStored.add(uint64_t(stats_.stored));
    impl_->tree = std::make_unique<KdTree<Photon>>(3, impl_->cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
    if (settings.precompute > 0 && !impl_->cloud.points.empty()) {
        const size_t stride = size_t(settings.precompute), count = (impl_->cloud.points.size() + stride - 1) / stride;
        impl_->precomputed.points.resize(count);
        parallelFor(
            int64_t(count),
            [&](int64_t b, int64_t e) {
                for (int64_t k = b; k < e; ++k) {
                    const Photon& p = impl_->cloud.points[size_t(k) * stride];
                    double radius = 0;
                    // Leave the photon itself out: an estimate at a photon's own position always counts
                    // that photon at the filter's full weight, which biases it up by about 1.5/k.
                    const Rgb E =
                        estimate(p.position.cast<double>(), p.normal.cast<double>(), &radius, size_t(k) * stride);
                    impl_->precomputed.points[size_t(k)] = {p.position, p.normal, E.matrix().cast<float>(),
                                                            float(radius * radius)};
                }
            },
            256);
        impl_->precomputedTree = std::make_unique<KdTree<IrradiancePoint>>(
            3, impl_->precomputed, nanoflann::KDTreeSingleIndexAdaptorParams(16));
    }
    stats_.seconds = timer.seconds();
    if (stats_.aimed > 0)
        logInfo("caustic photons: ", stats_.stored, " stored of ", stats_.aimed,
                " aimed at the mirrors and glass (for ", stats_.emitted, " emitted; ", stats_.storedPower.sum(),
                " W of ", stats_.aimedPower.sum(), " W sent at them, ", stats_.emittedPower.sum(), " W emitted) in ",
                stats_.seconds, " s");
    else
        logInfo("caustic photons: ", stats_.stored, " stored of ", stats_.emitted, " emitted (",
                stats_.storedPower.sum(), " W of ", stats_.emittedPower.sum(), " W) in ", stats_.seconds, " s");
}

PhotonMap::~PhotonMap() = default;

std::vector<PhotonMap::Stored> PhotonMap::storedPhotons() const {
    std::vector<Stored> out;
    out.reserve(impl_->cloud.points.size());
    for (const Photon& p : impl_->cloud.points)
        out.push_back({p.position.cast<double>(), p.normal.cast<double>(), p.power.cast<double>().array()});
    return out;
}

Rgb PhotonMap::irradiance(const Vec3& x, const Vec3& n) const {
    if (!impl_->precomputedTree) return estimate(x, n);
    // The nearest precomputed point on a surface facing the same way, if x lies within its disc:
    // first the nearest alone (the usual case, and the cheapest search), then a few more where it
    // lies on a surface facing elsewhere (a corner).
    const Eigen::Vector3f q = x.cast<float>(), nf = n.cast<float>();
    for (size_t candidates : {size_t(1), size_t(8)}) {
        uint32_t index[8];
        float dist2[8];
        nanoflann::KNNResultSet<float, uint32_t> result(candidates);
        result.init(index, dist2);
        dist2[candidates - 1] = float(maxRadius_ * maxRadius_);
        impl_->precomputedTree->findNeighbors(result, q.data(), nanoflann::SearchParams());
        bool facingElsewhere = false;
        for (size_t i = 0; i < result.size(); ++i) {
            const IrradiancePoint& p = impl_->precomputed.points[index[i]];
            if (p.normal.dot(nf) < 0.9f) {
                facingElsewhere = true;
                continue;
            }
            if (dist2[i] <= p.radius2) return p.irradiance.cast<double>().array();
        }
        if (!facingElsewhere) break;
    }
    return Rgb::Zero();
}

Rgb PhotonMap::estimate(const Vec3& x, const Vec3& n, double* radius, size_t exclude) const {
    if (radius) *radius = 0;
    if (impl_->cloud.points.empty()) return Rgb::Zero();
    const size_t k = size_t(nearest_);
    // Called at every shading point: the result buffers live with the thread, not the call.
    thread_local std::vector<uint32_t> index;
    thread_local std::vector<float> dist2;
    index.resize(k);
    dist2.resize(k);
    const Eigen::Vector3f q = x.cast<float>();
    // k nearest, but none beyond the largest radius: seeding the k-th distance with it lets the
    // tree skip everything farther (in sparse regions most of the tree).
    nanoflann::KNNResultSet<float, uint32_t> result(k);
    result.init(index.data(), dist2.data());
    dist2[k - 1] = float(maxRadius_ * maxRadius_);
    impl_->tree->findNeighbors(result, q.data(), nanoflann::SearchParams());
    const size_t found = result.size();
    if (found == 0) return Rgb::Zero();
    const double r2 = found == k ? double(dist2[k - 1]) : maxRadius_ * maxRadius_;
    if (r2 <= 0) return Rgb::Zero();
    const double r = std::sqrt(r2);
    if (radius) *radius = r;
    constexpr double kCone = 1.1;
    Rgb sum = Rgb::Zero();
    const Eigen::Vector3f nf = n.cast<float>();
    for (size_t i = 0; i < found; ++i) {
        if (dist2[i] > r2) break;
        if (index[i] == exclude) continue;
        const Photon& p = impl_->cloud.points[index[i]];
        if (p.normal.dot(nf) < 0.9f) continue;
        const double w = 1 - std::sqrt(double(dist2[i])) / (kCone * r);
        sum += w * p.power.cast<double>().array();
    }
    return sum / ((1 - 2 / (3 * kCone)) * kPi * r2);
}

}  // namespace penumbra
