#include "solver/radiosity/specular_transport.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>
#include <type_traits>

#include "core/counters.h"
#include "core/cumulative.h"
#include "core/error.h"
#include "core/log.h"
#include "core/optics.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "core/sobol.h"
#include "core/timer.h"

namespace penumbra {

// What the paths found, summed per source patch: each one's entries sorted by (group, kind, target),
// kept in the part of its bucket of sources where they were collated (a copy into one array was 5.6 MB
// of fresh pages on cornell-glass, and a fresh page costs this machine about 10 us).
struct SpecularPaths {
    enum Kind : uint8_t { Weight = 0, Delivered = 1, Lost = 2 };
    // Summed in double, kept in float (32 bytes, where doubles took 56: cornell-glass has 101k).
    struct Entry {
        int group;             // the mirror or glass object the light met first (index into the groups)
        Kind kind;             // Weight: the paths' etendue from the source; else a fate
        int target;            // patch (delivered) or object (lost)
        Eigen::Array3f value;  // m^2: etendue times the share that got there (Weight: what the same paths delivered)
        float square = 0;      // sum of the paths' values squared (Weight: their etendue's; Delivered: channels' mean)
        float weight = 0;      // Weight: the paths' etendue from the source, m^2
        Rgb light() const { return value.cast<double>(); }
    };
    static_assert(sizeof(Entry) == 32);
    struct Row {
        const Entry *from, *to;
        const Entry* begin() const { return from; }
        const Entry* end() const { return to; }
    };
    std::vector<std::vector<Entry>> parts;            // per bucket of 2^shift sources
    std::vector<std::pair<uint32_t, uint32_t>> span;  // per source patch, its entries in its bucket's part
    int shift = 0;
    int64_t paths = 0, rays = 0;
    bool reversed = false;  // some paths were traced from the receivers (SpecularSettings::receiverShare)

    Row row(size_t i) const {
        const Entry* part = parts[i >> shift].data();
        return {part + span[i].first, part + span[i].second};
    }
    size_t entries() const {
        size_t count = 0;
        for (const std::vector<Entry>& p : parts) count += p.size();
        return count;
    }

