#include "solver/solve.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <numeric>
#include <sstream>

#include "core/cluster.h"
#include "core/error.h"
#include "core/log.h"
#include "core/timer.h"
#include "mesh/refine.h"
#include "solver/radiosity/ray_form_factors.h"
#include "solver/radiosity/vertex_radiosity.h"
#include "solver/tracer.h"
#include "solver/visibility.h"

namespace penumbra {
namespace {

double procKilobytes(const char* file, const char* key) {
    std::ifstream in(file);
    std::string line;
    while (std::getline(in, line))
        if (line.rfind(key, 0) == 0) {
            std::istringstream fields(line.substr(std::string(key).size()));
            double kb = 0;
            fields >> kb;
            return kb * 1024;
        }
    return 0;
}

// A closed scene whose surfaces all reflect everything in some channel, with emission in it, has no
// steady state: the light grows without bound. Refuse it rather than iterate forever.
void checkSteadyState(const Scene& scene, const RadiositySystem& s, const std::vector<double>& rows) {
    double area = 0, loss = 0;
    for (size_t i = 0; i < s.size(); ++i) {
        area += s.area[i];
        loss += s.area[i] * std::max(0.0, 1 - rows[i]);
    }
    const double escapeFraction = area > 0 ? loss / area : 1;
    // What a surface keeps of the light it meets: a mirror its tint, glass its transmittance
    // (Fresnel's split loses nothing). A box of reflectance-1 mirrors around a reflectance-1 emitter
    // was accepted when only the diffuse surfaces were looked at.
    auto keeps = [&](size_t i, int c) {
        if (!s.specular[i]) return s.reflectance[i][c];
        const Material& m = scene.materialOf(scene.objects[size_t(s.object[i])]);
        return m.type == MaterialType::Mirror ? m.reflectance[c] : m.transmittance[c];
    };
    for (int c = 0; c < 3; ++c) {
        bool allOne = true, emits = false;
        for (size_t i = 0; i < s.size(); ++i) {
            allOne = allOne && keeps(i, c) >= 1;
            emits = emits || s.emission[i][c] > 0;
        }
        if (allOne && emits && escapeFraction < 1e-4)
            throw Error(cat(scene.path, ": no steady state: the scene is closed (", escapeFraction,
                            " of the light escapes) and every surface has reflectance 1 in channel ", c,
                            ", so light emitted there is never absorbed; give some surface a reflectance below 1"));
    }
}

}  // namespace

double availableMemoryBytes() { return procKilobytes("/proc/meminfo", "MemAvailable:"); }

double matrixBudget(const SolveOptions& options) {
    if (options.maxMemoryBytes > 0) return options.maxMemoryBytes;
    double mine = availableMemoryBytes() / cluster::ranksOnHost();
    if (!cluster::distributed()) return mine;
    // Every rank must choose alike (a matrix in row blocks or whole, the solver): the least of them.
    double least = 0;
    for (const std::string& theirs :
         cluster::allGather(std::string(reinterpret_cast<const char*>(&mine), sizeof mine))) {
        double b = 0;
        std::memcpy(&b, theirs.data(), std::min(sizeof b, theirs.size()));
        if (b > 0) least = least > 0 ? std::min(least, b) : b;
    }
    return least;
}
double peakMemoryBytes() { return procKilobytes("/proc/self/status", "VmHWM:"); }

bool resetPeakMemory() {
    std::ofstream clear("/proc/self/clear_refs");
    clear << "5";  // 5: reset the peak resident set size to the current one
    clear.flush();
    return bool(clear);
}

namespace {

constexpr size_t kAutoMatrixPatches = 12000;  // past this the n^2 analytic form factors take minutes

constexpr int kClosureRays = 16;  // per patch, for sceneClosure

bool castsFormFactors(const SolveOptions& o) { return o.formFactors.method == "rays"; }

// Bytes the matrix of n patches takes: n^2 floats analytic. Ray-cast: one entry per ray at most,
// the second pass of --ff-noise at most as many rays as the first, and rays read where they land
// (ray_form_factors.h) add their neighbours' columns: 4% more entries on the Cornell box, 22% on the
// building, a quarter allowed.
double matrixBytes(const SolveOptions& o, size_t n) {
    const int side = stratumSide(o.formFactors.raysPerPatch);
    const double passes = o.formFactors.objectNoise < 1 ? 2 : 1;
    return castsFormFactors(o) ? 1.25 * passes * double(sparseFormFactorBytes(n, uint64_t(side * side)))
                               : double(formFactorMatrixBytes(n));
}

}  // namespace

void solveBuiltMatrix(const SolveOptions& options, const StepObserver& observer, SolveResult& r) {
    const auto solver = makeSolver(options.solver);
    Timer solveTimer;
    r.solution = solver->solve(r.F, r.system, options.solverSettings, observer);
    r.secondsSolve += solveTimer.seconds();
    logInfo(options.solver, ": ", r.solution.iterations, " iterations, residual ", r.solution.residual, " in ",
            solveTimer.seconds(), " s");
    r.power = powerBalance(r.system, r.F, r.solution.B);
    Timer vertexTimer;
    const std::vector<char> small = options.forSolvedIndirectGather ? smallSources(r.system) : std::vector<char>{};
    if (std::find(small.begin(), small.end(), 1) != small.end())
        r.corners = interpolateCorners(r.patches, r.solution.display);
    else if (options.vertexRadiosity == "gather")
        r.corners = gatherCorners(r.patches, r.system, r.F, r.solution.display, *r.rays);
    else if (options.vertexRadiosity == "direct")
        r.corners = directCorners(r.patches, r.system, r.F, r.solution.display, *r.rays);
    else
        r.corners = interpolateCorners(r.patches, r.solution.display);
    r.indirect = indirectCorners(r.patches, r.system, r.F, r.solution.display);
    r.secondsVertices += vertexTimer.seconds();
}

namespace {

// The rays patch i's row was cast with at side x side strata: its exposed share of them, and of a
// mean row the share it saw.
double rowRays(const FormFactorMatrix& F, size_t i, int side) {
    return double(side) * side * double(F.exposed[i]) * (F.hasMeanRow(i) ? F.seen[i] : 1.0);
}

// Per patch, the variance of the mean brightness its rays gather, each ray reading the brightness
// of the patch it lands on (B, a first solve): (E[b^2] - E[b]^2) / rays from its row's ray-cast
// shares, the analytic columns left out (`visibility`: but for the noise of their visibility rays).
// Multinomial, so the gain of the strata is not in it: measured over 8 seeds on the Cornell box,
// objects' spread was 0.8-3x (mostly 2x) below it.
std::vector<double> gatherVariance(const SolveResult& r, const std::vector<char>& analytic, const std::vector<Rgb>& B,
                                   const SolveOptions& options, const std::vector<int>& raysFor, bool visibility) {
    const size_t n = r.patches.size();
    std::vector<double> var(n, 0.0);
    const int base = stratumSide(options.formFactors.raysPerPatch);
    for (size_t i = 0; i < n; ++i) {
        double m1 = 0, m2 = 0;
        r.F.forEachInRow(i, [&](size_t j, float f) {
            if (j < analytic.size() && analytic[j]) return;
            const double b = B[j].sum() / 3;
            m1 += f * b, m2 += f * b * b;
        });
        const double rays = rowRays(r.F, i, i < raysFor.size() && raysFor[i] > 0 ? stratumSide(raysFor[i]) : base);
        var[i] = rays >= 1 ? std::max(0.0, m2 - m1 * m1) / rays : 0;
    }
    // The small sources' columns, exact but for their visibility rays: a lamp's light through a
    // penumbra, sum over the row's uncertain entries of var(F(i, j)) b_j^2.
    if (visibility)
        for (const FormFactorMatrix::EntryVariance& e : r.F.entryVariance) {
            const double b = B[size_t(e.column)].sum() / 3;
            var[size_t(e.row)] += double(e.variance) * b * b;
        }
    return var;
}

// An object's variance as a sum over patches, sum_j w_j var_j: its own patches' gathers, w_j =
// (A_j rho_j)^2, and the noise of the patches they gather from, w_j = c_j^2 rho_j^2 with c_j =
// sum_i A_i rho_i F(i, j) over its patches i (first order, each patch's noise its own gather's).
// One object at a time: add, read, clear.
class ObjectTerms {
public:
    explicit ObjectTerms(const SolveResult& r)
        : r_(r), own_(r.patches.size(), 0.0), c_(r.patches.size(), 0.0), seen_(r.patches.size(), 0) {}

