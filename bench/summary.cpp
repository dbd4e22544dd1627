// The files of `penumbra bench`: trade.csv (one line a run), bench.json (limits, thread scaling,
// targets), summary.md (the tables, for the docs) and the plots through gnuplot.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>

#include "bench/trade.h"
#include "core/error.h"
#include "core/log.h"
#include "io/atomic_file.h"
#include "render/final_gather.h"
#include "render/photon_map.h"
#include "solver/solve.h"

namespace penumbra::bench {
namespace {

const char* methodTitle(const std::string& method) {
    if (method == "final-gather") return "radiosity + final gather";
    if (method == "radiosity") return "radiosity alone";
    return "path tracing";
}

std::string fixed(double v, int digits) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", digits, v);
    return buf;
}
std::string percent(double v) { return fixed(100 * v, v < 0.1 ? 2 : 1) + "%"; }

// The cheapest run of a method (any if empty) whose error is at most `limit`.
const Row* cheapest(const std::vector<Row>& rows, const std::string& method, double limit) {
    const Row* best = nullptr;
    for (const Row& r : rows)
        if ((method.empty() || r.setting.method == method) && r.imageError <= limit &&
            (!best || r.total() < best->total()))
            best = &r;
    return best;
}

// error = a * seconds^b fitted to the path tracer's runs (log-log least squares).
struct PowerFit {
    double a = 0, b = 0;
    bool ok = false;
    double secondsFor(double error) const { return std::pow(error / a, 1 / b); }
};
PowerFit fitPath(const std::vector<Row>& rows) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    int n = 0;
    for (const Row& r : rows)
        if (r.setting.method == "path" && r.imageError > 0 && r.total() > 0) {
            const double x = std::log(r.total()), y = std::log(r.imageError);
            sx += x, sy += y, sxx += x * x, sxy += x * y, ++n;
        }
    PowerFit f;
    if (n < 2 || sxx * n - sx * sx <= 0) return f;
    f.b = (n * sxy - sx * sy) / (n * sxx - sx * sx);
    f.a = std::exp((sy - f.b * sx) / n);
    f.ok = f.b < 0;
    return f;
}

// Seconds the path tracer needs for `error` on this image: between the two runs that bracket it,
// interpolated on log-log axes (its error falls as a power of the time); from the fit past the
// last run; measured when the cheapest run already gets there.
struct PathTime {
    double seconds = 0;
    bool known = false;
    const char* how = "";
};
PathTime pathTimeFor(const std::vector<Row>& rows, double error) {
    std::vector<const Row*> path;
    for (const Row& r : rows)
        if (r.setting.method == "path") path.push_back(&r);
    std::sort(path.begin(), path.end(), [](const Row* a, const Row* b) { return a->total() < b->total(); });
    for (size_t k = 0; k < path.size(); ++k) {
        if (path[k]->imageError > error) continue;
        if (k == 0) return {path[k]->total(), true, "measured"};
        const Row &a = *path[k - 1], &b = *path[k];
        const double slope = std::log(b.imageError / a.imageError) / std::log(b.total() / a.total());
        return {a.total() * std::pow(error / a.imageError, 1 / slope), true, "interpolated between its runs"};
    }
    const PowerFit f = fitPath(rows);
    if (!f.ok) return {};
    return {f.secondsFor(error), true, "extrapolated by the fit"};
}

// The reference image's own error, from the path run with the most samples N against the reference
// of R samples: err^2 = e_N^2 + e_R^2 with e_N^2 = e_R^2 R / N (variance falls as 1/samples).
double referenceNoise(const BenchResult& r) {
    const Row* most = nullptr;
    for (const Row& x : r.rows)
        if (x.setting.method == "path" && (!most || x.setting.spp > most->setting.spp)) most = &x;
    if (!most) return 0;
    const double ratio = double(r.referenceSpp) / most->setting.spp;
    return most->imageError / std::sqrt(ratio + 1);
}

struct Targets {
    double error = 0.02;
    const Row* gather = nullptr;  // cheapest final gather at `error`
    PathTime path;
    const Row* orbit = nullptr;  // cheapest view of either kind at `error` for 36 views (solve once)
    double orbitSeconds = 0, orbitPathSeconds = 0;
    const Row* view = nullptr;  // the radiosity view of the default solve
};
Targets targetsOf(const BenchResult& r, double error) {
    Targets t;
    t.error = error;
    t.gather = cheapest(r.rows, "final-gather", t.error);
    t.path = pathTimeFor(r.rows, t.error);
    for (const Row& row : r.rows) {
        if (row.setting.method == "path" || row.imageError > t.error) continue;
        const double cost = row.solveTotal() + row.photons + 36 * row.render;
        if (!t.orbit || cost < t.orbitSeconds) t.orbit = &row, t.orbitSeconds = cost;
    }
    t.orbitPathSeconds = 36 * t.path.seconds;
    for (const Row& row : r.rows)
        if (row.setting.method == "radiosity" && row.setting.sweep == "default") t.view = &row;
    return t;
}

}  // namespace

