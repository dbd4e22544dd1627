#include "solver/radiosity/specular_transport.h"

#include <algorithm>
#include <cmath>
#include <tuple>

#include "core/counters.h"
#include "core/log.h"
#include "core/optics.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "core/timer.h"

namespace penumbra {

// What the paths found, summed per source patch: entries sorted by (group, kind, target).
struct SpecularPaths {
    enum Kind : uint8_t { Weight = 0, Delivered = 1, Lost = 2 };
    struct Entry {
        int group;   // the mirror or glass object the light met first (index into the groups)
        Kind kind;   // Weight: the paths' etendue from the source (m^2), their count, sum of squares; else a fate
        int target;  // patch (delivered) or object (lost)
        Rgb value;   // m^2: etendue times the share that got there
    };
    std::vector<size_t> start;  // per source patch, into entries
    std::vector<Entry> entries;
    int64_t paths = 0, rays = 0;
};

namespace {

const Counter g_transportRays("specular.rays", "rays of the specular transport (paths' first rays and bounces)");

struct RowResult {
    std::vector<std::pair<int, Rgb>> delivered;  // target patch, S(i -> j)
    std::vector<std::pair<int, Rgb>> lost;       // object, share absorbed
    double unresolved = 0;
};

// A mirror or glass object: its surface, to start paths from.
struct Group {
    int object = -1;
    const RaySphere* sphere = nullptr;  // traced exactly, or else its patches
    std::vector<size_t> patches;
    std::vector<double> cdf;  // over the patches, by area
    double area = 0;          // m^2 paths start from (both sides of an open surface)
    int64_t paths = 0;
};

// Sums equal (target) entries of a sorted list.
void mergeByTarget(std::vector<std::pair<int, Rgb>>& v) {
    std::sort(v.begin(), v.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    size_t out = 0;
    for (size_t k = 0; k < v.size(); ++k) {
        if (out > 0 && v[out - 1].first == v[k].first)
            v[out - 1].second += v[k].second;
        else
            v[out++] = v[k];
    }
    v.resize(out);
}

std::shared_ptr<const SpecularPaths> tracePaths(const Scene& scene, const PatchSet& patches, const SceneTracer& tracer,
                                                const SpecularSettings& settings, std::vector<Group>& groups,
                                                int64_t total) {
    using Entry = SpecularPaths::Entry;
    double area = 0;
    for (const Group& g : groups) area += g.area;
    constexpr int64_t kBlock = 1024;
    std::vector<std::pair<size_t, int64_t>> blocks;  // group, first path
    for (size_t g = 0; g < groups.size(); ++g) {
        groups[g].paths = std::max<int64_t>(kBlock, int64_t(std::ceil(double(total) * groups[g].area / area)));
        for (int64_t b = 0; b < groups[g].paths; b += kBlock) blocks.emplace_back(g, b);
    }
    const double aimed = tracer.hasEmitters() ? std::clamp(settings.lampShare, 0.0, 1.0) : 0.0;
    struct Found {
        int source;
        Entry entry;
    };
    std::vector<std::vector<Found>> found(blocks.size());
    std::vector<int64_t> blockRays(blocks.size(), 0);
    Progress progress("specular transport", int64_t(blocks.size()));
    parallelFor(int64_t(blocks.size()), [&](int64_t begin, int64_t end) {
        prepareTracingThread();
        for (int64_t bb = begin; bb < end; ++bb, progress.update()) {
            const auto [g, first] = blocks[size_t(bb)];
            const Group& group = groups[g];
            const Material& material = scene.materialOf(scene.objects[size_t(group.object)]);
            Rng rng = pairRng(settings.seed, Stream::SpecularTransport, g, uint64_t(first / kBlock));
            auto& out = found[size_t(bb)];
            int64_t& rays = blockRays[size_t(bb)];
            for (int64_t k = first; k < std::min(first + kBlock, group.paths); ++k) {
                // A point on the surface and its side's normal.
                SurfaceHit at;
                at.found = true;
                at.object = group.object;
                at.material = &material;
                Vec3 n;
                if (group.sphere) {
                    const double z = 1 - 2 * rng.uniform(), phi = 2 * kPi * rng.uniform();
                    const double r = std::sqrt(std::max(0.0, 1 - z * z));
                    at.normal = n = Vec3(r * std::cos(phi), r * std::sin(phi), z);
                    at.point = group.sphere->center + group.sphere->radius * n;
                } else {
                    const double u = rng.uniform();
                    const size_t s = group.patches[std::min(
                        size_t(std::lower_bound(group.cdf.begin(), group.cdf.end(), u) - group.cdf.begin()),
                        group.patches.size() - 1)];
                    const double u1 = rng.uniform(), u2 = rng.uniform();
                    at.point = samplePatchPoint(patches, s, u1, u2, 0);
                    at.patch = int(s);
                    at.normal = patches.normal[s];
                    n = rng.uniform() < 0.5 ? at.normal : Vec3(-at.normal);
                }
                // A direction out of the side: towards a lamp, or cosine-distributed.
                const bool toLamp = aimed > 0 && rng.uniform() < aimed;
                Vec3 w;
                if (toLamp) {
                    w = (tracer.sampleEmitter(rng).point - at.point).normalized();
                } else {
                    w = cosineDirection(n, rng);
                }
                const double cosX = n.dot(w);
                if (!(cosX > 0)) continue;
                const SurfaceHit from = tracer.trace(at.point + tracer.epsilon() * n, w);
                ++rays;
                // The light must come from the front of a diffuse patch that sees the surface directly.
                if (!from.found || from.patch < 0 || from.material->type != MaterialType::Diffuse ||
                    !from.frontFacing(w))
                    continue;
                const double lampArea = tracer.emitterPdfArea(from.patch);
                if (toLamp && lampArea <= 0) continue;  // the lamp was hidden: this strategy found nothing
                double pdf = (1 - aimed) * cosX / kPi;
                if (lampArea > 0) pdf += aimed * lampArea * from.t * from.t / std::abs(from.normal.dot(w));
                const double weight = group.area * cosX / (kPi * double(group.paths) * pdf);
                out.push_back({from.patch, {int(g), SpecularPaths::Weight, 0, Rgb(weight, 1, weight * weight)}});
                // The light's walk on from the surface.
                const Vec3 d = -w;
                at.t = from.t;
                const SpecularWalk walk =
                    walkSpecular(tracer, at, d, rng, settings.maxDepth, 0.0, [&](int object, const Rgb& kept) {
                        out.push_back({from.patch, {int(g), SpecularPaths::Lost, object, Rgb(weight * kept)}});
                    });
                rays += walk.bounces;
                switch (walk.end) {
                    case WalkEnd::Escaped:
                        break;  // out of the scene: the remainder of the balance
                    case WalkEnd::Diffuse:
                        if (walk.hit.frontFacing(walk.dir))
                            out.push_back(
                                {from.patch,
                                 {int(g), SpecularPaths::Delivered, walk.hit.patch, weight * walk.throughput}});
                        else
                            out.push_back(
                                {from.patch, {int(g), SpecularPaths::Lost, walk.hit.object, weight * walk.throughput}});
                        break;
                    case WalkEnd::Absorbed:
                    case WalkEnd::TooDeep:
                        out.push_back(
                            {from.patch, {int(g), SpecularPaths::Lost, walk.hit.object, weight * walk.throughput}});
                        break;
                }
            }
        }
    });
    progress.done();

    // By source patch, in block order (so the sums do not depend on the threads), then summed.
    auto paths = std::make_shared<SpecularPaths>();
    const size_t n = patches.size();
    std::vector<size_t> count(n + 1, 0);
    for (const auto& b : found)
        for (const Found& f : b) ++count[size_t(f.source) + 1];
    for (size_t i = 0; i < n; ++i) count[i + 1] += count[i];
    std::vector<Entry> bySource(count[n]);
    {
        std::vector<size_t> fill(count.begin(), count.end() - 1);
        for (const auto& b : found)
            for (const Found& f : b) bySource[fill[size_t(f.source)]++] = f.entry;
    }
    found = {};
    std::vector<std::vector<Entry>> summed(n);
    parallelFor(
        int64_t(n),
        [&](int64_t begin, int64_t end) {
            for (int64_t ii = begin; ii < end; ++ii) {
                const size_t i = size_t(ii);
                auto first = bySource.begin() + std::ptrdiff_t(count[i]),
                     last = bySource.begin() + std::ptrdiff_t(count[i + 1]);
                std::stable_sort(first, last, [](const Entry& a, const Entry& b) {
                    return std::tie(a.group, a.kind, a.target) < std::tie(b.group, b.kind, b.target);
                });
                auto& out = summed[i];
                for (auto e = first; e != last; ++e) {
                    if (!out.empty() && out.back().group == e->group && out.back().kind == e->kind &&
                        out.back().target == e->target)
                        out.back().value += e->value;
                    else
                        out.push_back(*e);
                }
            }
        },
        64);
    paths->start.assign(n + 1, 0);
    for (size_t i = 0; i < n; ++i) paths->start[i + 1] = paths->start[i] + summed[i].size();
    paths->entries.reserve(paths->start[n]);
    for (auto& s : summed) paths->entries.insert(paths->entries.end(), s.begin(), s.end());
    for (const Group& g : groups) paths->paths += g.paths;
    for (int64_t r : blockRays) paths->rays += r;
    return paths;
}

}  // namespace

SpecularTransport computeSpecularTransport(const Scene& scene, const PatchSet& patches, const FormFactorMatrix& F,
                                           const SceneTracer& tracer, const SpecularSettings& settings,
                                           const SpecularTransport* previous, const std::vector<double>& rowRays) {
    SpecularTransport out;
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
        Group& g = groups[size_t(group[o])];
        patchGroup[i] = group[o];
        g.patches.push_back(i);
        g.cdf.push_back((g.cdf.empty() ? 0 : g.cdf.back()) + patches.area[i]);
    }
    for (Group& g : groups) {
        if (g.sphere) {
            g.area = 4 * kPi * g.sphere->radius * g.sphere->radius;
        } else {
            g.area = 2 * g.cdf.back();
            for (double& c : g.cdf) c /= g.cdf.back();
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
    out.traced = previous && previous->traced
                     ? previous->traced
                     : tracePaths(scene, patches, tracer, settings, groups,
                                  std::max<int64_t>(1, seeing) * std::max(1, settings.pathsPerPatch));
    const SpecularPaths& paths = *out.traced;
    out.paths = paths.paths;

    // Each row's share F(i, o), measured twice: by the row's own rays (binomial, variance about
    // f (1 - f) / m for m rays) and by the paths' etendue from patch i (a compound Poisson sum, variance
    // about f w / a for paths of mean weight w = sum w^2 / sum w over the patch's area a). Both are
    // unbiased; their inverse-variance mean, the ratio of the two variances taken from the weights
    // alone (not from either estimate, which would bias it), is the share the row sends on.
    // A path from patch i through object o then carries that share / (the paths' etendue from i to o)
    // of patch i's light per m^2 of its own etendue.
    out.patchGroup = patchGroup;
    out.groups = K;
    out.share.assign(n * K, 0.0);
    std::vector<RowResult> rows(n);
    parallelFor(
        int64_t(n),
        [&](int64_t begin, int64_t end) {
            std::vector<double> scale(K);
            for (int64_t ii = begin; ii < end; ++ii) {
                const size_t i = size_t(ii);
                const double* s = &share[i * K];
                if (std::all_of(s, s + K, [](double v) { return v <= 0; })) continue;
                std::fill(scale.begin(), scale.end(), 0.0);
                RowResult& row = rows[i];
                double* shared = &out.share[i * K];
                for (size_t k = paths.start[i]; k < paths.start[i + 1]; ++k) {
                    const SpecularPaths::Entry& e = paths.entries[k];
                    const size_t g = size_t(e.group);
                    if (e.kind == SpecularPaths::Weight) {
                        double f = s[g];
                        if (!rowRays.empty() && f > 0) {
                            const double a = patches.area[i] * (F.exposed.empty() ? 1.0 : double(F.exposed[i]));
                            const double own = std::max(rowRays[i], 1.0) / std::max(1 - f, 1e-3);
                            const double theirs = a * e.value[0] / e.value[2];
                            f = (own * f + theirs * e.value[0] / a) / (own + theirs);
                        }
                        shared[g] = f;
                        scale[g] = f / e.value[0];
                        continue;
                    }
                    if (s[g] <= 0 || scale[g] <= 0) continue;
                    (e.kind == SpecularPaths::Delivered ? row.delivered : row.lost)
                        .push_back({e.target, Rgb(scale[g] * e.value)});
                }
                for (size_t g = 0; g < K; ++g)
                    if (s[g] > 0 && scale[g] <= 0) {
                        row.lost.push_back({groups[g].object, Rgb::Constant(s[g])});
                        row.unresolved += s[g];
                        shared[g] = s[g];
                    }
                mergeByTarget(row.delivered);
                mergeByTarget(row.lost);
            }
        },
        64);

    // Compressed rows by source (outgoing, losses), then by target (incoming).
    out.outStart.assign(n + 1, 0);
    out.lossStart.assign(n + 1, 0);
    std::vector<size_t> inCount(n + 1, 0);
    double area = 0;
    for (size_t i = 0; i < n; ++i) {
        out.outStart[i + 1] = out.outStart[i] + rows[i].delivered.size();
        out.lossStart[i + 1] = out.lossStart[i] + rows[i].lost.size();
        for (const auto& [j, s] : rows[i].delivered) ++inCount[size_t(j) + 1];
        out.unresolvedShare += patches.area[i] * rows[i].unresolved;
        out.rowUnresolved.push_back(rows[i].unresolved);
        area += patches.area[i];
    }
    out.unresolvedShare /= std::max(area, 1e-300);
    for (size_t i = 0; i < n; ++i) {
        for (const auto& [j, s] : rows[i].delivered) {
            out.outTarget.push_back(j);
            out.outWeight.push_back(patches.area[i] * s / patches.area[size_t(j)]);
        }
        for (const auto& [o, s] : rows[i].lost) {
            out.lossObject.push_back(o);
            out.lossShare.push_back(s);
        }
    }
    out.inStart.assign(n + 1, 0);
    for (size_t j = 0; j < n; ++j) out.inStart[j + 1] = out.inStart[j] + inCount[j + 1];
    out.inSource.resize(out.outTarget.size());
    out.inWeight.resize(out.outTarget.size());
    std::vector<size_t> fill(out.inStart.begin(), out.inStart.end() - 1);
    for (size_t i = 0; i < n; ++i)
        for (size_t k = out.outStart[i]; k < out.outStart[i + 1]; ++k) {
            const size_t j = size_t(out.outTarget[k]);
            out.inSource[fill[j]] = int(i);
            out.inWeight[fill[j]] = out.outWeight[k];
            ++fill[j];
        }
    out.seconds = timer.seconds();
    if (previous && previous->traced) {
        logInfo("specular transport: the same ", paths.paths, " paths scaled to the rows cast again in ", out.seconds,
                " s");
    } else {
        g_transportRays.add(uint64_t(paths.rays));
        logInfo("specular transport: ", K, " mirror/glass objects, ", paths.paths, " paths from their surfaces (",
                paths.rays, " rays), ", out.outTarget.size(), " transfers in ", out.seconds, " s");
    }
    return out;
}

void matchSpecularShares(FormFactorMatrix& F, const SpecularTransport& transport) {
    const size_t K = transport.groups;
    if (transport.share.empty() || K == 0) return;
    const std::vector<int>& group = transport.patchGroup;
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
                const double rest = before < 1 - 1e-9 ? std::max(0.0, 1 - after) / (1 - before) : 1.0;
                F.scaleRow(i, [&](size_t j) { return group[j] >= 0 ? factor[size_t(group[j])] : rest; });
            }
        },
        64);
}

}  // namespace penumbra