    // Takes in the object's patches; returns its lit brightness, sum A_i b_i.
    double add(const std::vector<size_t>& members, const std::vector<Rgb>& B) {
        double light = 0;
        for (size_t i : members) {
            const double w = r_.system.area[i] * rho(i);
            light += r_.system.area[i] * B[i].sum() / 3;
            touch(i);
            own_[i] += w * w;
            r_.F.forEachInRow(i, [&](size_t j, float f) {
                touch(j);
                c_[j] += w * f;
            });
        }
        return light;
    }
    // The patches with a term (own or gathered from), and each one's weight w_j.
    const std::vector<size_t>& patches() const { return touched_; }
    double weight(size_t j) const { return own_[j] + c_[j] * c_[j] * rho(j) * rho(j); }
    void clear() {
        for (size_t j : touched_) own_[j] = c_[j] = 0, seen_[j] = 0;
        touched_.clear();
    }

private:
    double rho(size_t i) const { return r_.system.reflectance[i].sum() / 3; }
    void touch(size_t j) {
        if (!seen_[j]) seen_[j] = 1, touched_.push_back(j);
    }

    const SolveResult& r_;
    std::vector<double> own_, c_;
    std::vector<char> seen_;
    std::vector<size_t> touched_;
};

// Each object's estimated standard error (ObjectTerms' sum with each patch's gather variance), relative
// to its mean: over the object's lit brightness sum(A_i b_i), 0 where it is dark or has no patches.
std::vector<double> objectNoise(const Scene& scene, const SolveOptions& options, const SolveResult& r,
                                const std::vector<char>& analytic, const std::vector<Rgb>& B,
                                const std::vector<int>& raysFor) {
    std::vector<double> var = gatherVariance(r, analytic, B, options, raysFor, true);
    // And the light each patch gathers through mirrors and glass, whose paths have noise of their own.
    for (size_t j = 0; j < var.size(); ++j) var[j] += r.system.transport.incomingVariance(j, B);
    const std::vector<std::vector<size_t>> members = r.patches.byObject(scene.objects.size());
    std::vector<double> noise(members.size(), 0.0);
    ObjectTerms terms(r);
    for (size_t o = 0; o < members.size(); ++o) {
        const double light = terms.add(members[o], B);
        double sum = 0;
        for (size_t j : terms.patches()) sum += terms.weight(j) * var[j];
        terms.clear();
        noise[o] = light > 0 ? std::sqrt(sum) / light : 0;
    }
    return noise;
}

// Rays per patch cast again for the objects whose estimated noise (objectNoise, what they gather
// from included) is above --ff-noise. An object's variance is a sum over patches, sum_j t_j: its
// own patches' gathers and those of the patches it gathers from. Casting patch j again with f_j
// times its rays leaves sum_j t_j / f_j, and the fewest rays that bring it to the target T (sum_j
// n_j f_j least) are f_j = sqrt(t_j / n_j) sum_k sqrt(t_k n_k) / T^2 (Neyman's allocation): a
// table's underside, which gathers its noise from the floor under it, has those floor patches
// cast again, not its own (the floor as a whole is quiet). Per object at most 64 times the rays
// (kSmallObjectFactor for objects of fewer than kSmallObjectPatches patches' area), in all at most
// as many rays again as the first pass: the largest objects are served first, each in full while
// that lasts, and the rest share what is left in proportion to what they ask; then the large
// surfaces ask for a tighter target from half as many again (below). Empty when no object needs
// more. The building's large surfaces: 1.75 misses of 1% a solve over 8 seeds with each
// object's own rows cast again (an even share of the budget), 0.125 with this.
constexpr double kSmallObjectPatches = 3, kSmallObjectFactor = 4;
constexpr double kTightPatches = 14, kTightest = 0.4, kTightBudget = 0.5;
std::vector<int> raysForObjectNoise(const Scene& scene, const SolveOptions& options, const SolveResult& r,
                                    const std::vector<char>& analytic, const std::vector<Rgb>& B) {
    const double target = options.formFactors.objectNoise;
    if (!(target > 0) || target >= 1) return {};
    // Without the lamps' visibility noise: a patch's estimate of it comes from the very rays whose
    // answer it would replace (a penumbra whose rays all passed states none and reads bright), and
    // choosing by it kept the bright ones: the Cornell box's short_block_2, which sees the floor in
    // the block's half-shadow, read +0.49% over 8 seeds (+0.05% without).
    const std::vector<double> sampled = gatherVariance(r, analytic, B, options, {}, false);
    const size_t n = r.patches.size();
    const int base = stratumSide(options.formFactors.raysPerPatch);
    const double baseRays = double(base) * base;
    auto rays = [&](size_t j) { return rowRays(r.F, j, base); };
    const std::vector<std::vector<size_t>> members = r.patches.byObject(scene.objects.size());
    std::vector<double> area(members.size(), 0.0);
    for (size_t i = 0; i < n; ++i) area[size_t(r.patches.object[i])] += r.patches.area[i];
    // Each patch's variance as its object's patches have it on average (a ray's, area-weighted), over
    // its own rays: a patch's own sample variance picks the rows that happened to gather unusual
    // light (a row with none of a rare bright patch's rays states none), and casting those again while
    // keeping the rest biases the mean. On the Cornell box over 8 seeds, per-patch variances spread
    // short_block_2 by 0.82% and left one seed's worst object 1.71% off the reference; the object's
    // mean variance 0.42% and 0.83%.
    std::vector<double> var(n, 0.0);
    for (size_t o = 0; o < members.size(); ++o) {
        double perRay = 0;
        for (size_t i : members[o]) perRay += r.patches.area[i] * sampled[i] * rays(i);
        perRay = area[o] > 0 ? perRay / area[o] : 0;
        for (size_t i : members[o]) var[i] = rays(i) > 0 ? perRay / rays(i) : 0;
    }
    // Objects smaller than kSmallObjectPatches patches of the mesh's size (its patches' area-weighted
    // mean area: a book's face, a handle) ask at most kSmallObjectFactor times the rays: the
    // building's 9,000 of them, each asking up to 64x, had scaled everyone's extra rays down to 8.8x,
    // and its tables' undersides kept 1.3-1.5% of estimated noise (0.94-0.99% with the cap).
    double weighted = 0, total = 0;  // the mesh's patch area, as its large surfaces have it
    for (size_t i = 0; i < n; ++i) weighted += r.patches.area[i] * r.patches.area[i], total += r.patches.area[i];
    const double patchArea = total > 0 ? weighted / total : 0;

    // The factors each object asks, (patch, factor) with factor > 1, from its terms t_j = w_j var_j.
    ObjectTerms terms(r);
    std::vector<double> t(n, 0.0);
    auto asks = [&](size_t o, double noise) {
        std::vector<std::pair<size_t, double>> wants;
        const double light = terms.add(members[o], B);
        double sum = 0, neyman = 0;
        for (size_t j : terms.patches()) {
            t[j] = terms.weight(j) * var[j];
            sum += t[j];
            neyman += std::sqrt(t[j] * rays(j));
        }
        const double goal = noise * noise * light * light;
        if (light > 0 && sum > goal) {
            const double cap = area[o] < kSmallObjectPatches * patchArea ? kSmallObjectFactor : 64.0;
            for (size_t j : terms.patches()) {
                if (!(t[j] > 0)) continue;  // a patch wholly inside a solid casts nothing
                const double f = std::min(cap, std::sqrt(t[j] / rays(j)) * neyman / goal);
                if (f > 1) wants.emplace_back(j, f);
            }
        }
        terms.clear();
        return wants;
    };

    // Largest first: a large surface fills more of every view and carries more of the light, and
    // its rows cost no more a ray than a small object's. On the building, 8,393 of the 8,775 objects
    // under 0.3 m^2 ask 18x the first pass between them, and an even scaling left the ceilings and
    // the tables' undersides almost nothing.
    std::vector<size_t> order(scene.objects.size());
    for (size_t o = 0; o < order.size(); ++o) order[o] = o;
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return area[a] > area[b]; });
    std::vector<double> factor(n, 0.0);
    auto cost = [&](const std::vector<std::pair<size_t, double>>& wants, double scale) {
        double extra = 0;
        for (const auto& [j, f] : wants)
            if (f * scale > 1) extra += std::max(0.0, f * scale - factor[j]) * baseRays;
        return extra;
    };
    double budget = baseRays * double(n);
    size_t asking = 0, served = 0;
    std::vector<std::vector<std::pair<size_t, double>>> rest;
    for (size_t o : order) {
        std::vector<std::pair<size_t, double>> wants = asks(o, target);
        if (wants.empty()) continue;
        ++asking;
        const double extra = rest.empty() ? cost(wants, 1) : 0;
        if (rest.empty() && extra <= budget) {
            budget -= extra;
            ++served;
            for (const auto& [j, f] : wants) factor[j] = std::max(factor[j], f);
        } else {
            rest.push_back(std::move(wants));
        }
    }
    double rests = 0;
    for (const auto& wants : rest) rests += cost(wants, 1);
    const double scale = rests > budget ? budget / rests : 1;
    for (const auto& wants : rest)
        for (const auto& [j, f] : wants)
            if (f * scale > 1) factor[j] = std::max(factor[j], f * scale);
    // Then the large surfaces, to a tighter target from a budget of their own: a surface of more than
    // kTightPatches of the mesh's patches asks for the target times sqrt(kTightPatches patches / its
    // area), down to kTightest times it, largest first while kTightBudget of the first pass's rays
    // lasts. A large surface's error is the most light misplaced and the most pixels, and the budget
    // above runs out before they are quiet (the building's ceilings state 0.26% and never ask). The
    // one-sided building, seeds 1-8, against the mean of two references: ceilings' spread 0.24% ->
    // 0.15%, tables' undersides 0.45% -> 0.25%, the worst large surface per seed 0.73-1.03% ->
    // 0.53-0.72%, for 1-2 s. Inside the budget above instead, the Cornell box's walls, served first,
    // starved its blocks (worst object up to 2.6%).
    double tightBudget = kTightBudget * baseRays * double(n);
    const double tightArea = kTightPatches * patchArea;
    size_t tightened = 0;
    for (size_t o : order) {
        if (!(area[o] > tightArea)) break;
        const std::vector<std::pair<size_t, double>> wants =
            asks(o, target * std::max(kTightest, std::sqrt(tightArea / area[o])));
        const double extra = cost(wants, 1);
        if (extra <= 0) continue;
        if (extra > tightBudget) break;
        tightBudget -= extra;
        ++tightened;
        for (const auto& [j, f] : wants) factor[j] = std::max(factor[j], f);
    }
    std::vector<int> raysFor(n, 0);
    size_t patches = 0;
    for (size_t i = 0; i < n; ++i)
        if (factor[i] > 1) raysFor[i] = int(std::ceil(factor[i] * baseRays)), ++patches;
    if (patches == 0) return {};
    logInfo("form factors (rays): ", asking, " objects above ", 100 * target, "% estimated noise: ", patches,
            " patches they gather from cast again, with the rays the ", served, " largest ask",
            rest.empty()
                ? std::string()
                : cat(" and ", 100 * scale, "% of what the others ask (at most as many rays again as the first pass)"),
            tightened ? cat("; ", tightened, " large surfaces to a tighter target (up to half as many again)") : "");
    return raysFor;
}

