#include "solver/radiosity/hierarchy.h"

#include <algorithm>
#include <numeric>

#include "core/counters.h"
#include "core/error.h"
#include "core/log.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "core/timer.h"
#include "mesh/refine.h"
#include "solver/radiosity/form_factors.h"

namespace penumbra {
namespace {

const Counter g_linkRays("hierarchy.visibility_rays", "visibility rays between linked elements");
const Counter g_linkEvaluations("hierarchy.kernel_evaluations", "kernel evaluations of the links' form factors");

double brightness(const Rgb& b) { return b.sum() / 3; }

// A link: receiver r gathers F(r->s) B_s from source s. Structure of arrays, as the sweeps read them.
struct Links {
    std::vector<int> receiver, source;
    std::vector<float> visible;   // fraction of the visibility rays that got through
    std::vector<float> F;         // form factor from the receiver to the source, with visibility (-1: not yet)
    std::vector<uint8_t> partly;  // the visibility rays disagreed
    size_t size() const { return receiver.size(); }
    void add(int r, int s) {
        receiver.push_back(r), source.push_back(s), visible.push_back(0), F.push_back(-1), partly.push_back(0);
    }
    void copy(const Links& from, size_t k) {
        receiver.push_back(from.receiver[k]), source.push_back(from.source[k]), visible.push_back(from.visible[k]);
        F.push_back(from.F[k]), partly.push_back(from.partly[k]);
    }
};

class Hierarchy {
public:
    Hierarchy(const Scene& scene, const PatchSet& roots, const RayScene& rays, const HierarchySettings& settings)
        : scene_(scene), rays_(rays), settings_(settings) {
        nodes_ = roots;
        const size_t n = roots.size();
        parent_.assign(n, -1);
        firstChild_.assign(n, -1);
        rho_.resize(n);
        E_.resize(n);
        for (size_t i = 0; i < n; ++i) {
            PENUMBRA_CHECK(scene.materialOf(scene.objects[size_t(roots.object[i])]).type == MaterialType::Diffuse);
            rho_[i] = meanReflectance(scene, roots, i);
            E_[i] = kPi * meanEmission(scene, roots, i);
        }
        B_ = E_;
        H_.assign(n, Rgb::Zero());
        total_.assign(n, Rgb::Zero());
        power_ = 0;
        for (size_t i = 0; i < n; ++i) power_ += roots.area[i] * brightness(E_[i]);
        minArea_ = settings.minArea > 0
                       ? settings.minArea
                       : std::accumulate(roots.area.begin(), roots.area.end(), 0.0) / double(n) / 65536;
    }

    HierarchyResult run() {
        HierarchyResult out;
        Timer linkTimer;
        // Every pair of roots that face each other starts linked both ways.
        Links pending;
        for (size_t a = 0; a < nodes_.size(); ++a)
            for (size_t b = a + 1; b < nodes_.size(); ++b)
                if (facing(a, b)) pending.add(int(a), int(b)), pending.add(int(b), int(a));
        refine(pending);
        withinBudget(0);
        double secondsLinks = linkTimer.seconds(), secondsSolve = 0;
        for (int round = 1;; ++round) {
            Timer solveTimer;
            SolverSettings s = settings_.solver;
            solve(s, out.solution);
            secondsSolve += solveTimer.seconds();
            logInfo("hierarchy round ", round, ": ", leafCount(), " leaves of ", nodes_.size(), " elements, ",
                    links_.size(), " links; ", out.solution.iterations, " iterations to residual ",
                    out.solution.residual);
            out.stats.rounds = round;
            if (round >= settings_.maxRounds) break;
            Timer t;
            // The oracle again, with the radiosity now known: links whose source turned out bright split.
            Links again;
            std::swap(again, links_);
            const size_t before = again.size();
            const size_t refined = refine(again, true);
            withinBudget(round);
            secondsLinks += t.seconds();
            if (refined == 0) break;
            logDebug("hierarchy: ", refined, " of ", before, " links refined");
        }
        out.stats.secondsLinks = secondsLinks;
        out.stats.secondsSolve = secondsSolve;
        finish(out);
        return out;
    }

