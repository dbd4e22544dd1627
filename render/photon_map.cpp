#include "render/photon_map.h"

#include <nanoflann.hpp>

#include "core/log.h"
#include "core/optics.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "core/timer.h"

namespace penumbra {
namespace {

struct Photon {
    Eigen::Vector3f position;
    Eigen::Vector3f normal;   // of the surface it landed on
    Eigen::Vector3f power;    // W per channel
};

// nanoflann's view of the photon array.
struct PhotonCloud {
    std::vector<Photon> photons;
    size_t kdtree_get_point_count() const { return photons.size(); }
    float kdtree_get_pt(size_t i, size_t d) const { return photons[i].position[Eigen::Index(d)]; }
    template <class Box>
    bool kdtree_get_bbox(Box&) const { return false; }
};

using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, PhotonCloud>, PhotonCloud, 3,
                                                 uint32_t>;

constexpr int64_t kChunk = 4096;   // photons per work item; the merge order is the chunk order

}  // namespace

struct PhotonMap::Impl {
    PhotonCloud cloud;
    std::unique_ptr<Tree> tree;
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
                Rng rng(mixSeed(settings.seed, 0x9407, uint64_t(k)));
                const EmitterSample e = tracer.sampleEmitter(rng);
                // Cosine-distributed emission: the power is pi L_e / (pdf_area N).
                Rgb power = kPi * e.radiance / (e.pdfArea * double(n));
                emitted[size_t(c)] += power;
                Vec3 d = cosineDirection(e.normal, rng);
                Vec3 o = e.point + tracer.epsilon() * e.normal;
                bool specular = false;
                for (int depth = 0; depth < settings.maxDepth; ++depth) {
                    const SurfaceHit hit = tracer.trace(o, d);
                    if (!hit.found) break;
                    if (hit.material->type == MaterialType::Diffuse) {
                        if (specular && hit.frontFacing(d))
                            stored[size_t(c)].push_back({hit.point.cast<float>(), hit.normal.cast<float>(),
                                                         power.matrix().cast<float>()});
                        break;
                    }
                    const std::optional<SpecularBranch> b = sampleSpecular(hit, d, rng);
                    if (!b) break;
                    power *= b->weight;
                    d = b->dir;
                    o = tracer.offset(hit, d);
                    specular = true;
                }
            }
            progress.update();
        }
    });
    progress.done();
    for (size_t c = 0; c < stored.size(); ++c) {
        stats_.emittedPower += emitted[c];
        for (const Photon& p : stored[c]) {
            impl_->cloud.photons.push_back(p);
            stats_.storedPower += p.power.cast<double>().array();
        }
    }
    stats_.emitted = n;
    stats_.stored = int64_t(impl_->cloud.photons.size());
    impl_->tree = std::make_unique<Tree>(3, impl_->cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
    stats_.seconds = timer.seconds();
    logInfo("caustic photons: ", stats_.stored, " stored of ", stats_.emitted, " emitted (", stats_.storedPower.sum(),
            " W of ", stats_.emittedPower.sum(), " W) in ", stats_.seconds, " s");
}

PhotonMap::~PhotonMap() = default;

Rgb PhotonMap::irradiance(const Vec3& x, const Vec3& n) const {
    if (impl_->cloud.photons.empty()) return Rgb::Zero();
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
    constexpr double kCone = 1.1;
    Rgb sum = Rgb::Zero();
    const Eigen::Vector3f nf = n.cast<float>();
    for (size_t i = 0; i < found; ++i) {
        if (dist2[i] > r2) break;
        const Photon& p = impl_->cloud.photons[index[i]];
        if (p.normal.dot(nf) < 0.9f) continue;
        const double w = 1 - std::sqrt(double(dist2[i])) / (kCone * r);
        sum += w * p.power.cast<double>().array();
    }
    return sum / ((1 - 2 / (3 * kCone)) * kPi * r2);
}

}  // namespace penumbra