// One solve of the matrix system on the patches in `r`: form factors, specular transport, the
// iterative solve and the power balance. Stage times add to those already in `r`.
void solveMatrix(const Scene& scene, const SolveOptions& options, const StepObserver& observer, SolveResult& r) {
    const size_t n = r.patches.size();
    const double budget = matrixBudget(options);
    const double need = matrixBytes(options, n) + 400.0 * double(n);
    SolveOptions blocked = options;  // row blocks: the form factors' settings say whose rows
    const int ranks = cluster::size();
    const double eachRank = matrixBytes(options, n) / ranks + 400.0 * double(n);
    if (budget > 0 && need > budget && !castsFormFactors(options) && ranks > 1 && eachRank <= budget) {
        // Too large for one host, not for the ranks together: each holds a block of rows.
        const auto refuse = [&](const std::string& why) {
            throw Error(cat("the form-factor matrix of ", n, " patches needs ", need / (1 << 20),
                            " MiB, more than the ", budget / (1 << 20),
                            " MiB allowed (--max-memory); in row blocks over the ", ranks, " ranks it would fit (",
                            eachRank / (1 << 20), " MiB each), but ", why));
        };
        if (scene.hasSpecular()) refuse("the transport through mirrors and glass needs every row on every rank");
        if (options.refine.tolerance > 0) refuse("--refine reads every row on every rank");
        if (options.solver != "gauss-seidel" && options.solver != "jacobi")
            refuse(cat("--solver ", options.solver, " needs every row on every rank (gauss-seidel and jacobi do not)"));
        blocked.formFactors.rowBlocks = rowBlocksFor(n, ranks);
        logInfo("form-factor matrix: ", n, " x ", n, " floats, ", matrixBytes(options, n) / (1 << 20), " MiB (",
                need / (1 << 20), " MiB with the rest of the solve), more than the ", budget / (1 << 20),
                " MiB allowed on one rank: held in row blocks, ", matrixBytes(options, n) / ranks / (1 << 20),
                " MiB on each of the ", ranks, " ranks");
    } else if (budget > 0 && need > budget) {
        const size_t fit =
            castsFormFactors(options) ? size_t(double(n) * budget / need) : size_t(std::sqrt(budget / sizeof(float)));
        throw Error(cat("the form-factor matrix of ", n, " patches needs ", need / (1 << 20), " MiB, more than the ",
                        budget / (1 << 20), " MiB allowed (--max-memory): about ", fit,
                        " patches fit; lower --patches or raise --max-memory"));
    }
    if (castsFormFactors(options))
        logInfo("form-factor matrix: ", n, " sparse rows, at most ", matrixBytes(options, n) / (1 << 20), " MiB");
    else if (blocked.formFactors.rowBlocks.empty())
        logInfo("form-factor matrix: ", n, " x ", n, " floats, ", matrixBytes(options, n) / (1 << 20), " MiB");

    Timer ffTimer;
    r.F = FormFactorMatrix();  // the previous round's matrix goes before the next one is made
    HitReadings readings;
    if (!r.rays) r.rays = buildRayScene(scene, r.patches);  // else graded with it (contact_grading.h)
    r.system = buildSystem(scene, r.patches);
    std::vector<char> emitting(n, 0);
    for (size_t i = 0; i < n; ++i) emitting[i] = r.system.emission[i].maxCoeff() > 0;
    const std::vector<char> analytic = smallSources(r.system);  // the small sources' exact columns
    if (castsFormFactors(options)) {
        r.F = castFormFactors(r.patches, *r.rays, options.formFactors, analytic, emitting, &readings);
        // What a patch's light leaves from and lands on is its uncovered part (ray_form_factors.h).
        size_t covered = 0;
        for (size_t i = 0; i < n; ++i) {
            r.system.area[i] *= double(r.F.exposed[i]);
            covered += r.F.exposed[i] < 1;
        }
        if (covered) logInfo("form factors (rays): ", covered, " patches partly covered by a solid resting on them");
    } else {
        r.F = computeFormFactors(r.patches, *r.rays, blocked.formFactors);
    }
    std::vector<double> rows = rowSums(r.F);
    r.rowSumMin = n ? *std::min_element(rows.begin(), rows.end()) : 0;
    r.rowSumMax = n ? *std::max_element(rows.begin(), rows.end()) : 0;
    // Ray-cast rows sum to one in a closed scene by construction; the analytic ones within their
    // cubature and visibility sampling, and are scaled to it (sceneClosure).
    r.closedScene = sceneClosure(r.patches, *r.rays, kClosureRays, options.formFactors.seed).sealed;
    if (r.closedScene && !castsFormFactors(options)) {
        const double left = balanceClosedScene(r.F, r.patches.area);
        rows = rowSums(r.F);
        logInfo(
            "closed scene: the analytic form factors balanced to land all of every row's light, reciprocity "
            "kept (front-face row sums were within ",
            std::max(r.rowSumMax - 1, 1 - r.rowSumMin), " of one; all fates now within ", left, ")");
    }
    r.secondsFormFactors += ffTimer.seconds();

    // What a row sends to mirrors and glass, the transport passes on by the row's shares, scaled again
    // to the same paths whenever rows are cast again. The paths also measure each row's shares a
    // second time, weighed against the rays the row was cast with (matchSpecularShares, once F is
    // final).
    auto transport = [&](const std::vector<int>& raysFor) {
        const SceneTracer tracer(scene, r.patches, r.rays);
        SpecularSettings specular = options.specular;
        specular.seed = options.formFactors.seed;
        std::vector<double> cast;
        if (r.F.sampled) {
            const int base = stratumSide(options.formFactors.raysPerPatch);
            for (size_t i = 0; i < n; ++i)
                cast.push_back(rowRays(r.F, i, i < raysFor.size() && raysFor[i] > 0 ? stratumSide(raysFor[i]) : base));
        }
        r.system.transport =
            computeSpecularTransport(scene, r.patches, r.F, tracer, specular, &r.system.transport, cast);
        r.secondsSpecular += r.system.transport.seconds;
    };
    if (scene.hasSpecular())
        transport({});
    else
        logInfo("no mirrors or glass in the scene: no specular transport");
    checkSteadyState(scene, r.system, rows);
    if (!readings.rows.empty()) {
        // Where rays landed close, they read the light where they landed, by the slopes of a first
        // solve (ray_form_factors.h); the solve then starts again.
        Timer readTimer;
        const auto solver = makeSolver(options.solver);
        // A thousandth of the light left unshot is close enough for slopes and noise.
        SolverSettings loose = options.solverSettings;
        loose.tolerance = std::max(loose.tolerance, 1e-3);
        const std::vector<Rgb> first = solver->solve(r.F, r.system, loose, {}).B;
        std::vector<int> raysFor = raysForObjectNoise(scene, options, r, analytic, first);
        if (!raysFor.empty()) {
            const Timer more;
            castMoreRays(r.F, readings, r.patches, *r.rays, options.formFactors, analytic, emitting, raysFor);
            for (size_t i = 0; i < n; ++i) r.system.area[i] = r.patches.area[i] * double(r.F.exposed[i]);
            r.secondsFormFactors += more.seconds();
            r.secondsSolve -= more.seconds();  // counted in readTimer's too
            if (scene.hasSpecular()) {
                const Timer again;
                transport(raysFor);
                r.secondsSolve -= again.seconds();
            }
        }
        r.objectNoise = objectNoise(scene, options, r, analytic, first, raysFor);
        readLightWhereRaysLand(r.F, r.patches, readings, first, r.system.specular, r.system.reflectance);
        readings = HitReadings();
        r.secondsSolve += readTimer.seconds();
    }
    matchSpecularShares(r.F, r.system.transport);
    solveBuiltMatrix(options, observer, r);
}