std::string settingText(const Setting& s) {
    if (s.method == "path") return cat(s.spp, " spp");
    std::string t = s.solver == "hierarchical" ? cat("hierarchical, finest as ", s.patches, " patches")
                    : s.refine > 0
                        ? cat("adaptive from ", s.patches, " patches to ", s.refine, ", at most ", s.refineBudget)
                        : cat(s.patches, " patches");
    if (s.visibilityRays != FormFactorSettings{}.visibilityRays) t += cat(", ", s.visibilityRays, " vis. rays");
    if (s.ffRays > 0)
        t += cat(", ray-cast FF ", s.ffRays, " rays");
    else if (s.ffRays < 0)
        t += cat(", analytic FF", s.ffTolerance != CubatureSettings{}.tolerance ? cat(" tol ", s.ffTolerance) : "");
    if (s.tolerance != SolverSettings{}.tolerance) t += cat(", tol ", s.tolerance);
    if (s.ffNoise() != FormFactorSettings{}.objectNoise) t += cat(", ff-noise ", s.ffNoise());
    if (s.specularRays != SpecularSettings{}.pathsPerPatch && s.method != "path")
        t += cat(", ", s.specularRays, " specular rays");
    t += cat(", ", s.spp, " spp");
    if (s.method == "final-gather") {
        // The default path reads the solve's indirect light and casts no gather rays: named only when
        // set (where the solve holds no indirect light, the gather casts them).
        if (s.gatherRays != GatherSettings{}.gatherRays) t += cat(", ", s.gatherRays, " gather rays");
        if (s.photons != PhotonSettings{}.photons) t += cat(", ", s.photons, " photons");
        if (s.photonK != PhotonSettings{}.nearest) t += cat(", k ", s.photonK);
    }
    return t;
}

void markPareto(std::vector<Row>& rows) {
    for (Row& r : rows) {
        r.pareto = true;
        for (const Row& o : rows)
            if (&o != &r && o.total() <= r.total() && o.imageError <= r.imageError &&
                (o.total() < r.total() || o.imageError < r.imageError)) {
                r.pareto = false;
                break;
            }
    }
}

std::string tradeCsv(const std::vector<Row>& rows) {
    std::string csv =
        "method,sweep,patches_asked,patches,form_factors,visibility_rays,ff_tolerance,ff_rays,tolerance,specular_rays,"
        "photons,"
        "photon_k,"
        "gather_rays,spp,"
        "seconds_meshing,seconds_form_factors,seconds_specular,seconds_solve,seconds_photons,seconds_render,"
        "seconds_total,peak_memory_mib,matrix_mib,rays,pooled_l1_blurred,per_pixel_relative_blurred,rmse,"
        "object_error_max,object_error_mean,pareto\n";
    auto opt = [](double v) { return v < 0 ? std::string() : cat(v); };
    for (const Row& r : rows) {
        const Setting& s = r.setting;
        const bool path = s.method == "path";
        csv += cat(s.method, ",", s.sweep, ",", path ? "" : cat(s.patches), ",", r.patchesMade, ",", r.formFactorMethod,
                   ",", path ? "" : cat(s.visibilityRays), ",", path ? "" : cat(s.ffTolerance), ",",
                   path || s.ffRays <= 0 ? "" : cat(s.ffRays), ",", path ? "" : cat(s.tolerance), ",",
                   path ? "" : cat(s.specularRays), ",", s.method == "final-gather" ? cat(s.photons) : "", ",",
                   s.method == "final-gather" ? cat(s.photonK) : "", ",",
                   s.method == "final-gather" ? cat(s.gatherRays) : "", ",", s.spp, ",", r.meshing, ",", r.formFactors,
                   ",", r.specular, ",", r.solve, ",", r.photons, ",", r.render, ",", r.total(), ",", r.peakMiB, ",",
                   r.matrixMiB, ",", r.rays, ",", r.imageError, ",", r.imageErrorRaw, ",", r.rmse, ",",
                   opt(r.objectErrorMax), ",", opt(r.objectErrorMean), ",", r.pareto ? 1 : 0, "\n");
    }
    return csv;
}

