#include "render/photon_map.h"

#include <nanoflann.hpp>

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

}  // namespace

struct PhotonMap::Impl {
    PointCloud<Photon> cloud;
    std::unique_ptr<KdTree<Photon>> tree;
    PointCloud<IrradiancePoint> precomputed;
    std::unique_ptr<KdTree<IrradiancePoint>> precomputedTree;
};

PhotonMap::PhotonMap(const SceneTracer& tracer, const PhotonSettings& settings)
    : impl_(std::make_unique<Impl>()), nearest_(settings.nearest) {
    Timer timer;
    maxRadius_ = settings.maxRadius * tracer.diagonal();
    const int64_t n = tracer.hasEmitters() ? settings.photons : 0;
    const int64_t chunks = (n + kChunk - 1) / kChunk;
    std::vector<std::vector<Photon>> stored(static_cast<size_t>(chunks));
    std::vector<Rgb> emitted(static_cast<size_t>(chunks), Rgb::Zero());
    Progress progress("photons", chunks);
    parallelFor(chunks, [&](int64_t c0, int64_t c1) {
        prepareTracingThread();
        for (int64_t c = c0; c < c1; ++c) {
            for (int64_t k = c * kChunk; k < std::min(n, (c + 1) * kChunk); ++k) {
                Rng rng = streamRng(settings.seed, Stream::Photons, uint64_t(k));
                const EmitterSample e = tracer.sampleEmitter(rng);
                // Cosine-distributed emission: the power is pi L_e / (pdf_area N).
                Rgb power = kPi * e.radiance / (e.pdfArea * double(n));
                emitted[size_t(c)] += power;
                const Vec3 d = cosineDirection(e.normal, rng);
                const SpecularWalk w = walkSpecular(tracer, tracer.trace(e.point + tracer.epsilon() * e.normal, d), d,
                                                    rng, settings.maxDepth);
                if (w.end == WalkEnd::Diffuse && w.bounces > 0 && w.hit.frontFacing(w.dir))
                    stored[size_t(c)].push_back({w.hit.point.cast<float>(), w.hit.normal.cast<float>(),
                                                 Rgb(power * w.throughput).matrix().cast<float>()});
            }
            progress.update();
        }
    });
    progress.done();
    for (size_t c = 0; c < stored.size(); ++c) {
        stats_.emittedPower += emitted[c];
        for (const Photon& p : stored[c]) {
            impl_->cloud.points.push_back(p);
            stats_.storedPower += p.power.cast<double>().array();
        }
    }
    stats_.emitted = n;
    stats_.stored = int64_t(impl_->cloud.points.size());
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
    logInfo("caustic photons: ", stats_.stored, " stored of ", stats_.emitted, " emitted (", stats_.storedPower.sum(),
            " W of ", stats_.emittedPower.sum(), " W) in ", stats_.seconds, " s");
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