// The roots with every quad that is not flat (a bilinear patch of a non-planar wall, like the Cornell
// box's) replaced by the two triangles Embree traces it as: an element's sample points then lie on
// the traced surface itself, not up to a millimetre off it and hidden behind it.
PatchSet planarRoots(const PatchSet& p) {
    PatchSet out;
    out.vertices = p.vertices;
    size_t split = 0;
    for (size_t i = 0; i < p.size(); ++i) {
        const auto& c = p.corners[i];
        const auto& id = p.cornerVertex[i];
        const Vec3 n = (c[1] - c[0]).cross(c[3] - c[0]).normalized();
        if (p.isTriangle(i) || std::abs(n.dot(c[2] - c[0])) <= 1e-7 * p.radius[i]) {
            out.add(c, p.cornerCount[i], p.object[i], id);
            continue;
        }
        ++split;
        out.add({c[0], c[1], c[3], c[3]}, 3, p.object[i], {id[0], id[1], id[3], id[3]});
        out.add({c[2], c[3], c[1], c[1]}, 3, p.object[i], {id[2], id[3], id[1], id[1]});
    }
    if (split) logDebug("hierarchy: ", split, " non-planar root quads split into their two triangles");
    return out;
}

// The hierarchy: roots meshed coarsely, elements no finer than the patches `meshing` asks for.
void solveHierarchical(const Scene& scene, const SolveOptions& options, SolveResult& r) {
    const CounterValues before = counterValues();
    Timer meshTimer;
    MeshingOptions rootMeshing;
    rootMeshing.patchesPerObject = 0;  // about --roots of them, however many objects
    // Roots no finer than the elements asked for.
    rootMeshing.targetPatches = options.meshing.patchSize > 0
                                    ? options.hierarchyRoots
                                    : std::min(options.hierarchyRoots, patchTarget(scene, options.meshing));
    const PatchSet roots = planarRoots(meshScene(scene, rootMeshing));
    HierarchySettings settings = options.hierarchy;
    settings.solver = options.solverSettings;
    settings.seed = options.formFactors.seed;
    settings.visibilityRays = options.formFactors.visibilityRays;
    settings.maxBytes = options.maxMemoryBytes > 0 ? options.maxMemoryBytes : availableMemoryBytes();
    if (!(settings.minArea > 0)) {
        const double h = options.meshing.patchSize > 0
                             ? options.meshing.patchSize / scene.metresPerUnit
                             : std::sqrt(sceneArea(scene) / patchTarget(scene, options.meshing));
        settings.minArea = h * h;
    }
    const std::shared_ptr<const RayScene> rootRays = buildRayScene(scene, roots);
    const Closure closure = sceneClosure(roots, *rootRays, kClosureRays, settings.seed);
    r.closedScene = closure.sealed;
    settings.closedScene = closure.frontOnly;
    r.secondsMeshing = meshTimer.seconds();
    HierarchyResult h = solveHierarchy(scene, roots, *rootRays, settings);
    r.hierarchy = h.stats;
    r.secondsFormFactors = h.stats.secondsLinks;
    r.secondsSolve = h.stats.secondsSolve;
    r.patches = std::move(h.leaves);
    r.rays = buildRayScene(scene, r.patches);
    r.solution = std::move(h.solution);
    r.solution.B = h.B;
    r.solution.display = std::move(h.B);
    r.power = std::move(h.power);
    logInfo("hierarchical: ", h.stats.leaves, " leaves (", h.stats.elements, " elements over ", h.stats.roots,
            " roots), ", h.stats.links, " links, ", h.stats.bytes / (1 << 20),
            " MiB (the matrix of as many patches: ", double(formFactorMatrixBytes(h.stats.leaves)) / (1 << 20),
            " MiB), ", countersSince(before)["hierarchy.visibility_rays"], " visibility rays");
    // The equation at every vertex costs vertices x leaves: past the matrix's reach, the mean.
    if (options.vertexRadiosity != "average")
        logInfo("hierarchical: displayed vertex radiosity is the mean of the patches around each vertex");
    r.corners = interpolateCorners(r.patches, r.solution.display);
}