// The radiosity views of one mesh kind: the uniform patch sweep, adaptive subdivision or the
// hierarchy, by patch count.
std::vector<const Row*> meshRows(const std::vector<Row>& rows, const std::string& kind) {
    std::vector<const Row*> out;
    for (const Row& x : rows) {
        if (x.setting.method != "radiosity") continue;
        const bool uniform = x.setting.sweep == "patches" || x.setting.sweep == "default";
        if ((kind == "uniform" && uniform) || x.setting.sweep == kind) out.push_back(&x);
    }
    std::sort(out.begin(), out.end(), [](const Row* a, const Row* b) { return a->patchesMade < b->patchesMade; });
    return out;
}

// Patches a uniform mesh needs for `error`: log-log between the two uniform runs around it.
double uniformPatchesFor(const std::vector<const Row*>& uniform, double error) {
    for (size_t k = 1; k < uniform.size(); ++k) {
        const Row &a = *uniform[k - 1], &b = *uniform[k];
        if ((a.imageError - error) * (b.imageError - error) <= 0 && a.imageError != b.imageError) {
            const double t = std::log(error / a.imageError) / std::log(b.imageError / a.imageError);
            return std::exp(std::log(double(a.patchesMade)) + t * std::log(double(b.patchesMade) / a.patchesMade));
        }
    }
    return -1;  // outside the uniform sweep
}

std::string meshesMarkdown(const std::vector<Row>& rows) {
    const auto uniform = meshRows(rows, "uniform");
    std::string md =
        "\n## Model only what the light needs: uniform, adaptive and hierarchical meshes\n\n"
        "Radiosity views. *Uniform patches for this error*: the uniform sweep interpolated on log-log "
        "axes; the ratio is how many times fewer patches (elements) this mesh needed.\n\n"
        "![error against patches](meshes.png) ![storage against patches](storage.png)\n\n"
        "| mesh | setting | patches / leaves | seconds | error | uniform patches for this error | ratio | "
        "storage MiB | links |\n|---|---|---|---|---|---|---|---|---|\n";
    for (const char* kind : {"uniform", "adaptive", "hierarchical"})
        for (const Row* x : meshRows(rows, kind)) {
            const double u = std::string(kind) == "uniform" ? -1 : uniformPatchesFor(uniform, x->imageError);
            md += cat("| ", kind, " | ", settingText(x->setting), " | ", x->patchesMade, " | ", fixed(x->total(), 2),
                      " | ", percent(x->imageError), " | ", u > 0 ? cat(std::lround(u)) : "-", " | ",
                      u > 0 ? cat(fixed(u / x->patchesMade, 2), "x") : "-", " | ", fixed(x->storageMiB, 2), " | ",
                      x->links ? cat(x->links) : "-", " |\n");
        }
    return md;
}

namespace {
// Seconds Embree alone would take for a stage's rays: cast rays at its nearest-hit rate, visibility
// rays at its occlusion rate.
double embreeAloneSeconds(double castRays, double visibilityRays, const EmbreeLimit& e) {
    return castRays / e.intersect1 + visibilityRays / e.occluded1;
}
}  // namespace

StageRatio formFactorRatio(const BenchResult& r) {
    const EmbreeLimit& e = r.embree;
    struct Run {
        double ratio, cast, visibility, seconds;
    };
    std::vector<Run> runs;
    for (const ObjectRun& o : r.objectRuns)
        if (o.formFactorSeconds > 0) runs.push_back({0, o.castRays, o.visibilityRays, o.formFactorSeconds});
    if (runs.empty() && r.formFactorSeconds > 0)
        runs.push_back({0, r.formFactorCastRays, r.formFactorRays, r.formFactorSeconds});
    StageRatio out;
    if (runs.empty() || !(e.intersect1 > 0) || !(e.occluded1 > 0)) return out;
    for (Run& k : runs) k.ratio = embreeAloneSeconds(k.cast, k.visibility, e) / k.seconds;
    std::sort(runs.begin(), runs.end(), [](const Run& a, const Run& b) { return a.ratio < b.ratio; });
    const Run& m = runs[runs.size() / 2];
    out.median = m.ratio, out.low = runs.front().ratio, out.high = runs.back().ratio;
    out.castRays = m.cast, out.visibilityRays = m.visibility, out.seconds = m.seconds;
    out.runs = runs.size();
    return out;
}