    // --max-memory for the hierarchy (it took 1.5 MiB under --max-memory 0.001, and 6.8 MiB by default
    // on the Cornell box, whatever the bound).
    void withinBudget(int round) const {
        const double bytes = hierarchyBytes(nodes_.size(), links_.size());
        if (settings_.maxBytes > 0 && bytes > settings_.maxBytes)
            throw Error(cat("the hierarchy's ", nodes_.size(), " elements and ", links_.size(), " links take ",
                            bytes / (1 << 20), " MiB ", round == 0 ? "as first linked" : cat("after round ", round),
                            ", more than the ", settings_.maxBytes / (1 << 20),
                            " MiB allowed (--max-memory): raise it, or --link-tolerance or --roots for fewer links"));
    }

private:
    bool facing(size_t a, size_t b) const { return planeSides(nodes_, a, b).front && planeSides(nodes_, b, a).front; }
    // Children may be half the finest patch area asked for: leaves then span the sizes about it.
    bool splittable(int i) const { return nodes_.area[size_t(i)] >= 2 * minArea_; }

    // Point-to-disc estimate of F(r -> s): the largest seen from r's centroid and from its corners
    // pulled a tenth in, so that a source touching the receiver's edge (a block on the floor) is
    // not judged from the far side of the receiver.
    double estimate(int r, int s) const {
        const Vec3& c = nodes_.centroid[size_t(r)];
        double best = pointToDisc(c, r, s);
        for (int k = 0; k < nodes_.cornerCount[size_t(r)]; ++k)
            best = std::max(best, pointToDisc(nodes_.corners[size_t(r)][size_t(k)] +
                                                  0.1 * (c - nodes_.corners[size_t(r)][size_t(k)]),
                                              r, s));
        return best;
    }
    double pointToDisc(const Vec3& x, int r, int s) const {
        const Vec3 d = nodes_.centroid[size_t(s)] - x;
        const double r2 = d.squaredNorm();
        const double cr = nodes_.normal[size_t(r)].dot(d), cs = -nodes_.normal[size_t(s)].dot(d);
        if (cr <= 0 || cs <= 0) return 0;
        const double as = nodes_.area[size_t(s)];
        return std::min(1.0, as * cr * cs / (r2 * (kPi * r2 + as)));
    }

    void splitElement(int i) {
        if (firstChild_[size_t(i)] >= 0) return;
        std::array<std::array<Vec3, 4>, 4> children;
        childPolygons(nodes_, size_t(i), children);
        std::array<std::array<Vec2, 4>, 4> uvs;
        const bool textured = nodes_.hasUv();
        if (textured) childUvs(nodes_, size_t(i), uvs);
        const int first = int(nodes_.size());
        for (size_t k = 0; k < 4; ++k) {
            nodes_.add(children[k], nodes_.cornerCount[size_t(i)], nodes_.object[size_t(i)], {0, 0, 0, 0},
                       textured ? &uvs[k] : nullptr);
            PENUMBRA_CHECK_EQ(nodes_.size(), parent_.size() + 1);  // a child of a real patch has area
            parent_.push_back(i);
            firstChild_.push_back(-1);
            // Under a texture each element takes its own mean; else its parent's factors.
            rho_.push_back(textured ? meanReflectance(scene_, nodes_, nodes_.size() - 1) : rho_[size_t(i)]);
            E_.push_back(textured ? Rgb(kPi * meanEmission(scene_, nodes_, nodes_.size() - 1)) : E_[size_t(i)]);
            B_.push_back(B_[size_t(i)]);
            H_.push_back(Rgb::Zero());
            total_.push_back(total_[size_t(i)]);
        }
        firstChild_[size_t(i)] = first;
    }