// Whether the per-object floor (--patches-per-object) sets the default patch count: a scene of many
// objects, whose count is the small objects' floor, not a budget for the large surfaces. Grading then
// adds its patches to the uniform mesh instead of coarsening it to keep the count: the building's
// large surfaces had gone from 0.37 m to 0.74 m patches, and 140-141 of its 147 large surfaces were
// within 1% of the path-traced reference (seeds 1-3); kept at 0.37 m with 64 rays a patch, 145-146,
// in 6.0-7.0 s of stages instead of 3.9-4.7 (with 144 rays 146-147 in 9.7-9.9 s).
bool manyObjects(const Scene& scene, const SolveOptions& options) {
    return !(options.meshing.patchSize > 0) && patchTarget(scene, options.meshing) > options.meshing.targetPatches;
}

// Grades r's uniform mesh towards contacts (contact_grading.h), keeping the ray scene it builds on
// the way. --patches N asks for about N patches in all: while the graded mesh overshoots N by more
// than a tenth, the uniform mesh under it is asked for N / (graded / asked) patches instead (at most
// twice more); the closest try is kept.
void gradeMesh(const Scene& scene, const SolveOptions& options, SolveResult& r) {
    ContactGrading grading = options.grading;
    if (!(grading.minArea > 0))
        grading.minArea = std::accumulate(r.patches.area.begin(), r.patches.area.end(), 0.0) /
                          double(r.patches.size()) / std::pow(4.0, grading.levels);
    const size_t uniform = r.patches.size();
    // Every try measures in the uniform mesh's ray scene (the same geometry): one scene built, not three.
    Timer timer;
    const std::shared_ptr<const RayScene> geometry = buildRayScene(scene, r.patches);
    logDebug("contact grading: ray scene built in ", timer.seconds(), " s");
    timer = Timer();
    GradedMesh best = gradeContacts(scene, r.patches, grading, geometry);
    logDebug("contact grading: try 1 in ", timer.seconds(), " s");
    if (best.split == 0) best.rays = geometry;  // the uniform mesh itself: its scene serves the solve
    const double target = patchTarget(scene, options.meshing);
    auto miss = [&](const GradedMesh& g) { return std::abs(double(g.patches.size()) / target - 1); };
    double asked = target, got = double(best.patches.size());
    // A uniform mesh of fewer than two patches per object (the building: 13,346 for 9,553 quads at
    // --patches 3000) is about as coarse as its objects allow: asking it for fewer coarsens only its
    // large surfaces (its floors went to one 5 m^2 patch each), so it keeps its size and grows.
    const bool retry = !(options.meshing.patchSize > 0) && double(uniform) >= 2.0 * double(scene.objects.size()) &&
                       !manyObjects(scene, options);
    for (int attempt = 0; attempt < 2 && retry && got > 1.1 * target; ++attempt) {
        MeshingOptions again = options.meshing;
        asked *= target / got;
        again.targetPatches = std::max(1, int(std::lround(asked)));
        again.patchesPerObject = 0;  // `asked` holds the floor already
        timer = Timer();
        PatchSet uniformAgain = meshScene(scene, again);
        logDebug("contact grading: uniform mesh again in ", timer.seconds(), " s");
        timer = Timer();
        GradedMesh graded = gradeContacts(scene, std::move(uniformAgain), grading, geometry);
        logDebug("contact grading: try ", attempt + 2, " in ", timer.seconds(), " s");
        got = double(graded.patches.size());
        if (miss(graded) < miss(best)) best = std::move(graded);
    }
    logInfo("contact grading: ", best.split, " patches near another surface split: ", best.patches.size(),
            " patches (a uniform mesh of ", uniform, " before)");
    r.patches = std::move(best.patches);
    r.rays = std::move(best.rays);
}