StageRatio transportRatio(const BenchResult& r) {
    std::vector<std::pair<double, const ObjectRun*>> runs;
    for (const ObjectRun& o : r.objectRuns)
        if (o.transportSeconds > 0 && o.transportRays > 0 && r.embree.intersect1 > 0)
            runs.emplace_back(o.transportRays / o.transportSeconds / r.embree.intersect1, &o);
    StageRatio out;
    if (runs.empty()) return out;
    std::sort(runs.begin(), runs.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    const auto& [ratio, m] = runs[runs.size() / 2];
    out.median = ratio, out.low = runs.front().first, out.high = runs.back().first;
    out.castRays = m->transportRays, out.seconds = m->transportSeconds;
    out.runs = runs.size();
    return out;
}

std::string summaryMarkdown(const BenchResult& r) {
    std::string md =
        cat("# Bench: ", r.scene, "\n\nMachine: ", r.machine, ". Images ", r.width, "x", r.height,
            "; reference: the path tracer at ", r.referenceSpp, " spp",
            r.referenceSeconds > 0 ? cat(" (", fixed(r.referenceSeconds, 1), " s)") : std::string(" (from the cache)"),
            ". Error: pooled L1 after a 5x5 box blur, sum |blur(image) - blur(reference)| / sum blur(reference) over "
            "all pixels and channels. Seconds: wall "
            "seconds from the scene file to the image.\n\n![error against time](error-time.png)\n"
            "![cost against patches](cost-patches.png)\n\n");
    md +=
        "## Settings that reach 10%, 3% and 1% error\n\n| error | method | cheapest setting that reaches it | seconds "
        "| error |\n|---|---|---|---|---|\n";
    for (double limit : {0.10, 0.03, 0.01})
        for (const char* method : {"final-gather", "radiosity", "path"}) {
            const Row* row = cheapest(r.rows, method, limit);
            if (row) {
                md += cat("| ", percent(limit), " | ", methodTitle(method), " | ", settingText(row->setting), " | ",
                          fixed(row->total(), 2), " | ", percent(row->imageError), " |\n");
            } else if (std::string(method) == "path" && pathTimeFor(r.rows, limit).known) {
                md += cat("| ", percent(limit), " | ", methodTitle(method), " | not reached; extrapolated | ",
                          fixed(pathTimeFor(r.rows, limit).seconds, 1), " (fit) | |\n");
            } else {
                double best = 1e300;
                for (const Row& x : r.rows)
                    if (x.setting.method == method) best = std::min(best, x.imageError);
                md += cat("| ", percent(limit), " | ", methodTitle(method), " | not reached (best ",
                          best < 1e300 ? percent(best) : "-", ") | | |\n");
            }
        }

    const PowerFit fit = fitPath(r.rows);
    md += "\n## Targets: one image, and 36 views, sooner than the path tracer\n\n";
    if (fit.ok)
        md += cat("Path tracer: error = ", fixed(fit.a, 4), " x seconds^", fixed(fit.b, 3),
                  " fitted over its runs (the Monte Carlo rate is ^-0.5).\n\n");
    if (const double noise = referenceNoise(r); noise > 0)
        md += cat("The reference's own noise is about ", percent(noise),
                  " (the error of the path tracer's most sampled run, which has noise independent of the reference's, "
                  "taken apart by the 1/samples law of variances): errors near it are at the floor this reference can "
                  "see.\n\n");
    // Issue 14: one image at 2% (cornell-glass), 1% and 0.5% (the Cornell box), and 36 views at 1%.
    for (const double error : {0.02, 0.01, 0.005}) {
        const Targets e = targetsOf(r, error);
        if (e.gather && e.path.known)
            md += cat("- One image at ", percent(error), ": radiosity + final gather ", fixed(e.gather->total(), 2),
                      " s (", settingText(e.gather->setting), ", error ", percent(e.gather->imageError),
                      "); path tracer ", fixed(e.path.seconds, 1), " s (", e.path.how, "): **",
                      fixed(e.path.seconds / e.gather->total(), 1), "x sooner**.\n");
        else
            md += cat("- One image at ", percent(error), ": the final gather did not reach it in this sweep.\n");
        if (e.orbit && e.path.known)
            md += cat("- 36 views at ", percent(error), ": one solve + photons + 36 views = ", fixed(e.orbitSeconds, 1),
                      " s (", methodTitle(e.orbit->setting.method), ", ", settingText(e.orbit->setting), ", ",
                      fixed(e.orbit->render, 3), " s a view); the path tracer ", fixed(e.orbitPathSeconds, 1),
                      " s: ratio **", fixed(e.orbitSeconds / e.orbitPathSeconds, 3),
                      "** (issue 14: at most 0.05 at 1%).\n");
    }
    const Targets t = targetsOf(r, 0.02);
    if (t.view)
        md += cat("- A new viewpoint of the radiosity solution: ", fixed(t.view->render, 3), " s against the solve's ",
                  fixed(t.view->solveTotal(), 2), " s: **", percent(t.view->render / t.view->solveTotal()),
                  "** of it (target under 1%).\n");

    if (!r.objectRuns.empty()) {
        double worst = 0, slowest = 0;
        std::vector<double> seconds;
        for (const ObjectRun& o : r.objectRuns) {
            worst = std::max(worst, o.worstError);
            slowest = std::max(slowest, o.seconds);
            seconds.push_back(o.seconds);
        }
        std::sort(seconds.begin(), seconds.end());
        md += cat(
            "- The default solve against each object's path-traced mean (", percent(r.objectReferenceError),
            " standard error per object",
            r.objectReferenceSeconds > 0 ? cat(", ", fixed(r.objectReferenceSeconds, 1), " s") : ", from the cache",
            ") over ", r.objectRuns.size(), " seeds: worst object **", percent(worst), "** (target within 1%), stages ",
            fixed(seconds.front(), 3), "-", fixed(slowest, 3), " s, median **", fixed(seconds[seconds.size() / 2], 3),
            " s** (target at most 0.3 s on the Cornell box).\n\n"
            "| seed | stages (s) | worst object | its error | its stated noise |\n|---|---|---|---|---|\n");
        for (const ObjectRun& o : r.objectRuns)
            md += cat("| ", o.seed, " | ", fixed(o.seconds, 3), " | ", o.worst, " | ", percent(o.worstError), " | ",
                      percent(o.worstStated), " |\n");
    }

    const EmbreeLimit& e = r.embree;
    const BandwidthLimit& b = r.bandwidth;
    md +=
        cat("\n## Close to the limit\n\nEmbree alone on the same patches and ", e.threads, " threads (", e.rays,
            " rays each, made before the clock starts); memory on a ", b.n, "^2 float matrix (",
            fixed(b.matrixBytes / (1 << 20), 0), " MiB).\n\n| stage | measured | limit | ratio |\n|---|---|---|---|\n");
    if (const StageRatio f = formFactorRatio(r); f.runs > 0) {
        const double rays = f.castRays + f.visibilityRays;
        md += cat("| form factors (rays / stage seconds: ", fixed(f.castRays / 1e6, 2), " M cast, ",
                  fixed(f.visibilityRays / 1e6, 2), " M visibility",
                  f.runs > 1 ? cat("; median of ", f.runs, " default solves, ", percent(f.low), "-", percent(f.high))
                             : std::string(),
                  ") | ", fixed(rays / f.seconds / 1e6, 2),
                  " M rays/s | Embree alone: ", fixed(rays / f.seconds / f.median / 1e6, 2), " M rays/s | ",
                  percent(f.median), " |\n");
        if (f.runs > 1 && r.formFactorSeconds > 0) {
            // The process's first solve also pays for first touches of its memory (page faults).
            const double alone = embreeAloneSeconds(r.formFactorCastRays, r.formFactorRays, e);
            md += cat("| form factors, the process's first solve (cold) | ",
                      fixed((r.formFactorCastRays + r.formFactorRays) / r.formFactorSeconds / 1e6, 2), " M rays/s | | ",
                      percent(alone / r.formFactorSeconds), " |\n");
        }
    }
    if (const StageRatio tr = transportRatio(r); tr.runs > 0)
        md += cat("| specular transport (the paths' rays and bounces / stage seconds: ", fixed(tr.castRays / 1e6, 2),
                  " M; median of ", tr.runs, " default solves, ", percent(tr.low), "-", percent(tr.high), ") | ",
                  fixed(tr.castRays / tr.seconds / 1e6, 2), " M rays/s | Embree nearest hit ",
                  fixed(r.embree.intersect1 / 1e6, 2), " M rays/s | ", percent(tr.median), " |\n");
    if (r.gatherSeconds > 0)
        md += cat("| final gather (rays / render seconds) | ", fixed(r.gatherRays / r.gatherSeconds / 1e6, 2),
                  " M rays/s | Embree nearest hit ", fixed(e.intersect1 / 1e6, 2), " M rays/s | ",
                  percent(r.gatherRays / r.gatherSeconds / e.intersect1), " |\n");
    md += cat("| Embree 8-wide packets against single rays (occlusion) | ", fixed(e.occluded8 / 1e6, 2), " M rays/s | ",
              fixed(e.occluded1 / 1e6, 2), " M rays/s | ", fixed(e.occluded8 / e.occluded1, 2), "x |\n");
    md += cat("| Jacobi sweep (", b.threads, " threads) | ", fixed(b.jacobiGBs, 1), " GB/s (",
              fixed(b.jacobiSeconds * 1e3, 1), " ms) | read stream ", fixed(b.readGBs, 1), " GB/s | ",
              percent(b.jacobiGBs / b.readGBs), " |\n");
    md += cat("| Jacobi sweep against a copy | | copy ", fixed(b.copyGBs, 1), " GB/s | ",
              percent(b.jacobiGBs / b.copyGBs), " |\n");
    md += cat("| Gauss-Seidel sweep (1 thread, sequential) | ", fixed(b.gaussSeidelGBs, 1), " GB/s (",
              fixed(b.gaussSeidelSeconds * 1e3, 1), " ms) | read stream on 1 thread ", fixed(b.readGBs1, 1), " GB/s | ",
              percent(b.gaussSeidelGBs / b.readGBs1), " |\n");

    md += meshesMarkdown(r.rows);

    md +=
        "\n## Threads\n\n| stage | size | 1 thread (s) | all threads (s) | speed-up | results identical "
        "|\n|---|---|---|---|---|---|\n";
    for (const ThreadScaling& s : r.threads)
        md += cat("| ", s.stage, " | ", s.size, " | ", fixed(s.oneThread, 2), " | ", fixed(s.allThreads, 2), " (",
                  s.threads, ") | ", fixed(s.oneThread / s.allThreads, 2), "x | ", s.identical ? "yes" : "**no**",
                  " |\n");

    md +=
        "\n## Runs\n\n| method | swept | setting | patches | mesh + FF + specular + solve (s) | photons (s) | render "
        "(s) | "
        "total (s) | peak MiB | rays | error | object error (max) | Pareto "
        "|\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const Row& x : r.rows)
        md += cat("| ", methodTitle(x.setting.method), " | ", x.setting.sweep, " | ", settingText(x.setting), " | ",
                  x.patchesMade, " | ", fixed(x.solveTotal(), 2), " | ", fixed(x.photons, 2), " | ", fixed(x.render, 2),
                  " | ", fixed(x.total(), 2), " | ", fixed(x.peakMiB, 0), " | ", x.rays, " | ", percent(x.imageError),
                  " | ", x.objectErrorMax < 0 ? "-" : percent(x.objectErrorMax), " | ", x.pareto ? "yes" : "", " |\n");
    return md;
}

std::string benchJson(const BenchResult& r) {
    using Json = nlohmann::json;
    const Targets t = targetsOf(r, 0.02);
    Json j;
    j["scene"] = r.scene;
    j["machine"] = r.machine;
    j["resolution"] = {r.width, r.height};
    j["reference_spp"] = r.referenceSpp;
    j["embree"] = {{"threads", r.embree.threads},
                   {"rays", r.embree.rays},
                   {"occluded1_rays_per_s", r.embree.occluded1},
                   {"occluded8_rays_per_s", r.embree.occluded8},
                   {"intersect1_rays_per_s", r.embree.intersect1}};
    const BandwidthLimit& b = r.bandwidth;
    j["bandwidth"] = {{"n", b.n},
                      {"threads", b.threads},
                      {"read_gb_per_s", b.readGBs},
                      {"read_gb_per_s_one_thread", b.readGBs1},
                      {"copy_gb_per_s", b.copyGBs},
                      {"jacobi_gb_per_s", b.jacobiGBs},
                      {"gauss_seidel_gb_per_s", b.gaussSeidelGBs},
                      {"jacobi_over_read", b.jacobiGBs / b.readGBs}};
    if (const StageRatio f = formFactorRatio(r); f.runs > 0)
        j["form_factors"] = {{"rays", f.visibilityRays},   {"cast_rays", f.castRays},
                             {"seconds", f.seconds},       {"rays_per_s", (f.visibilityRays + f.castRays) / f.seconds},
                             {"over_embree", f.median},    {"over_embree_low", f.low},
                             {"over_embree_high", f.high}, {"solves", f.runs}};
    if (const StageRatio tr = transportRatio(r); tr.runs > 0)
        j["specular_transport"] = {
            {"rays", tr.castRays},      {"seconds", tr.seconds},     {"rays_per_s", tr.castRays / tr.seconds},
            {"over_embree", tr.median}, {"over_embree_low", tr.low}, {"over_embree_high", tr.high},
            {"solves", tr.runs}};
    if (r.gatherSeconds > 0)
        j["final_gather"] = {{"rays", r.gatherRays},
                             {"seconds", r.gatherSeconds},
                             {"rays_per_s", r.gatherRays / r.gatherSeconds},
                             {"over_embree", r.gatherRays / r.gatherSeconds / r.embree.intersect1}};
    Json threads = Json::array();
    for (const ThreadScaling& s : r.threads)
        threads.push_back({{"stage", s.stage},
                           {"size", s.size},
                           {"one_thread_s", s.oneThread},
                           {"all_threads_s", s.allThreads},
                           {"threads", s.threads},
                           {"speedup", s.oneThread / s.allThreads},
                           {"identical", s.identical}});
    j["threads"] = threads;
    Json targets;
    targets["error"] = t.error;
    if (t.gather) targets["final_gather_seconds"] = t.gather->total();
    if (t.path.known) targets["path_seconds"] = t.path.seconds, targets["path_seconds_how"] = t.path.how;
    if (t.gather && t.path.known) targets["speedup"] = t.path.seconds / t.gather->total();
    if (t.orbit && t.path.known) targets["orbit36_ratio"] = t.orbitSeconds / t.orbitPathSeconds;
    if (t.view) targets["radiosity_view_over_solve"] = t.view->render / t.view->solveTotal();
    targets["reference_noise"] = referenceNoise(r);
    // Issue 14's errors: one image and 36 views at each, against the path tracer.
    Json byError = Json::array();
    for (const double error : {0.02, 0.01, 0.005}) {
        const Targets e = targetsOf(r, error);
        Json x;
        x["error"] = error;
        if (e.gather) x["final_gather_seconds"] = e.gather->total(), x["final_gather_error"] = e.gather->imageError;
        if (e.path.known) x["path_seconds"] = e.path.seconds, x["path_seconds_how"] = e.path.how;
        if (e.gather && e.path.known) x["speedup"] = e.path.seconds / e.gather->total();
        if (e.orbit && e.path.known) x["orbit36_ratio"] = e.orbitSeconds / e.orbitPathSeconds;
        byError.push_back(x);
    }
    targets["by_error"] = byError;
    if (!r.objectRuns.empty()) {
        Json runs = Json::array();
        for (const ObjectRun& o : r.objectRuns)
            runs.push_back({{"seed", o.seed},
                            {"seconds", o.seconds},
                            {"worst_object", o.worst},
                            {"worst_error", o.worstError},
                            {"worst_stated_noise", o.worstStated}});
        targets["objects_against_path_traced"] = {{"reference_error", r.objectReferenceError}, {"runs", runs}};
    }
    j["targets"] = targets;
    return j.dump(2) + "\n";
}

bool writePlots(const BenchResult& r, const std::string& dir) {
    const std::filesystem::path d(dir);
    const std::filesystem::path data = d / "plot-data";
    ensureDirectory(data.string());
    // (seconds, error) of the runs that pass `keep`, in order of time.
    auto points = [&](const auto& keep) {
        std::vector<const Row*> rows;
        for (const Row& x : r.rows)
            if (keep(x)) rows.push_back(&x);
        std::sort(rows.begin(), rows.end(), [](const Row* a, const Row* b) { return a->total() < b->total(); });
        std::string text = "# seconds_total pooled_l1_blurred\n";
        for (const Row* x : rows) text += cat(x->total(), " ", x->imageError, "\n");
        return text;
    };
    for (const char* method : {"final-gather", "radiosity", "path"})
        writeFileAtomic((data / cat(method, ".dat")).string(),
                        points([&](const Row& x) { return x.setting.method == method; }));
    writeFileAtomic((data / "pareto.dat").string(), points([](const Row& x) { return x.pareto; }));
    // The cost of the solve against the patch count: the radiosity runs of the patch sweep.
    std::vector<const Row*> solves;
    for (const Row& x : r.rows)
        if (x.setting.method == "radiosity" && (x.setting.sweep == "patches" || x.setting.sweep == "default"))
            solves.push_back(&x);
    std::sort(solves.begin(), solves.end(), [](const Row* a, const Row* b) { return a->patchesMade < b->patchesMade; });
    std::string cost = "# patches seconds_form_factors seconds_solve peak_memory_mib matrix_mib\n";
    for (const Row* x : solves)
        cost += cat(x->patchesMade, " ", x->formFactors, " ", x->solve, " ", x->peakMiB, " ", x->matrixMiB, "\n");
    writeFileAtomic((data / "cost.dat").string(), cost);
    for (const char* kind : {"uniform", "adaptive", "hierarchical"}) {
        std::string text = "# patches seconds_total pooled_l1_blurred storage_mib links\n";
        for (const Row* x : meshRows(r.rows, kind))
            text += cat(x->patchesMade, " ", x->total(), " ", x->imageError, " ", x->storageMiB, " ", x->links, "\n");
        writeFileAtomic((data / cat("mesh-", kind, ".dat")).string(), text);
    }
    const double nMax = solves.empty() ? 1 : solves.back()->patchesMade;
    const double c = solves.empty() ? 0 : solves.back()->formFactors / (nMax * nMax);

    const std::string script = cat(
        "# Made by penumbra bench; run from this folder: gnuplot plots.gp\n"
        "set terminal pngcairo size 960,640 enhanced font 'sans,11'\n"
        "set output 'error-time.png'\n"
        "set logscale xy\nset grid\nset key top right box opaque\n"
        "set xlabel 'wall seconds, scene file to image (",
        r.machine,
        ")'\n"
        "set ylabel 'pooled L1 after a 5x5 blur'\n"
        "set format y '%g'\n"
        "set title \"",
        r.scene, ": error against time at ", r.width, "x", r.height, " (reference: path tracer, ", r.referenceSpp,
        " spp)\" noenhanced\n",
        "plot 'plot-data/final-gather.dat' using 1:2 with points pt 7 ps 1.2 lc rgb '#d95f02' title 'radiosity + final "
        "gather', \\\n"
        "     'plot-data/radiosity.dat' using 1:2 with points pt 5 ps 1.0 lc rgb '#1b9e77' title 'radiosity alone', "
        "\\\n"
        "     'plot-data/path.dat' using 1:2 with linespoints pt 9 ps 1.2 lw 1.5 lc rgb '#7570b3' title 'path "
        "tracing', \\\n"
        "     'plot-data/pareto.dat' using 1:2 with steps lw 2.5 dt 2 lc rgb 'black' title 'Pareto front (all "
        "methods)', \\\n"
        "     'plot-data/pareto.dat' using 1:2 with points pt 6 ps 2 lw 1.5 lc rgb 'black' notitle\n"
        "set output 'cost-patches.png'\n"
        "set title \"",
        r.scene,
        ": cost of the matrix solve against the patch count\" noenhanced\n"
        "set xlabel 'patches'\nset ylabel 'wall seconds'\nset y2label 'MiB'\n"
        "set logscale y2\nset y2tics\nset ytics nomirror\nset key bottom right box opaque\n"
        "plot 'plot-data/cost.dat' using 1:2 with linespoints pt 7 lw 2 lc rgb '#d95f02' title 'form factors (s)', \\\n"
        "     'plot-data/cost.dat' using 1:3 with linespoints pt 5 lw 2 lc rgb '#1b9e77' title 'solve (s)', \\\n"
        "     'plot-data/cost.dat' using 1:4 axes x1y2 with linespoints pt 9 lw 2 lc rgb '#7570b3' title 'peak memory "
        "(MiB, right)', \\\n"
        "     'plot-data/cost.dat' using 1:5 axes x1y2 with linespoints pt 4 dt 3 lc rgb '#e7298a' title 'matrix n^2 x "
        "4 bytes (MiB, right)', \\\n"
        "     [x=50:",
        nMax * 1.5, "] ", c,
        " * x**2 with lines dt 2 lc rgb 'gray40' title 'n^2 through the largest form-factor time'\n"
        "unset y2label\nunset y2tics\nunset logscale y2\nset ytics mirror\n"
        "set output 'meshes.png'\n"
        "set title \"",
        r.scene, ": radiosity view error against patches (", r.machine,
        ")\" noenhanced\n"
        "set logscale xy\nset xlabel 'patches (hierarchy: leaves)'\nset ylabel 'pooled L1 after a 5x5 blur'\n"
        "set key top right box opaque\n"
        "plot 'plot-data/mesh-uniform.dat' using 1:3 with linespoints pt 7 lw 2 lc rgb '#7570b3' title 'uniform', \\\n"
        "     'plot-data/mesh-adaptive.dat' using 1:3 with linespoints pt 5 lw 2 lc rgb '#1b9e77' title 'adaptive "
        "(--refine)', \\\n"
        "     'plot-data/mesh-hierarchical.dat' using 1:3 with linespoints pt 9 lw 2 lc rgb '#d95f02' title "
        "'hierarchical'\n"
        "set output 'storage.png'\n"
        "set title \"",
        r.scene,
        ": storage of the light transport against patches\" noenhanced\n"
        "set ylabel 'MiB (links: count)'\nset key top left box opaque\n"
        "plot 'plot-data/mesh-uniform.dat' using 1:4 with linespoints pt 7 lw 2 lc rgb '#7570b3' title 'matrix (MiB)', "
        "\\\n"
        "     'plot-data/mesh-hierarchical.dat' using 1:4 with linespoints pt 9 lw 2 lc rgb '#d95f02' title "
        "'hierarchy: elements + links (MiB)', \\\n"
        "     'plot-data/mesh-hierarchical.dat' using 1:($5/1e6) with linespoints pt 6 dt 2 lw 2 lc rgb '#e7298a' "
        "title 'hierarchy: links (millions)', \\\n"
        "     [x=100:300000] 4*x**2/2**20 with lines dt 3 lc rgb 'gray40' title 'n^2 floats (MiB)'\n");
    writeFileAtomic((d / "plots.gp").string(), script);
    if (std::system("command -v gnuplot >/dev/null 2>&1") != 0) {
        logWarning("gnuplot not found: no plots (install gnuplot-nox, or run `bash scripts/bootstrap.sh build`); ",
                   "the script is ", (d / "plots.gp").string());
        return false;
    }
    const std::string command = cat("cd '", d.string(), "' && gnuplot plots.gp");
    if (std::system(command.c_str()) != 0) throw Error(cat("gnuplot failed on ", (d / "plots.gp").string()));
    return true;
}

}  // namespace penumbra::bench