    // Rays for the links in `list` from `begin` on, in parallel (the elements do not change meanwhile).
    void testVisibility(Links& list, size_t begin) {
        parallelFor(
            int64_t(list.size() - begin),
            [&](int64_t b, int64_t e) {
                prepareTracingThread();
                uint64_t mine = 0;
                for (int64_t k = b; k < e; ++k) {
                    const size_t l = begin + size_t(k);
                    const size_t r = size_t(list.receiver[l]), s = size_t(list.source[l]);
                    const bool clipped = planeSides(nodes_, r, s).straddles() || planeSides(nodes_, s, r).straddles();
                    const Visibility v = visibleFraction(nodes_, rays_, std::min(r, s), std::max(r, s), 1, 1, clipped,
                                                         settings_.visibilityRays, settings_.seed);
                    mine += uint64_t(v.rays);
                    list.visible[l] = float(v.fraction);
                    list.partly[l] = v.fraction > 0 && v.fraction < 1;
                }
                g_linkRays.add(mine);
            },
            64);
    }

    // Takes links, tests them, and keeps or splits each by the oracle until every one is kept;
    // returns how many were split. With `known`, the links already carry their visibility.
    size_t refine(Links& pending, bool known = false) {
        size_t refinedCount = 0;
        size_t tested = known ? pending.size() : 0;
        for (size_t at = 0; at < pending.size();) {
            if (tested < pending.size()) {
                testVisibility(pending, tested);
                tested = pending.size();
            }
            // Decide the links tested so far; the splits append new links to be tested next.
            const size_t end = pending.size();
            for (; at < end; ++at) {
                const int r = pending.receiver[at], s = pending.source[at];
                // BFA: the power the link carries, F(r->s) B_s A_r, against a share of the emitted power.
                const double carried = estimate(r, s) * brightness(B_[size_t(s)]) * nodes_.area[size_t(r)];
                const double limit = settings_.linkTolerance * power_;
                const bool needs = carried > limit || (pending.partly[at] && carried > 0.1 * limit);
                const bool big = nodes_.area[size_t(r)] >= nodes_.area[size_t(s)];
                const int split = needs ? (big ? (splittable(r)   ? r
                                                  : splittable(s) ? s
                                                                  : -1)
                                               : (splittable(s)   ? s
                                                  : splittable(r) ? r
                                                                  : -1))
                                        : -1;
                // A link the rays found hidden still splits if it would carry too much unhidden:
                // four rays miss a partly visible pair of large elements often, and dropping the
                // link would lose its light; its children are tested afresh.
                if (split < 0) {
                    if (pending.visible[at] > 0) links_.copy(pending, at);
                    continue;
                }
                ++refinedCount;
                splitElement(split);
                const int c0 = firstChild_[size_t(split)];
                for (int c = c0; c < c0 + 4; ++c) {
                    const int nr = split == r ? c : r, ns = split == s ? c : s;
                    if (facing(size_t(nr), size_t(ns))) pending.add(nr, ns);
                }
            }
            if (at >= pending.size()) break;
        }
        formFactors();
        return refinedCount;
    }

    // The kept links' form factors: the analytic kernel over the smaller element, times visibility.
    void formFactors() {
        const size_t n = links_.size();
        parallelFor(
            int64_t(n),
            [&](int64_t b, int64_t e) {
                uint64_t mine = 0;
                for (int64_t k = b; k < e; ++k) {
                    const size_t l = size_t(k);
                    if (links_.F[l] >= 0) continue;  // kept from an earlier round
                    const size_t r = size_t(links_.receiver[l]), s = size_t(links_.source[l]);
                    const bool rSmaller = nodes_.area[r] <= nodes_.area[s];
                    const AreaFactors g =
                        unoccludedAreaFactors(nodes_, rSmaller ? r : s, rSmaller ? s : r, settings_.cubature, &mine);
                    links_.F[l] = float(double(links_.visible[l]) * g.front / nodes_.area[r]);
                }
                g_linkEvaluations.add(mine);
            },
            256);
        // Receivers together, in element order: the gather walks them so.
        std::vector<size_t> order(links_.size());
        std::iota(order.begin(), order.end(), 0);
        std::stable_sort(order.begin(), order.end(),
                         [&](size_t a, size_t b) { return links_.receiver[a] < links_.receiver[b]; });
        Links sorted;
        for (size_t k : order) sorted.copy(links_, k);
        links_ = std::move(sorted);
        linkStart_.assign(nodes_.size() + 1, 0);
        for (int r : links_.receiver) ++linkStart_[size_t(r) + 1];
        for (size_t i = 0; i < nodes_.size(); ++i) linkStart_[i + 1] += linkStart_[i];
        closeRows();
    }