// Splits r's patches where caustics fall (caustic_grading.h), down to the contact grading's smallest
// patches: a quarter of the mean patch's area per level.
void gradeCausticMesh(const Scene& scene, const SolveOptions& options, SolveResult& r) {
    CausticGrading settings = options.causticGrading;
    settings.seed = options.formFactors.seed;
    if (!(settings.minArea > 0))
        settings.minArea = std::accumulate(r.patches.area.begin(), r.patches.area.end(), 0.0) /
                           double(r.patches.size()) / std::pow(4.0, settings.levels);
    const size_t before = r.patches.size();
    const Timer timer;
    const size_t split = gradeCaustics(scene, r.patches, r.rays, settings);
    if (split > 0)
        logInfo("caustic grading: ", split, " patches lit by a caustic split: ", r.patches.size(), " patches (", before,
                " before) in ", timer.seconds(), " s");
}

// What --solver auto runs, and why.
std::string chooseSolver(const Scene& scene, const SolveOptions& options, size_t n, std::string& why) {
    const double budget = matrixBudget(options);
    const double matrix = matrixBytes(options, n);
    const double mib = double(1 << 20);
    if (scene.hasSpecular()) {
        why = "the scene has mirrors or glass, whose transport the matrix solve carries and the hierarchy does not";
        return "gauss-seidel";
    }
    if (options.refine.tolerance > 0) {
        why = "--refine subdivides the matrix solve's mesh";
        return "gauss-seidel";
    }
    if ((n <= kAutoMatrixPatches || castsFormFactors(options)) && (budget <= 0 || matrix <= 0.5 * budget)) {
        why = cat("the matrix of ", n, " patches takes ", matrix / mib, " MiB",
                  budget > 0 ? cat(" of ", budget / mib, " MiB available") : "");
        return "gauss-seidel";
    }
    why = cat("the matrix of ", n, " patches would take ", matrix / mib, " MiB",
              n > kAutoMatrixPatches && !castsFormFactors(options)
                  ? cat(" and its form factors grow as n^2 past ", kAutoMatrixPatches, " patches")
                  : " (more than half the memory)",
              "; the hierarchy's links grow about as n");
    return "hierarchical";
}

}  // namespace

