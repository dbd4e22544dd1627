// `penumbra bench`: the speed-accuracy trade of a scene, measured. Sweeps the settings that buy
// accuracy with time (patches, form-factor rays, solver tolerance, photons and k, gather rays,
// pixel samples, and the path tracer's samples), one at a time and in combinations, and measures
// each run's stage times, peak memory, rays and error against references that do not depend on the
// setting swept: a converged path-traced image (cached on disk) and, for the solve alone, the
// finest solve of the sweep. In the same run it measures this machine's limits (Embree alone,
// memory bandwidth) and the thread scaling, so speeds are stated as ratios.
// Writes DIR/trade.csv, DIR/bench.json, DIR/summary.md, DIR/error-time.png, DIR/cost-patches.png.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "bench/limits.h"

namespace penumbra::bench {

struct BenchOptions {
    std::string scene, out;
    std::string cache;          // folder of cached reference images ("": $XDG_CACHE_HOME or ~/.cache, /penumbra)
    bool quick = false;         // a one-minute version: fewer, smaller runs
    int width = 0, height = 0;  // 0: 256 pixels wide (quick: 64), the camera's aspect
    int referenceSpp = 0;       // 0: 4096 (quick: 1024)
    uint64_t seed = 1;
    std::vector<std::string>
        only;  // non-empty: just these sweeps (and the defaults), e.g. patches,adaptive,hierarchical
};

// One setting of the sweep. `method`: "final-gather" (radiosity + final gather), "radiosity" (the
// plain radiosity view) or "path" (the path tracer); `sweep` names the setting varied.
struct Setting {
    std::string method, sweep;
    int patches = 0, visibilityRays = 0;
    double ffTolerance = 0;  // the form-factor cubature's target error
    int ffRays = 0;  // 0: the default form factors (auto); > 0: ray-cast with this many rays per patch; < 0: analytic
    double tolerance = 0;  // the solver's
    int specularRays = 0;  // rays per patch through mirrors and glass in the solve
    int64_t photons = 0;
    int photonK = 0, gatherRays = 0, spp = 0;
    double refine = 0;                    // > 0: adaptive subdivision from `patches` to this tolerance
    int refineBudget = 0;                 // and at most this many patches
    std::string solver = "gauss-seidel";  // or "hierarchical" (then `patches` sets the finest elements)
    // The form factors' noise target (--ff-noise) as `render` sets it: for final-gathered images of
    // `spp`, formFactorNoiseFor(spp); else the solve's default.
    double ffNoise() const;
    // Whether the solve makes the displayed corners the view shows, as `render` has it: a final gather
    // reads none of them where the scene has small sources (SolveOptions::forSolvedIndirectGather).
    bool displayedCorners() const { return method != "final-gather"; }
};

// What one run cost and how close it came. Seconds are wall seconds of producing the image from
// nothing: a run that reuses an earlier solve still counts that solve's stages.
struct Row {
    Setting setting;
    int patchesMade = 0;
    double meshing = 0, formFactors = 0, specular = 0, solve = 0, photons = 0, render = 0;
    double total() const { return meshing + formFactors + specular + solve + photons + render; }
    double solveTotal() const { return meshing + formFactors + specular + solve; }
    std::string formFactorMethod;  // analytic or rays (empty for the path tracer and the hierarchy)
    double peakMiB = 0;            // peak resident memory during the run's own stages
    double matrixMiB = 0;
    uint64_t links = 0;        // hierarchical: links kept
    double storageMiB = 0;     // what the solve's light transport is stored in: matrix, or elements and links
    uint64_t rays = 0;         // rays cast by the run's stages (solve + render)
    uint64_t renderRays = 0;   // of those, the final gather's render alone (photons not counted)
    double imageError = 0;     // pooled L1 after a 5x5 box blur, against the reference
    double imageErrorRaw = 0;  // per-pixel relative error after the same blur (beside it, labelled)
    double rmse = 0;
    double objectErrorMax = -1, objectErrorMean = -1;  // radiosity per object against the finest solve; -1: none
    bool pareto = false;
};

// Stage speed-up from one thread to all of them, and whether the results were identical.
struct ThreadScaling {
    std::string stage, size;
    double oneThread = 0, allThreads = 0;  // seconds
    int threads = 0;
    bool identical = false;
};

// The default solve at one seed against the path-traced per-object reference (issue 13's target:
// the whole solve in at most 0.3 s on the Cornell box, every object within 1%).
struct ObjectRun {
    uint64_t seed = 0;
    double seconds = 0;      // the solve's stages
    std::string worst;       // the object furthest from the reference
    double worstError = 0;   // |mean / reference - 1| over the channels' sum
    double worstStated = 0;  // that object's relative_error_estimate
    // Its form-factor stage: seconds, cast (nearest-hit) rays and visibility (occlusion) rays.
    double formFactorSeconds = 0, castRays = 0, visibilityRays = 0;
    // Its specular transport (scenes with mirrors or glass): seconds, and the paths' rays and bounces
    // (nearest-hit; a chord inside an exact ball is solved, not traced, and counts too).
    double transportSeconds = 0, transportRays = 0;
};

struct BenchResult {
    std::string scene, machine;
    int width = 0, height = 0, referenceSpp = 0;
    double referenceSeconds = 0;  // 0 when read from the cache
    std::vector<Row> rows;
    EmbreeLimit embree;
    BandwidthLimit bandwidth;
    std::vector<ThreadScaling> threads;
    // The form-factor and final-gather rates of the default settings, rays per second.
    // The default solve's form-factor stage: visibility (occlusion) rays and cast (nearest-hit) rays.
    double formFactorRays = 0, formFactorCastRays = 0, formFactorSeconds = 0, gatherRays = 0, gatherSeconds = 0;
    // Each object's mean radiosity by path tracing (render/object_reference.h), cached like the
    // image, to this relative standard error per object; and the default solve against it, per seed.
    double objectReferenceError = 0, objectReferenceSeconds = 0;  // seconds 0 when read from the cache
    std::vector<ObjectRun> objectRuns;
};

BenchResult runBench(const BenchOptions& options);

// The form-factor stage's rays per second over the rate Embree alone casts them at (cast rays at the
// nearest-hit rate, visibility rays at the occlusion rate): the median over the default solves of
// the per-object runs (warm: the first solve of a process also pays for first touches), else the
// final gather's default solve. `runs` 0 when neither was measured.
struct StageRatio {
    double median = 0, low = 0, high = 0, castRays = 0, visibilityRays = 0, seconds = 0;
    size_t runs = 0;
};
StageRatio formFactorRatio(const BenchResult& result);
// The specular transport's rays per second over Embree's nearest-hit rate, likewise (castRays: its
// rays); `runs` 0 on a scene without mirrors or glass.
StageRatio transportRatio(const BenchResult& result);

// A setting in a few words ("1000 patches, 8 spp, 16 gather rays"): what differs from the defaults.
std::string settingText(const Setting& s);

// Files from a result (summary.cpp): trade.csv, bench.json, summary.md and the plots.
void markPareto(std::vector<Row>& rows);
std::string tradeCsv(const std::vector<Row>& rows);
std::string summaryMarkdown(const BenchResult& result);
std::string benchJson(const BenchResult& result);
// Writes the gnuplot script and runs it; returns false (after a warning) when gnuplot is missing.
bool writePlots(const BenchResult& result, const std::string& dir);

}  // namespace penumbra::bench