    // Per leaf, the form factors of the links that serve it (its own and its ancestors'): the row sum
    // the hierarchy gives it. In a closed scene that is one; each leaf's gathered light is scaled by
    // the inverse. Children come after their parents, so one pass in element order sums down the tree.
    void closeRows() {
        const size_t n = nodes_.size();
        std::vector<double> sum(n, 0.0);
        for (size_t i = 0; i < n; ++i) {
            for (size_t l = linkStart_[i]; l < linkStart_[i + 1]; ++l) sum[i] += double(links_.F[l]);
            if (parent_[i] >= 0) sum[i] += sum[size_t(parent_[i])];
        }
        scale_.assign(n, 1.0);
        stats_.leafSumMin = 1e300, stats_.leafSumMax = 0;
        for (size_t i = 0; i < n; ++i) {
            if (firstChild_[i] >= 0) continue;
            stats_.leafSumMin = std::min(stats_.leafSumMin, sum[i]);
            stats_.leafSumMax = std::max(stats_.leafSumMax, sum[i]);
            if (settings_.closedScene && sum[i] > 0) scale_[i] = 1 / sum[i];
        }
        if (settings_.closedScene)
            logDebug("hierarchy: closed scene: the leaves' link sums ", stats_.leafSumMin, " .. ", stats_.leafSumMax,
                     " scaled to one");
    }

    size_t leafCount() const { return size_t(std::count(firstChild_.begin(), firstChild_.end(), -1)); }

    // Irradiance pushed down from the ancestors plus the element's own; B pulled up as area means.
    Rgb pushPull(int i, const Rgb& down, std::vector<Rgb>& next) {
        const Rgb total = down + H_[size_t(i)];
        const int c0 = firstChild_[size_t(i)];
        total_[size_t(i)] = c0 < 0 ? Rgb(scale_[size_t(i)] * total) : total;
        if (c0 < 0) return next[size_t(i)] = E_[size_t(i)] + rho_[size_t(i)] * total_[size_t(i)];
        Rgb sum = Rgb::Zero();
        for (int c = c0; c < c0 + 4; ++c) sum += nodes_.area[size_t(c)] * pushPull(c, total, next);
        return next[size_t(i)] = sum / nodes_.area[size_t(i)];
    }

    // Gather along every link, then push-pull, until the leaves' radiosity settles (Jacobi).
    void solve(const SolverSettings& settings, RadiositySolution& out) {
        const size_t n = nodes_.size();
        double emitted = 0;
        for (size_t i = 0; i < n; ++i)
            if (firstChild_[i] < 0) emitted += nodes_.area[i] * E_[i].sum();
        std::vector<Rgb> next(n);
        out = RadiositySolution();
        Timer timer;
        Progress progress("hierarchy solve", settings.maxIterations);
        for (int k = 1;; ++k) {
            gather();
            parallelFor(int64_t(rootCount()), [&](int64_t b, int64_t e) {
                for (int64_t root = b; root < e; ++root) pushPull(int(root), Rgb::Zero(), next);
            });
            // Residual: the change of the leaves' power, over the emitted power (Jacobi's step is
            // the residual of the iterate it starts from).
            double change = 0;
            for (size_t i = 0; i < n; ++i)
                if (firstChild_[i] < 0) change += nodes_.area[i] * (next[i] - B_[i]).abs().sum();
            std::swap(B_, next);
            const double residual = emitted > 0 ? change / emitted : 0;
            out.history.push_back({k, residual, timer.seconds()});
            out.iterations = k;
            out.residual = residual;
            out.converged = residual <= settings.tolerance;
            progress.update();
            if (out.converged || k >= settings.maxIterations) break;
        }
        progress.done();
        out.seconds = timer.seconds();
        if (!out.converged)
            logWarning("hierarchy stopped after ", out.iterations, " iterations with residual ", out.residual,
                       " above the tolerance ", settings.tolerance);
    }