    // The factor, per channel, that brings what source i's entries deliver through group g (the balance
    // heuristic's sum over both directions) to what its paths from the ball's surface delivered: so each
    // row's fates still sum to its share (1 where no path was traced the other way).
    Rgb deliveredScale(size_t i, int g) const {
        if (!reversed) return Rgb::Ones();
        Rgb reached = Rgb::Zero(), sum = Rgb::Zero();
        for (const Entry& e : row(i)) {
            if (e.group != g) continue;
            if (e.kind == Weight) reached += e.light();
            if (e.kind == Delivered) sum += e.light();
        }
        return (sum > 0).select(reached / sum.max(1e-300), Rgb::Ones());
    }
};

namespace {

const Counter g_transportRays("specular.rays", "rays of the specular transport (paths' first rays and bounces)");

struct Transfer {
    int target;
    Rgb share;
    double square = 0;  // sum over the paths of the square of each one's share (mean of the channels)
};

struct RowResult {
    std::vector<Transfer> delivered;  // target patch, S(i -> j)
    std::vector<Transfer> lost;       // object, share absorbed
    double unresolved = 0;
    // A delivered or lost entry of the paths, `scale` times (per unit of this row's share); a delivered
    // one `reach` times more (deliveredScale).
    void add(const SpecularPaths::Entry& e, double scale, const Rgb& reach) {
        if (e.kind == SpecularPaths::Delivered) {
            const double r = reach.sum() / 3;
            delivered.push_back({e.target, Rgb(scale * reach * e.light()), scale * scale * r * r * e.square});
        } else {
            lost.push_back({e.target, Rgb(scale * e.light())});
        }
    }
};

// A mirror or glass object: its surface, to start paths from.
struct Group {
    int object = -1;
    const RaySphere* sphere = nullptr;  // traced exactly, or else its patches
    std::vector<size_t> patches;
    CumulativeTable cdf;  // over the patches, by area (not on a sphere)
    double area = 0;      // m^2 paths start from (both sides of an open surface)
    int64_t paths = 0;
    // On a sphere an aimed path starts in the cap that sees the aimed patch's centroid (pole, cos of
    // its angular radius): the rest of the sphere sees little or none of the patch.
    struct Aim {
        double density = 0;  // the patch's chance per m^2 of being aimed at
        Vec3 pole = Vec3::UnitZ();
        double cosCap = 0;
        double inCap = 2;  // 2 / (1 - cosCap)
        // How much denser than uniform over the sphere aimed points are at normal n (0 outside the cap).
        double capFactor(const Vec3& n) const { return n.dot(pole) >= cosCap ? inCap : 0.0; }
    };
    // Patches to aim at: `patch` picked by `cdf` (cumulative, normalised), each one's Aim, and per
    // patch of the scene its place in them (-1: not aimed at; a hash map's lookups were 1.5% of a
    // cornell-glass solve's samples).
    struct Aims {
        std::vector<int> patch;
        CumulativeTable cdf;
        std::vector<Aim> aim;
        std::vector<PatchPointSampler> point;  // points on each patch (its triangles found once)
        std::vector<int> index;
        bool empty() const { return patch.empty(); }
        const Aim* find(int p) const {
            if (p < 0 || size_t(p) >= index.size() || index[size_t(p)] < 0) return nullptr;
            return &aim[size_t(index[size_t(p)])];
        }
    };
    Aims aims;       // by the light each patch sends into the object
    Aims receivers;  // the patches paths are traced back from (SpecularSettings::receiverShare)
};

// Sorts by target and sums the entries of equal targets.
void mergeByTarget(std::vector<Transfer>& v) {
    std::sort(v.begin(), v.end(), [](const Transfer& a, const Transfer& b) { return a.target < b.target; });
    size_t out = 0;
    for (size_t k = 0; k < v.size(); ++k) {
        if (out > 0 && v[out - 1].target == v[k].target) {
            v[out - 1].share += v[k].share;
            v[out - 1].square += v[k].square;
        } else {
            v[out++] = v[k];
        }
    }
    v.resize(out);
}

// Light arriving along `dir` at `hit`, a mirror or glass surface, carrying `carried`, on to its fates:
// lose(object, share) where an object absorbs it, deliver(at, along, share) where it lands on the front
// of a diffuse patch (at, arriving along `along`); every branch for the first `split` bounces, then one
// branch at a time by its odds (walkSpecular), `depth` bounces in all.
template <typename Lose, typename Deliver>
void followSpecular(const SceneTracer& tracer, const SurfaceHit& hit, const Vec3& dir, const Rgb& carried, int depth,
                    int split, Rng& rng, int64_t& rays, const Lose& lose, const Deliver& deliver) {
    if (depth <= 0) {
        lose(hit.object, carried);
        return;
    }
    auto land = [&](const SurfaceHit& at, const Vec3& along, const Rgb& light) {
        if (!at.found) return;  // out of the scene: the remainder of the balance
        if (at.frontFacing(along))
            deliver(at, along, light);
        else
            lose(at.object, light);
    };
    if (split <= 0) {
        const SpecularWalk walk = walkSpecular(tracer, hit, dir, rng, depth, 0.0,
                                               [&](int object, const Rgb& part) { lose(object, Rgb(carried * part)); });
        rays += walk.bounces;
        if (walk.end == WalkEnd::Diffuse)
            land(walk.hit, walk.dir, carried * walk.throughput);
        else if (walk.end != WalkEnd::Escaped)
            lose(walk.hit.object, carried * walk.throughput);
        return;
    }
    SpecularBranch branch[2];
    const int branches = specularBranches(hit, dir, branch);
    Rgb kept = Rgb::Ones();
    for (int b = 0; b < branches; ++b) kept -= branch[b].weight;
    if ((kept > 0).any()) lose(hit.object, Rgb(carried * kept.max(0.0)));
    for (int b = 0; b < branches; ++b) {
        const SurfaceHit next = tracer.trace(tracer.offset(hit, branch[b].dir), branch[b].dir);
        ++rays;
        const Rgb light = carried * branch[b].weight;
        if (next.found && next.material->type != MaterialType::Diffuse)
            followSpecular(tracer, next, branch[b].dir, light, depth - 1, split - 1, rng, rays, lose, deliver);
        else
            land(next, branch[b].dir, light);
    }
}

std::shared_ptr<const SpecularPaths> tracePaths(const Scene& scene, const PatchSet& patches, const SceneTracer& tracer,
                                                const SpecularSettings& settings, std::vector<Group>& groups,
                                                int64_t total) {
    using Entry = SpecularPaths::Entry;
    // Paths by area, glass's four times as dense: on cornell-glass its ball carried most of the noise
    // (over 16 seeds at 64 paths a patch, 8x the mirror ball's paths left the objects' rms error at
    // 0.83%, 4x the glass ball's took it to 0.45%; the default 128 a patch, so weighted: 0.46%).
    auto density = [&](const Group& g) {
        const bool glass = scene.materialOf(scene.objects[size_t(g.object)]).type == MaterialType::Dielectric;
        return g.area * (glass ? 4.0 : 1.0);
    };
    double area = 0;
    for (const Group& g : groups) area += density(g);
    // Whole blocks of 1,024 (256 for a small set, such as the first: so the two threads share it
    // evenly): each strategy's points in a block are an aligned run of its Sobol set, a net.
    const int64_t kBlock = total < 65536 ? 256 : 1024;
    std::vector<std::pair<size_t, int64_t>> blocks;  // group, first path
    for (size_t g = 0; g < groups.size(); ++g) {
        groups[g].paths =
            kBlock *
            std::max<int64_t>(1, (int64_t(std::ceil(double(total) * density(groups[g]) / area)) + kBlock / 2) / kBlock);
        for (int64_t b = 0; b < groups[g].paths; b += kBlock) blocks.emplace_back(g, b);
    }
    const double share = std::clamp(settings.aimedShare, 0.0, 1.0);
    const double receiverShare = std::clamp(settings.receiverShare, 0.0, 0.95);
    // What one path found, as compact as it goes (20 bytes; cornell-glass's paths write 366k): summed
    // in double once collated, with the squares (a Weight's etendue's, a Delivered's channels' mean's)
    // taken then. The object the light met first is the block's.
    struct Found {
        uint32_t source : 30, kind : 2;
        union {
            int target;    // Delivered: the patch; Lost: the object
            float weight;  // Weight: the path's etendue from the source, m^2
        };
        float value[3];
    };
    static_assert(std::is_trivial_v<Found> && sizeof(Found) == 20);
    PENUMBRA_CHECK_OP(patches.size(), <, size_t(1) << 30);
    auto record = [](int source, SpecularPaths::Kind kind, int target, const Rgb& v) {
        Found f;
        f.source = uint32_t(source);
        f.target = target;
        f.kind = kind;
        for (int c = 0; c < 3; ++c) f.value[c] = float(v[c]);
        return f;
    };
    // Each block's records, sorted while still in cache into buckets of 2^shift source patches
    // (bucketStart per block); a bucket's records are collated in cache afterwards. (A scatter of
    // every record to its source across the whole buffer took 30-55 ms of cornell-glass's 480k.)
    const size_t patchCount = patches.size();
    int shift = 0;
    while ((patchCount >> shift) > 64) ++shift;
    const size_t buckets = (patchCount >> shift) + 1;
    std::vector<std::vector<Found>> found(blocks.size());
    std::vector<uint32_t> bucketStart(blocks.size() * (buckets + 1), 0);
    const uint64_t sobolSeed = streamSeed(settings.seed, Stream::SpecularTransport);
    // A direction given about a pole, in the world.
    auto toWorld = [](const Vec3& local, const Vec3& pole) {
        Vec3 t, b;
        orthonormalBasis(pole, t, b);
        return Vec3(local.x() * t + local.y() * b + local.z() * pole);
    };
    // A sphere's normal at a point uniform over it, or over the cap of `cap` (by the Sobol pair pa, pb).
    auto spherePoint = [&](double pa, double pb, const Group::Aim* cap) {
        const double z = cap ? 1 - pa * (1 - cap->cosCap) : 1 - 2 * pa, phi = 2 * kPi * pb;
        const double r = std::sqrt(std::max(0.0, 1 - z * z));
        const Vec3 local(r * std::cos(phi), r * std::sin(phi), z);
        return cap ? toWorld(local, cap->pole) : local;
    };
    std::vector<int64_t> blockRays(blocks.size(), 0);
    Timer traceTimer;
    Progress progress("specular transport", int64_t(blocks.size()));
    parallelFor(int64_t(blocks.size()), [&](int64_t begin, int64_t end) {
        prepareTracingThread();
        std::vector<Found> out;
        out.reserve(4 * kBlock);  // a path leaves about 1.9 records on cornell-glass
        for (int64_t bb = begin; bb < end; ++bb, progress.update()) {
            const auto [g, first] = blocks[size_t(bb)];
            const Group& group = groups[g];
            const Material& material = scene.materialOf(scene.objects[size_t(group.object)]);
            const double aimed = group.aims.empty() ? 0.0 : share;
            // Paths traced back from the receivers: on spheres (the caps), where there are any.
            const double back = group.sphere && !group.receivers.empty() ? receiverShare : 0.0;
            const double N = double(group.paths);
            Rng rng = pairRng(settings.seed, Stream::SpecularTransport, g, uint64_t(first / kBlock));
            out.clear();
            int64_t& rays = blockRays[size_t(bb)];
            const ScrambledSobol strategy[3] = {
                ScrambledSobol(mixSeed(sobolSeed, g, 0)), ScrambledSobol(mixSeed(sobolSeed, g, 1)),
                ScrambledSobol(mixSeed(sobolSeed, g, 2))};  // cosine, aimed, traced back
            // The densities of a path's two ends over the etendue at the ball's surface (per m^2 per
            // steradian of projected solid angle, relative to uniform points): from the ball's surface at
            // x (normal n) along w to the source `from` (cosine and aimed mixed), and back from x'
            // (normal n') along r to the receiver `to`. Etendue is conserved along the path through
            // the ball, so the two are comparable (the balance heuristic), and the branches' odds
            // are the same either way.
            auto forward = [&](const Vec3& n, const Vec3& w, const SurfaceHit& from) {
                const double cosX = n.dot(w);
                double pdf = (1 - aimed) * cosX / kPi;
                if (aimed > 0) {
                    if (const Group::Aim* a = group.aims.find(from.patch))
                        pdf += aimed * (group.sphere ? a->capFactor(n) : 1.0) * a->density * from.t * from.t /
                               std::abs(from.normal.dot(w));
                }
                return pdf / cosX;
            };
            auto backward = [&](const Vec3& n, const Vec3& r, const SurfaceHit& to) {
                const Group::Aim* a = group.receivers.find(to.patch);
                if (!a) return 0.0;
                return a->capFactor(n) * a->density * to.t * to.t / std::abs(to.normal.dot(r)) / n.dot(r);
            };
            // The point where the light left the ball towards `at` (along `along`), and the sphere's normal there.
            auto leaving = [&](const SurfaceHit& at, const Vec3& along) {
                return Vec3((at.point - at.t * along - group.sphere->center).normalized());
            };
            for (int64_t k = first; k < first + kBlock; ++k) {
                // Path k is traced back from a receiver, or else takes the aimed strategy or the cosine
                // one, by fixed splits in proportion (with the balance heuristic the same weights as a
                // coin, without its binomial count), and the next point of that strategy's own scrambled
                // Sobol set: its points (pa, pb) and directions (da, db) stratified together. (Strata of
                // points per block with directions shuffled left cornell-glass's ceiling pieces at
                // 1.05% rms, their noise the floor's light that the glass ball carries up to them.)
                const int64_t backBefore = int64_t(std::floor(double(k) * back));
                if (int64_t(std::floor(double(k + 1) * back)) > backBefore) {
                    const auto [pa, pb, da, db] = strategy[2](uint32_t(backBefore));
                    double within = 0;
                    const size_t picked = group.receivers.cdf.pick(da, within);
                    const int to = group.receivers.patch[picked];
                    const Group::Aim& aimAt = group.receivers.aim[picked];
                    const Vec3 n = spherePoint(pa, pb, &aimAt);
                    SurfaceHit at;
                    at.found = true;
                    at.object = group.object;
                    at.material = &material;
                    at.normal = n;
                    at.point = group.sphere->center + group.sphere->radius * n;
                    const Vec3 r = (group.receivers.point[picked](within, db) - at.point).normalized();
                    if (!(n.dot(r) > 0)) continue;
                    const SurfaceHit hit = tracer.trace(at.point + tracer.epsilon() * n, r);
                    ++rays;
                    if (!hit.found || hit.patch != to || !hit.frontFacing(r)) continue;
                    const double qBack = back * backward(n, r, hit);
                    at.t = hit.t;
                    // The light's walk from the receiver back through the ball to where it came from.
                    followSpecular(
                        tracer, at, Vec3(-r), Rgb::Ones(), settings.maxDepth, settings.splitBounces, rng, rays,
                        [](int, const Rgb&) {},
                        [&](const SurfaceHit& from, const Vec3& w, const Rgb& light) {
                            if (from.patch < 0 || from.material->type != MaterialType::Diffuse) return;
                            const Vec3 nx = leaving(from, w);
                            if (!(nx.dot(w) > 0)) return;
                            const Rgb v =
                                light * (group.area / (kPi * N * ((1 - back) * forward(nx, w, from) + qBack)));
                            out.push_back(record(from.patch, SpecularPaths::Delivered, to, v));
                        });
                    continue;
                }
                const int64_t kf = k - backBefore;
                const int64_t before = int64_t(std::floor(double(kf) * aimed));
                const bool aiming = int64_t(std::floor(double(kf + 1) * aimed)) > before;
                const auto [pa, pb, da, db] = strategy[aiming](uint32_t(aiming ? before : kf - before));
                // A point on the surface and its side's normal; for an aimed path the patch aimed at
                // first, and on a sphere a point of the cap that sees it.
                int aim = -1;
                size_t picked = 0;
                double within = 0;
                const Group::Aim* aimAt = nullptr;
                if (aiming) {
                    picked = group.aims.cdf.pick(da, within);
                    aim = group.aims.patch[picked];
                    aimAt = &group.aims.aim[picked];
                }
                SurfaceHit at;
                at.found = true;
                at.object = group.object;
                at.material = &material;
                Vec3 n;
                if (group.sphere) {
                    n = spherePoint(pa, pb, aimAt);
                    at.normal = n;
                    at.point = group.sphere->center + group.sphere->radius * n;
                } else {
                    double u1 = 0;
                    const size_t s = group.patches[group.cdf.pick(pa, u1)];
                    at.point = samplePatchPoint(patches, s, u1, pb, 0);
                    at.patch = int(s);
                    at.normal = patches.normal[s];
                    n = rng.uniform() < 0.5 ? at.normal : Vec3(-at.normal);
                }
                // A direction out of the side: towards a point on the patch aimed at, or cosine-distributed.
                Vec3 w;
                if (aiming)
                    w = (group.aims.point[picked](within, db) - at.point).normalized();
                else
                    w = cosineDirection(n, da, db);
                if (!(n.dot(w) > 0)) continue;
                const SurfaceHit from = tracer.trace(at.point + tracer.epsilon() * n, w);
                ++rays;
                // The light must come from the front of a diffuse patch that sees the surface directly.
                if (!from.found || from.patch < 0 || from.material->type != MaterialType::Diffuse ||
                    !from.frontFacing(w))
                    continue;
                // An aimed direction that met another patch first found nothing: so the aimed
                // strategy's density is that of the patch the ray meets, wherever it lands.
                if (aim >= 0 && from.patch != aim) continue;
                const double qForward = (1 - back) * forward(n, w, from);
                const double weight = group.area / (kPi * N * qForward);
                const size_t weightRecord = out.size();
                out.push_back(record(from.patch, SpecularPaths::Weight, 0, Rgb::Zero()));
                out.back().weight = float(weight);
                // The light's walk on from the surface, split into every branch for the first
                // settings.splitBounces bounces, then one branch by Fresnel's odds. What it delivers
                // is weighed against the paths traced back from the receivers (its own share kept in
                // the Weight record: deliveredScale).
                Rgb reached = Rgb::Zero();
                at.t = from.t;
                followSpecular(
                    tracer, at, Vec3(-w), Rgb::Constant(weight), settings.maxDepth, settings.splitBounces, rng, rays,
                    [&](int object, const Rgb& part) {
                        out.push_back(record(from.patch, SpecularPaths::Lost, object, part));
                    },
                    [&](const SurfaceHit& to, const Vec3& along, const Rgb& part) {
                        reached += part;
                        double mis = 1;
                        if (back > 0) {
                            const Vec3 nr = leaving(to, along);
                            const double qBack = nr.dot(along) > 0 ? back * backward(nr, along, to) : 0.0;
                            mis = qForward / (qForward + qBack);
                        }
                        out.push_back(record(from.patch, SpecularPaths::Delivered, to.patch, Rgb(part * mis)));
                    });
                for (int c = 0; c < 3; ++c) out[weightRecord].value[c] = float(reached[c]);
            }
            // The block's records by bucket, stable (in path order within each).
            uint32_t* at = &bucketStart[size_t(bb) * (buckets + 1)];
            for (const Found& f : out) ++at[(size_t(f.source) >> shift) + 1];
            for (size_t b = 0; b < buckets; ++b) at[b + 1] += at[b];
            std::vector<uint32_t> fill(at, at + buckets);
            std::vector<Found>& sorted = found[size_t(bb)];
            sorted.resize(out.size());
            for (const Found& f : out) sorted[fill[size_t(f.source) >> shift]++] = f;
        }
    });
    progress.done();
    const double traceSeconds = traceTimer.seconds();
    Timer collateTimer;

    // Summed by (source, group, kind, target) through a hash table a bucket of sources at a time, in
    // block order and within a block in path order (so the sums do not depend on the threads); then
    // each source's sums sorted by (group, kind, target) into the bucket's part of the entries. (Each
    // source's records sorted and summed instead: 14 ms of the threads' time on cornell-glass.)
    auto paths = std::make_shared<SpecularPaths>();
    paths->shift = shift;
    paths->parts.resize(buckets);
    paths->span.assign(patchCount, {0, 0});
    auto key = [](const Found& f, size_t g) {
        return uint64_t(g) << 34 | uint64_t(f.kind) << 32 |
               (f.kind == SpecularPaths::Weight ? 0 : uint64_t(uint32_t(f.target)));
    };
    int64_t records = 0;
    for (size_t bb = 0; bb < blocks.size(); ++bb) records += int64_t(found[bb].size());
    struct Sum {
        uint64_t key;
        uint32_t source;  // from the bucket's first
        Rgb value;
        double square, weight;
    };
    parallelFor(int64_t(buckets), [&](int64_t begin, int64_t end) {
        std::vector<int32_t> table;
        std::vector<Sum> sums;
        std::vector<uint32_t> count, order;
        for (int64_t b = begin; b < end; ++b) {
            const size_t first = size_t(b) << shift,
                         sources = std::min(patchCount, first + (size_t(1) << shift)) - first;
            if (first >= patchCount) continue;
            size_t held = 0;
            for (size_t bb = 0; bb < blocks.size(); ++bb) {
                const uint32_t* at = &bucketStart[bb * (buckets + 1) + size_t(b)];
                held += at[1] - at[0];
            }
            int bits = 4;
            while ((size_t(1) << bits) < 2 * held) ++bits;
            const size_t mask = (size_t(1) << bits) - 1;
            table.assign(mask + 1, -1);
            sums.clear();
            for (size_t bb = 0; bb < blocks.size(); ++bb) {
                const uint32_t* at = &bucketStart[bb * (buckets + 1) + size_t(b)];
                for (uint32_t r = at[0]; r < at[1]; ++r) {
                    const Found& f = found[bb][r];
                    const uint64_t k = key(f, blocks[bb].first);
                    const auto source = uint32_t(size_t(f.source) - first);
                    size_t h = size_t(((k ^ (uint64_t(source) << 40)) * 0x9E3779B97F4A7C15ull) >> (64 - bits));
                    while (table[h] >= 0 &&
                           (sums[size_t(table[h])].key != k || sums[size_t(table[h])].source != source))
                        h = (h + 1) & mask;
                    if (table[h] < 0) {
                        table[h] = int32_t(sums.size());
                        sums.push_back({k, source, Rgb::Zero(), 0.0, 0.0});
                    }
                    Sum& e = sums[size_t(table[h])];
                    const Rgb v(f.value[0], f.value[1], f.value[2]);
                    e.value += v;
                    if (f.kind == SpecularPaths::Weight) {
                        e.weight += f.weight;
                        e.square += double(f.weight) * f.weight;
                    } else if (f.kind == SpecularPaths::Delivered) {
                        const double mean = v.sum() / 3;
                        e.square += mean * mean;
                    }
                }
            }
            count.assign(sources + 1, 0);
            for (const Sum& x : sums) ++count[x.source + 1];
            for (size_t i = 0; i < sources; ++i) count[i + 1] += count[i];
            order.resize(sums.size());
            for (size_t x = 0; x < sums.size(); ++x) order[count[sums[x].source]++] = uint32_t(x);
            std::vector<Entry>& entries = paths->parts[size_t(b)];
            entries.reserve(sums.size());
            for (size_t i = 0, from = 0; i < sources; from = count[i++]) {
                // count[i] is now where source i's sums end
                std::sort(order.begin() + ptrdiff_t(from), order.begin() + ptrdiff_t(count[i]),
                          [&](uint32_t x, uint32_t y) { return sums[x].key < sums[y].key; });
                paths->span[first + i].first = uint32_t(entries.size());
                for (size_t x = from; x < count[i]; ++x) {
                    const Sum& e = sums[order[x]];
                    entries.push_back({int(e.key >> 34), SpecularPaths::Kind((e.key >> 32) & 3), int(uint32_t(e.key)),
                                       e.value.cast<float>(), float(e.square), float(e.weight)});
                }
                paths->span[first + i].second = uint32_t(entries.size());
            }
        }
    });
    found = {};
    for (const Group& g : groups) {
        paths->paths += g.paths;
        paths->reversed = paths->reversed || (receiverShare > 0 && g.sphere && !g.receivers.empty());
    }
    for (int64_t r : blockRays) paths->rays += r;
    logDebug("specular transport: paths traced in ", traceSeconds, " s, collated in ", collateTimer.seconds(), " s (",
             records, " records, ", paths->entries(), " entries)");
    return paths;
}

}  // namespace

SpecularTransport computeSpecularTransport(const Scene& scene, const PatchSet& patches, const FormFactorMatrix& F,
                                           const SceneTracer& tracer, const SpecularSettings& settings,
                                           const SpecularTransport* previous, const std::vector<double>& rowRays) {
    SpecularTransport out;
    int64_t firstRays = 0;  // the first set's, which finds the caustics to aim at
    if (!tracer.hasSpecular()) return out;
    Timer timer;
    const size_t n = patches.size();
    // The specular objects, numbered 0..K-1, and their patches.
    std::vector<int> group(scene.objects.size(), -1), patchGroup(n, -1);
    std::vector<Group> groups;
    for (size_t i = 0; i < n; ++i) {
        const size_t o = size_t(patches.object[i]);
        if (scene.materialOf(scene.objects[o]).type == MaterialType::Diffuse) continue;
        if (group[o] < 0) {
            group[o] = int(groups.size());
            groups.push_back({});
            groups.back().object = int(o);
            groups.back().sphere = tracer.exactSphere(int(o));
        }
        patchGroup[i] = group[o];
        groups[size_t(group[o])].patches.push_back(i);
    }
    for (Group& g : groups) {
        if (g.sphere) {
            g.area = 4 * kPi * g.sphere->radius * g.sphere->radius;
        } else {
            std::vector<double> cdf;
            for (size_t i : g.patches) cdf.push_back((cdf.empty() ? 0 : cdf.back()) + patches.area[i]);
            const double total = cdf.back();
            g.area = 2 * total;
            for (double& c : cdf) c /= total;
            g.cdf = CumulativeTable(std::move(cdf));
        }
    }
    const size_t K = groups.size();

    // Each row's shares F(i, o).
    std::vector<double> share(n * K, 0.0);
    int64_t seeing = 0;
    for (size_t i = 0; i < n; ++i) {
        const Material& m = scene.materialOf(scene.objects[size_t(patches.object[i])]);
        if (m.type != MaterialType::Diffuse || ((m.reflectance <= 0).all() && !m.emits())) continue;
        bool any = false;
        F.forEachInRow(i, [&](size_t j, float f) {
            if (patchGroup[j] >= 0) share[i * K + size_t(patchGroup[j])] += f, any = true;
        });
        seeing += any;
    }
    if (previous && previous->traced) {
        out.traced = previous->traced;
    } else {
        // The patches aimed at, by the light each sends into the object: a lamp's, its emission
        // times its area and its share of the object (in W); then also the patches the balls light
        // by a caustic, whose light through them is as sharp: a glass ball images the caustic at its
        // foot onto the ceiling, and on cornell-glass nine floor patches of that caustic, reached by
        // cosine paths alone, held 68% of the paths' noise in ceiling_right (20% of its light). Their
        // light is measured by a first, small set of paths (SpecularSettings::causticShare of them, then discarded).
        // (Aiming by a first solve's radiosity instead, or half by each, measured no better on
        // cornell-glass: 2026-12-05.)
        std::vector<double> power(n * K, 0.0);
        for (size_t i = 0; i < n; ++i) {
            const double emitted =
                kPi * luminance(scene.materialOf(scene.objects[size_t(patches.object[i])]).emission) * patches.area[i];
            for (size_t g = 0; g < K; ++g) power[i * K + g] = emitted * share[i * K + g];
        }
        // A table of patches to aim at, by `by` (per patch and object): cumulative, normalised, and each
        // patch's chance per m^2, with the cap of a sphere that sees it.
        auto table = [&](const std::vector<double>& by, size_t g, Group::Aims& aims) {
            const Group& aim = groups[g];
            aims = Group::Aims();
            aims.index.assign(n, -1);
            double total = 0;
            std::vector<double> cdf;
            for (size_t i = 0; i < n; ++i) {
                if (!(by[i * K + g] > 0)) continue;
                total += by[i * K + g];
                aims.index[i] = int(aims.patch.size());
                aims.patch.push_back(int(i));
                cdf.push_back(total);
            }
            aims.aim.resize(aims.patch.size());
            aims.point.reserve(aims.patch.size());
            for (int i : aims.patch) aims.point.emplace_back(patches, size_t(i));
            for (size_t k = 0; k < aims.patch.size(); ++k) {
                const double before = k ? cdf[k - 1] : 0;
                const size_t i = size_t(aims.patch[k]);
                Group::Aim& a = aims.aim[k];
                a.density = (cdf[k] - before) / total / patches.area[i];
                if (aim.sphere) {
                    const Vec3 towards = patches.centroid[i] - aim.sphere->center;
                    const double d = towards.norm();
                    a.pole = towards / d;
                    a.cosCap = d > aim.sphere->radius ? std::min(aim.sphere->radius / d, 1 - 1e-9) : 0.0;
                    a.inCap = 2 / (1 - a.cosCap);
                }
            }
            for (double& c : cdf) c /= total;
            aims.cdf = CumulativeTable(std::move(cdf));
            if (aims.patch.empty()) aims.index.clear();
        };
        auto aimBy = [&](const std::vector<double>& by) {
            for (size_t g = 0; g < K; ++g) table(by, g, groups[g].aims);
        };
        // The receivers paths are traced back from: every diffuse object that sees the ball and reflects,
        // each as often as any other, over its patches by their etendue to the ball (A_j F(j, o)).
        if (settings.receiverShare > 0) {
            std::vector<double> seen(scene.objects.size() * K, 0.0), by(n * K, 0.0);
            auto reflects = [&](size_t j) {
                const Material& m = scene.materialOf(scene.objects[size_t(patches.object[j])]);
                return m.type == MaterialType::Diffuse && (m.reflectance > 0).any();
            };
            for (size_t j = 0; j < n; ++j)
                if (reflects(j))
                    for (size_t g = 0; g < K; ++g)
                        seen[size_t(patches.object[j]) * K + g] += patches.area[j] * share[j * K + g];
            for (size_t j = 0; j < n; ++j)
                if (reflects(j))
                    for (size_t g = 0; g < K; ++g) {
                        const double s = seen[size_t(patches.object[j]) * K + g];
                        if (s > 0) by[j * K + g] = patches.area[j] * share[j * K + g] / s;
                    }
            for (size_t g = 0; g < K; ++g)
                if (groups[g].sphere) table(by, g, groups[g].receivers);
        }
        aimBy(power);
        const int64_t total = std::max<int64_t>(1, seeing) * std::max(1, settings.pathsPerPatch);
        if (settings.causticShare > 0 && std::any_of(power.begin(), power.end(), [](double p) { return p > 0; })) {
            SpecularSettings first = settings;
            first.seed = mixSeed(settings.seed, 0xCA05);
            const auto lit = tracePaths(scene, patches, tracer, first, groups,
                                        std::max<int64_t>(1, int64_t(settings.causticShare * double(total))));
            firstRays = lit->rays;
            // The light each patch receives from the lamps through the objects, W (the share of a
            // lamp's light a path carries there is its part of the lamp's paths' etendue).
            std::vector<double> received(n, 0.0);
            for (size_t i = 0; i < n; ++i) {
                std::vector<double> perEtendue(K, 0.0);
                for (const SpecularPaths::Entry& e : lit->row(i)) {
                    const size_t g = size_t(e.group);
                    if (e.kind == SpecularPaths::Weight)
                        perEtendue[g] = e.weight > 0 ? power[i * K + g] / e.weight : 0.0;
                    else if (e.kind == SpecularPaths::Delivered)
                        received[size_t(e.target)] += perEtendue[g] * luminance(e.light());
                }
            }
            for (size_t j = 0; j < n; ++j) {
                const Material& m = scene.materialOf(scene.objects[size_t(patches.object[j])]);
                if (m.type != MaterialType::Diffuse || !(received[j] > 0)) continue;
                for (size_t g = 0; g < K; ++g)
                    power[j * K + g] += luminance(m.reflectance) * received[j] * share[j * K + g];
            }
            aimBy(power);
        }
        out.traced = tracePaths(scene, patches, tracer, settings, groups, total);
    }
    const SpecularPaths& paths = *out.traced;
    out.paths = paths.paths;

    // Each row's share F(i, o), measured twice: by the row's own rays (binomial, variance about
    // f (1 - f) / m for m rays) and by the paths' etendue from patch i (a compound Poisson sum, variance
    // about f w / a for paths of mean weight w = sum w^2 / sum w over the patch's area a). Both are
    // unbiased; their inverse-variance mean, the ratio of the two variances taken from the weights
    // alone (not from either estimate, which would bias it), is the share the row sends on. The
    // binomial's 1 - f is taken as 1 for that reason: weighed by the row's own 1 - f, a patch under
    // cornell-glass's mirror ball whose 30 rays all met the ball (f = 1 against the paths' 0.91) took
    // a thousand times the paths' weight.
    // A path from patch i through object o then carries that share / (the paths' etendue from i to o)
    // of patch i's light per m^2 of its own etendue.
    out.patchGroup = patchGroup;
    out.groups = K;
    out.share.assign(n * K, 0.0);
    // What each row's fates are made from: its shares F(i, o), the rays it was cast with and its
    // exposed part. A row whose inputs are those of `previous`'s, and which every path it needed
    // reached, has the same fates: they are copied (on cornell-glass 2,466 of 3,231 rows when rows
    // are cast again), not summed again.
    const size_t inputs = K + 2;
    out.rowInputs.resize(n * inputs);
    std::vector<char> same(n, 0);
    const bool reuse = previous && previous->traced == out.traced && previous->groups == K &&
                       previous->rowInputs.size() == n * inputs && previous->rowUnresolved.size() == n;
    for (size_t i = 0; i < n; ++i) {
        double* in = &out.rowInputs[i * inputs];
        std::copy(&share[i * K], &share[i * K] + K, in);
        in[K] = rowRays.empty() ? -1.0 : rowRays[i];
        in[K + 1] = F.exposed.empty() ? 1.0 : double(F.exposed[i]);
        same[i] =
            reuse && previous->rowUnresolved[i] == 0 && std::equal(in, in + inputs, &previous->rowInputs[i * inputs]);
    }
    std::vector<RowResult> rows(n);
    std::vector<char> unresolved(n * K, 0);  // rows (and objects) no path reached
    parallelFor(
        int64_t(n),
        [&](int64_t begin, int64_t end) {
            std::vector<double> scale(K);
            std::vector<Rgb> reach(K, Rgb::Ones());
            for (int64_t ii = begin; ii < end; ++ii) {
                const size_t i = size_t(ii);
                const double* s = &share[i * K];
                if (std::all_of(s, s + K, [](double v) { return v <= 0; })) continue;
                if (same[i]) {
                    std::copy(&previous->share[i * K], &previous->share[i * K] + K, &out.share[i * K]);
                    continue;
                }
                std::fill(scale.begin(), scale.end(), 0.0);
                RowResult& row = rows[i];
                double* shared = &out.share[i * K];
                for (const SpecularPaths::Entry& e : paths.row(i)) {
                    const size_t g = size_t(e.group);
                    if (e.kind == SpecularPaths::Weight) {
                        double f = s[g];
                        if (!rowRays.empty() && f > 0) {
                            const double a = patches.area[i] * (F.exposed.empty() ? 1.0 : double(F.exposed[i]));
                            const double own = std::max(rowRays[i], 1.0);
                            const double theirs = a * e.weight / e.square;
                            // At most all of the row's light: a patch under a ball that its
                            // facets cover but the exact sphere does not has a sliver of exposed
                            // area (1 ray in 144) and the paths' full share over it (28 x).
                            f = std::min((own * f + theirs * e.weight / a) / (own + theirs), 1.0);
                        }
                        shared[g] = f;
                        scale[g] = f / e.weight;
                        reach[g] = paths.deliveredScale(i, int(g));
                        continue;
                    }
                    if (s[g] <= 0 || scale[g] <= 0) continue;
                    row.add(e, scale[g], reach[g]);
                }
                for (size_t g = 0; g < K; ++g)
                    if (s[g] > 0 && scale[g] <= 0) {
                        unresolved[i * K + g] = 1;
                        row.unresolved += s[g];
                        shared[g] = s[g];
                    }
                mergeByTarget(row.delivered);
                mergeByTarget(row.lost);
            }
        },
        64);
    // A row no path reached (a patch that sees a sliver of a ball) sends its share on as the nearest
    // row of its own object that paths did reach sends its share through the same ball; booked
    // absorbed by the ball, it darkened the walls by 0.18% on cornell-glass at 64 paths a patch. (Its
    // object's mean fates instead: three times the transfers, each such row reaching every target.)
    // With no such row, it is absorbed. The search runs over the object's own patches.
    const std::vector<std::vector<size_t>> members =
        std::any_of(unresolved.begin(), unresolved.end(), [](char u) { return u != 0; })
            ? patches.byObject()
            : std::vector<std::vector<size_t>>{};
    parallelFor(
        int64_t(n),
        [&](int64_t begin, int64_t end) {
            for (int64_t ii = begin; ii < end; ++ii) {
                const size_t i = size_t(ii);
                bool changed = false;
                for (size_t g = 0; g < K; ++g) {
                    if (!unresolved[i * K + g]) continue;
                    size_t near = n;
                    double best = std::numeric_limits<double>::infinity();
                    for (size_t j : members[size_t(patches.object[i])]) {
                        if (unresolved[j * K + g] || !(out.share[j * K + g] > 0)) continue;
                        const double d = (patches.centroid[j] - patches.centroid[i]).squaredNorm();
                        if (d < best) best = d, near = j;
                    }
                    const double f = share[i * K + g];
                    RowResult& row = rows[i];
                    changed = true;
                    if (near == n) {
                        row.lost.push_back({groups[g].object, Rgb::Constant(f)});
                        continue;
                    }
                    double scale = 0;  // of the near row's paths, per unit of this row's share
                    const Rgb reach = paths.deliveredScale(near, int(g));
                    for (const SpecularPaths::Entry& e : paths.row(near)) {
                        if (size_t(e.group) != g) continue;
                        if (e.kind == SpecularPaths::Weight)
                            scale = f / e.weight;
                        else
                            row.add(e, scale, reach);
                    }
                }
                if (!changed) continue;
                mergeByTarget(rows[i].delivered);
                mergeByTarget(rows[i].lost);
            }
        },
        64);

    const double rowSeconds = timer.seconds();
    // The part of patch i that light leaves and lands on: its area less any part covered by a solid
    // resting on it (ray-cast rows: FormFactorMatrix::exposed). B is the mean over that part, so a share
    // of i's light lands on j as irradiance in the ratio of those parts, not of the whole areas: by the
    // whole areas, a floor patch almost wholly under cornell-glass's glass ball (1% exposed) sent on
    // through the ball a hundred times the light it had, and Gauss-Seidel diverged. (The floor keeps
    // a fully covered patch, which no path can reach, from dividing by zero.)
    auto litPart = [&](size_t i, double exposed) { return patches.area[i] * std::max(exposed, 1e-6); };
    auto lit = [&](size_t i) { return litPart(i, F.exposed.empty() ? 1.0 : double(F.exposed[i])); };
    auto previousLit = [&](size_t i) { return litPart(i, previous->rowInputs[i * inputs + K + 1]); };
    // Compressed rows by source (outgoing, losses), then by target (incoming).
    out.outStart.assign(n + 1, 0);
    out.lossStart.assign(n + 1, 0);
    std::vector<size_t> inCount(n + 1, 0);
    double area = 0;
    size_t copied = 0;
    for (size_t i = 0; i < n; ++i) {
        if (same[i]) {
            ++copied;
            const SpecularTransport& p = *previous;
            out.outStart[i + 1] = out.outStart[i] + (p.outStart[i + 1] - p.outStart[i]);
            out.lossStart[i + 1] = out.lossStart[i] + (p.lossStart[i + 1] - p.lossStart[i]);
            for (size_t k = p.outStart[i]; k < p.outStart[i + 1]; ++k) ++inCount[size_t(p.outTarget[k]) + 1];
        } else {
            out.outStart[i + 1] = out.outStart[i] + rows[i].delivered.size();
            out.lossStart[i + 1] = out.lossStart[i] + rows[i].lost.size();
            for (const Transfer& t : rows[i].delivered) ++inCount[size_t(t.target) + 1];
        }
        out.unresolvedShare += patches.area[i] * rows[i].unresolved;
        out.rowUnresolved.push_back(rows[i].unresolved);
        area += patches.area[i];
    }
    out.unresolvedShare /= std::max(area, 1e-300);
    // Sized once and filled in parallel (grown by push_back, the arrays' fresh pages cost a cornell-glass
    // solve up to 0.03 s in faults).
    out.outTarget.resize(out.outStart[n]);
    out.outWeight.resize(out.outStart[n]);
    out.lossObject.resize(out.lossStart[n]);
    out.lossShare.resize(out.lossStart[n]);
    out.outSquare.resize(out.outStart[n]);
    parallelFor(
        int64_t(n),
        [&](int64_t begin, int64_t end) {
            for (int64_t ii = begin; ii < end; ++ii) {
                const size_t i = size_t(ii);
                if (same[i]) {
                    const SpecularTransport& p = *previous;
                    const auto from = ptrdiff_t(p.outStart[i]), to = ptrdiff_t(p.outStart[i + 1]);
                    const auto at = ptrdiff_t(out.outStart[i]);
                    std::copy(p.outTarget.begin() + from, p.outTarget.begin() + to, out.outTarget.begin() + at);
                    // The same shares; a target whose uncovered part was measured again since takes
                    // them over its new part.
                    for (auto k = from; k < to; ++k) {
                        const size_t j = size_t(p.outTarget[size_t(k)]);
                        const double ratio = previousLit(j) / lit(j);
                        out.outWeight[size_t(at + k - from)] = ratio * p.outWeight[size_t(k)];
                        out.outSquare[size_t(at + k - from)] = ratio * ratio * p.outSquare[size_t(k)];
                    }
                    const auto lossFrom = ptrdiff_t(p.lossStart[i]), lossTo = ptrdiff_t(p.lossStart[i + 1]);
                    const auto lossAt = ptrdiff_t(out.lossStart[i]);
                    std::copy(p.lossObject.begin() + lossFrom, p.lossObject.begin() + lossTo,
                              out.lossObject.begin() + lossAt);
                    std::copy(p.lossShare.begin() + lossFrom, p.lossShare.begin() + lossTo,
                              out.lossShare.begin() + lossAt);
                    continue;
                }
                size_t k = out.outStart[i];
                for (const Transfer& t : rows[i].delivered) {
                    const double ratio = lit(i) / lit(size_t(t.target));
                    out.outTarget[k] = t.target;
                    out.outWeight[k] = ratio * t.share;
                    out.outSquare[k++] = ratio * ratio * t.square;
                }
                k = out.lossStart[i];
                for (const Transfer& t : rows[i].lost) {
                    out.lossObject[k] = t.target;
                    out.lossShare[k++] = t.share;
                }
            }
        },
        256);
    out.inStart.assign(n + 1, 0);
    for (size_t j = 0; j < n; ++j) out.inStart[j + 1] = out.inStart[j] + inCount[j + 1];
    out.inSource.resize(out.outTarget.size());
    out.inWeight.resize(out.outTarget.size());
    out.inSquare.resize(out.outTarget.size());
    std::vector<size_t> fill(out.inStart.begin(), out.inStart.end() - 1);
    for (size_t i = 0; i < n; ++i)
        for (size_t k = out.outStart[i]; k < out.outStart[i + 1]; ++k) {
            const size_t j = size_t(out.outTarget[k]);
            out.inSource[fill[j]] = int(i);
            out.inWeight[fill[j]] = out.outWeight[k];
            out.inSquare[fill[j]] = out.outSquare[k];
            ++fill[j];
        }
    out.seconds = timer.seconds();
    logDebug("specular transport: rows in ", rowSeconds, " s, compressed in ", out.seconds - rowSeconds, " s");
    if (previous && previous->traced) {
        logInfo("specular transport: the same ", paths.paths, " paths scaled to the rows cast again (", n - copied,
                " rows; ", copied, " unchanged) in ", out.seconds, " s");
    } else {
        g_transportRays.add(uint64_t(paths.rays + firstRays));
        logInfo("specular transport: ", K, " mirror/glass objects, ", paths.paths, " paths from their surfaces (",
                paths.rays, " rays; ", firstRays, " more first, to find the caustics), ", out.outTarget.size(),
                " transfers in ", out.seconds, " s");
    }
    return out;
}

void matchSpecularShares(FormFactorMatrix& F, const SpecularTransport& transport) {
    const size_t K = transport.groups;
    if (transport.share.empty() || K == 0) return;
    const std::vector<int>& group = transport.patchGroup;
    // What is left for the rest of a row whose entries to the objects went from `before` to `after`
    // in all: the rest shares out what the objects no longer take (or give back).
    auto restOf = [](double before, double after) {
        return before < 1 - 1e-9 ? std::max(0.0, 1 - after) / (1 - before) : 1.0;
    };
    parallelFor(
        int64_t(F.size()),
        [&](int64_t begin, int64_t end) {
            std::vector<double> now(K), factor(K);
            for (int64_t ii = begin; ii < end; ++ii) {
                const size_t i = size_t(ii);
                const double* want = &transport.share[i * K];
                if (std::all_of(want, want + K, [](double v) { return v <= 0; })) continue;
                std::fill(now.begin(), now.end(), 0.0);
                F.forEachInRow(i, [&](size_t j, float f) {
                    if (group[j] >= 0) now[size_t(group[j])] += f;
                });
                double before = 0, after = 0;
                for (size_t g = 0; g < K; ++g) {
                    factor[g] = now[g] > 0 ? want[g] / now[g] : 1.0;
                    before += now[g];
                    after += now[g] * factor[g];
                }
                const double rest = restOf(before, after);
                // A patch partly hidden has a mean row too (the whole patch's view): its entries to
                // the objects scale as the row's do, and its rest by its own sums. (The row's rest
                // applied to it read a patch under cornell-glass's mirror ball, whose row gave the
                // ball all but 1e-5 of its view, 10^4 times too bright: the floor 1,300 times.)
                double meanBefore = 0, meanAfter = 0;
                if (F.hasMeanRow(i)) {
                    const FormFactorMatrix::SparseRow m = F.meanRow(i);
                    for (size_t k = 0; k < m.count; ++k) {
                        const int g = group[size_t(m.column[k])];
                        if (g < 0) continue;
                        meanBefore += m.value[k];
                        meanAfter += m.value[k] * factor[size_t(g)];
                    }
                }
                const double meanRest = restOf(meanBefore, meanAfter);
                F.scaleRow(
                    i, [&](size_t j) { return group[j] >= 0 ? factor[size_t(group[j])] : rest; },
                    [&](size_t j) { return group[j] >= 0 ? factor[size_t(group[j])] : meanRest; });
            }
        },
        64);
}

}  // namespace penumbra