std::vector<SolveSetting> solveSettings(SolveOptions& o) {
    // (0, infinity): any positive number.
    constexpr double kPositive = 0, kHuge = std::numeric_limits<double>::infinity();
    return {
        {"patches", "--patches",
         "About this many patches in all; unless given, at least four per object (a scene of many small objects "
         "leaves its large surfaces their share; with --refine: to start from, default 400)",
         1, 1e8, true, &o.meshing.targetPatches},
        {"patches_per_object", "--patches-per-object",
         "The floor of the default --patches: at least this many patches per object (kept with an explicit "
         "--patches only if given too; 0: none)",
         0, 1e6, true, &o.meshing.patchesPerObject},
        {"patch_size_m", "--patch-size", "Target patch edge length in metres (overrides --patches)", kPositive, kHuge,
         false, &o.meshing.patchSize},
        {"link_tolerance", "--link-tolerance",
         "Hierarchical: split a link while it carries more than this share of the emitted power", 1e-9, 1, true,
         &o.hierarchy.linkTolerance},
        {"roots", "--roots", "Hierarchical: the scene is meshed into about this many roots", 1, 1e6, true,
         &o.hierarchyRoots},
        {"tolerance", "--tolerance", "Stop when the unshot fraction of the emitted power falls below this", kPositive,
         kHuge, true, &o.solverSettings.tolerance},
        {"max_iterations", "--max-iterations", "Iteration cap", 1, 1e8, true, &o.solverSettings.maxIterations},
        {"visibility_rays", "--visibility-rays",
         "Visibility rays per patch pair that decide how to measure it; as many again measure it (16x as many where a "
         "shadow edge crosses the pair)",
         1, 4096, true, &o.formFactors.visibilityRays},
        {"ff_tolerance", "--ff-tolerance", "Target relative error of each unoccluded form factor", 1e-12, 1, true,
         &o.formFactors.cubature.tolerance},
        {"ff_rays", "--ff-rays",
         "--form-factors rays: rays cast from each patch (unless given: 64 where the per-object floor sets the "
         "mesh, a scene of many objects)",
         1, 1 << 24, true, &o.formFactors.raysPerPatch},
        {"ff_noise", "--ff-noise",
         "--form-factors rays: cast more rays from the patches of each object whose mean radiosity's estimated "
         "standard error is above this share of it (up to 64x --ff-rays, at most as many rays again in all, and half "
         "as many more for large surfaces to a tighter target; 1: off)",
         1e-6, 1, true, &o.formFactors.objectNoise},
        {"specular_rays", "--specular-rays",
         "Light paths per patch that sees a mirror or glass, traced from their surfaces in the solve", 1, 1 << 24, true,
         &o.specular.pathsPerPatch},
        {"specular_max_depth", "--specular-depth", "Mirror and glass bounces the solve's transport follows", 0, 1000,
         true, &o.specular.maxDepth},
        {"specular_caustics", "--specular-caustics",
         "Share of the solve's light paths traced first to find the caustics that mirrors and glass throw, which "
         "the paths then aim at too (0: the lamps alone)",
         0, 1, false, &o.specular.causticShare},
        {"specular_receivers", "--specular-receivers",
         "Share of a ball's light paths traced back from the surfaces that see it, each object as often as any other "
         "(0: every path from the ball's surface)",
         0, 0.95, false, &o.specular.receiverShare},
        {"refine", "--refine",
         "Adaptive subdivision: after each solve, split patches whose radiosity differs from a neighbour's, or whose "
         "light a shadow edge changes, by more than this fraction (e.g. 0.1)",
         1e-6, 10, false, &o.refine.tolerance},
        {"max_patches", "--max-patches", "Patch budget of --refine", 1, 1e8, true, &o.refine.maxPatches},
        {"grade_contacts", "--grade-contacts",
         "Split patches that another surface comes closer to than their width, up to this many times, before "
         "the first solve (0: off)",
         0, 8, true, &o.grading.levels},
        {"grade_caustics", "--grade-caustics",
         "Split patches where mirrors and glass focus the lamps' light (brighter than the scene's mean irradiance), "
         "up to this many times, before the first solve (0: off)",
         0, 8, true, &o.causticGrading.levels},
        {"refine_rounds", "--refine-rounds", "Most rounds of --refine", 1, 100, true, &o.refine.maxRounds},
    };
}

std::vector<SolverInfo> solverRegistry() {
    std::vector<SolverInfo> out{{"auto",
                                 "the matrix when it fits and the scene is small or has mirrors or glass, else the "
                                 "hierarchy (the log and report say which and why)"}};
    for (const std::string& name : solverNames()) out.push_back({name, solverSummary(name)});
    out.push_back({"hierarchical", "links between element quadtrees, about linear storage (diffuse scenes)"});
    return out;
}

std::vector<std::string> allSolverNames() {
    std::vector<std::string> names;
    for (const SolverInfo& s : solverRegistry()) names.push_back(s.name);
    return names;
}