    void gather() {
        parallelFor(
            int64_t(nodes_.size()),
            [&](int64_t b, int64_t e) {
                for (int64_t i = b; i < e; ++i) {
                    Rgb h = Rgb::Zero();
                    for (size_t l = linkStart_[size_t(i)]; l < linkStart_[size_t(i) + 1]; ++l)
                        h += double(links_.F[l]) * B_[size_t(links_.source[l])];
                    H_[size_t(i)] = h;
                }
            },
            256);
    }

    size_t rootCount() const {
        size_t k = 0;
        while (k < parent_.size() && parent_[k] < 0) ++k;
        return k;
    }

    void finish(HierarchyResult& out) {
        // The power, from one more gather with the final B: what leaves every surface, and what
        // arrives (the rest left the scene).
        gather();
        std::vector<Rgb> next(nodes_.size());
        for (size_t root = 0; root < rootCount(); ++root) pushPull(int(root), Rgb::Zero(), next);
        Rgb leaving = Rgb::Zero(), arriving = Rgb::Zero();
        PatchSet leaves;
        for (size_t i = 0; i < nodes_.size(); ++i) {
            if (firstChild_[i] >= 0) continue;
            leaves.add(nodes_.corners[i], nodes_.cornerCount[i], nodes_.object[i], {0, 0, 0, 0},
                       nodes_.hasUv() ? &nodes_.uv[i] : nullptr);
            out.B.push_back(B_[i]);
            PowerBalance& p = out.power;
            p.emitted.push_back(nodes_.area[i] * E_[i]);
            p.absorbed.push_back(nodes_.area[i] * (1 - rho_[i]) * total_[i]);
            p.totalEmitted += p.emitted.back();
            p.totalAbsorbed += p.absorbed.back();
            leaving += nodes_.area[i] * B_[i];
            arriving += nodes_.area[i] * total_[i];
        }
        out.power.escaped = leaving - arriving;
        out.leaves = shareVertices(leaves);
        stats_.roots = rootCount();
        stats_.elements = nodes_.size();
        stats_.leaves = out.B.size();
        stats_.links = links_.size();
        stats_.partlyVisibleLinks = size_t(std::count(links_.partly.begin(), links_.partly.end(), 1));
        stats_.bytes = hierarchyBytes(nodes_.size(), links_.size());
        const int rounds = out.stats.rounds;
        const double sl = out.stats.secondsLinks, ss = out.stats.secondsSolve;
        out.stats = stats_;
        out.stats.rounds = rounds, out.stats.secondsLinks = sl, out.stats.secondsSolve = ss;
    }

    const Scene& scene_;
    const RayScene& rays_;
    const HierarchySettings& settings_;
    PatchSet nodes_;  // every element: roots first, then children in fours
    std::vector<int> parent_, firstChild_;
    std::vector<Rgb> rho_, E_, B_, H_, total_;
    std::vector<double> scale_;  // per element: what its gathered light is multiplied by (closeRows)
    Links links_;                // kept links, by receiver once the form factors are known
    std::vector<size_t> linkStart_;
    double power_ = 0, minArea_ = 0;
    HierarchyStats stats_;
};

}  // namespace

double hierarchyBytes(size_t elements, size_t links) {
    // Per element: the patch arrays (corners, normal, centroid, area, radius, object, count and
    // display ids) and the tree's (parent, first child, rho, E, B, H, pushed total).
    const double element = 4 * 24 + 24 + 24 + 8 + 8 + 4 + 1 + 16 + 4 + 4 + 5 * 24;
    const double link = 4 + 4 + 4 + 1 + sizeof(size_t) / 4.0;
    return double(elements) * element + double(links) * link;
}

HierarchyResult solveHierarchy(const Scene& scene, const PatchSet& roots, const RayScene& rays,
                               const HierarchySettings& settings) {
    for (const SceneObject& o : scene.objects)
        if (scene.materialOf(o).type != MaterialType::Diffuse)
            throw Error(cat("object '", o.name, "': --solver hierarchical handles diffuse surfaces only; this one is ",
                            "a mirror or glass: use --solver gauss-seidel (or leave --solver to choose)"));
    Hierarchy h(scene, roots, rays, settings);
    return h.run();
}

}  // namespace penumbra