namespace {

SolveResult solveUncounted(const Scene& scene, const SolveOptions& given, const StepObserver& observer) {
    SolveResult r;
    r.options = given;
    if (given.manyObjectsRays > 0 && manyObjects(scene, given) &&
        r.options.formFactors.raysPerPatch != given.manyObjectsRays) {
        r.options.formFactors.raysPerPatch = given.manyObjectsRays;
        logInfo("form factors: ", given.manyObjectsRays, " rays a patch (--ff-rays), because the floor of ",
                given.meshing.patchesPerObject, " patches per object sets the mesh of these ", scene.objects.size(),
                " objects: finer patches with fewer rays each");
    }
    const SolveOptions& options = r.options;
    const auto names = allSolverNames();
    if (std::find(names.begin(), names.end(), options.solver) == names.end()) {
        std::string known;
        for (const std::string& name : names) known += cat(known.empty() ? "" : ", ", name);
        throw Error(cat("--solver: unknown solver '", options.solver, "' (known: ", known, ")"));
    }
    r.solverName = options.solver;
    Timer meshTimer;
    if (r.solverName != "hierarchical") {
        r.patches = meshScene(scene, options.meshing);
        logDebug("meshing: uniform mesh in ", meshTimer.seconds(), " s");
        if (options.grading.levels > 0) gradeMesh(scene, options, r);
        if (options.causticGrading.levels > 0 && scene.hasSpecular()) gradeCausticMesh(scene, options, r);
    }
    r.secondsMeshing = meshTimer.seconds();
    SolveOptions matrix = options;
    if (r.solverName != "hierarchical") {
        r.formFactorMethod = options.formFactors.method;
        if (r.formFactorMethod == "auto") {
            r.formFactorMethod = chooseFormFactors(r.patches, r.formFactorReason);
            logInfo("form factors: ", r.formFactorMethod, ", because ", r.formFactorReason);
        }
        matrix.formFactors.method = r.formFactorMethod;
    }
    if (r.solverName == "auto") {
        r.solverName = chooseSolver(scene, matrix, r.patches.size(), r.solverReason);
        logInfo("solver: ", r.solverName, ", because ", r.solverReason);
    }
    if (r.solverName == "hierarchical") {
        r.formFactorMethod.clear(), r.formFactorReason.clear();  // the hierarchy makes its own links
        if (options.refine.tolerance > 0)
            throw Error(
                "--refine works on the matrix solve's mesh; the hierarchy refines itself (use one or the other)");
        solveHierarchical(scene, options, r);
        return r;
    }
    matrix.solver = r.solverName;
    solveMatrix(scene, matrix, observer, r);

    const RefineSettings& refine = options.refine;
    if (!(refine.tolerance > 0)) return r;
    // The finest patches allowed: maxLevels halvings of the first mesh's edge length.
    const double firstArea =
        std::accumulate(r.patches.area.begin(), r.patches.area.end(), 0.0) / double(r.patches.size());
    const double minArea = firstArea / std::pow(4.0, refine.maxLevels);
    r.refinement.push_back(
        {r.patches.size(), 0, 0, 0,
         r.secondsMeshing + r.secondsFormFactors + r.secondsSpecular + r.secondsSolve + r.secondsVertices});
    for (int round = 1; round <= refine.maxRounds; ++round) {
        Timer timer;
        const size_t n = r.patches.size();
        // At most a quarter of the patches per round, the worst first: each round's solve then
        // judges the patches that the last one left, so that the budget goes where light changes.
        const size_t budgetRoom = size_t(refine.maxPatches) > n ? (size_t(refine.maxPatches) - n) / 3 : 0;
        const size_t room = std::min(budgetRoom, std::max<size_t>(1, n / 4));
        SplitChoice choice =
            chooseSplits(r.patches, r.system, r.F, r.solution.B, r.corners, *r.rays, refine, minArea, room);
        const size_t chosen = size_t(std::count(choice.split.begin(), choice.split.end(), 1));
        if (chosen == 0) {
            logInfo("refinement: converged after ", round - 1,
                    " rounds: no patch differs from its neighbours by more than ", refine.tolerance,
                    (budgetRoom == 0 ? " or the patch budget is spent" : ""));
            break;
        }
        PatchSet finer = splitPatches(r.patches, choice.split);
        // Splits the 2:1 rule adds can overrun the budget: keep the strongest half until it fits.
        for (size_t want = chosen / 2; finer.size() > size_t(refine.maxPatches) && want > 0; want /= 2) {
            choice = chooseSplits(r.patches, r.system, r.F, r.solution.B, r.corners, *r.rays, refine, minArea, want);
            finer = splitPatches(r.patches, choice.split);
        }
        if (finer.size() > size_t(refine.maxPatches)) {
            logInfo("refinement: stopped: the next round would pass the budget of ", refine.maxPatches, " patches");
            break;
        }
        const size_t made = size_t(std::count(choice.split.begin(), choice.split.end(), 1));
        logInfo("refinement round ", round, ": split ", made, " of ", n, " patches (", choice.byGradient,
                " by gradient, ", choice.byShadow, " by shadow edges, ", made - std::min(made, chosen),
                " more for the 2:1 rule) -> ", finer.size(), " patches");
        r.patches = std::move(finer);
        r.rays.reset();
        r.secondsMeshing += timer.seconds();
        solveMatrix(scene, matrix, observer, r);
        r.refinement.push_back(
            {r.patches.size(), choice.byGradient, choice.byShadow, made,
             r.secondsMeshing + r.secondsFormFactors + r.secondsSpecular + r.secondsSolve + r.secondsVertices});
    }
    return r;
}

}  // namespace

std::vector<Rgb> objectRadiosity(const SolveResult& r, size_t objects) {
    std::vector<Rgb> sum(objects, Rgb::Zero());
    std::vector<double> area(objects, 0.0);
    // Where part of a patch is hidden, B holds what the rest of the scene sees of it, not its mean.
    const bool hidden = !r.F.seen.empty() && r.F.size() == r.patches.size() && r.system.size() == r.patches.size();
    const std::vector<Rgb> mean = hidden ? meanRadiosity(r.system, r.F, r.solution.B) : std::vector<Rgb>();
    for (size_t i = 0; i < r.patches.size(); ++i) {
        const size_t o = size_t(r.patches.object[i]);
        sum[o] += litArea(r, i) * (hidden ? mean[i] : r.solution.B[i]);
        area[o] += r.patches.area[i];
    }
    for (size_t o = 0; o < objects; ++o) sum[o] = area[o] > 0 ? Rgb(sum[o] / area[o]) : Rgb::Zero();
    return sum;
}

SolveResult solveScene(const Scene& scene, const SolveOptions& options, const StepObserver& observer) {
    const CounterValues before = counterValues();
    SolveResult r = solveUncounted(scene, options, observer);
    r.counters = countersSince(before);
    r.sceneFingerprint = scene.fingerprint;
    r.metresPerUnit = scene.metresPerUnit;
    return r;
}

}  // namespace penumbra
