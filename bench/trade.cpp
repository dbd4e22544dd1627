// The sweep of `penumbra bench`: plans the runs, caches solves (and the path-traced reference on
// disk), times every stage, and measures the machine's limits and thread scaling in the same run.
#include "bench/trade.h"

#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

#include "core/error.h"
#include "core/log.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "core/timer.h"
#include "io/atomic_file.h"
#include "io/image_io.h"
#include "render/final_gather.h"
#include "render/image_metrics.h"
#include "render/integrators.h"
#include "render/object_reference.h"
#include "render/path_tracer.h"
#include "render/photon_map.h"
#include "render/radiosity_view.h"
#include "solver/solve.h"
#include "solver/tracer.h"

namespace penumbra::bench {

double Setting::ffNoise() const {
    return method == "final-gather" ? gatherEffortFor(spp).ffNoise : FormFactorSettings{}.objectNoise;
}

namespace {

// The settings every sweep starts from: the command line's defaults (quick: smaller).
struct Baseline {
    int patches = MeshingOptions{}.targetPatches;
    int visibilityRays = FormFactorSettings{}.visibilityRays;
    double ffTolerance = CubatureSettings{}.tolerance;
    double tolerance = SolverSettings{}.tolerance;
    int specularRays = SpecularSettings{}.pathsPerPatch;
    int64_t photons = PhotonSettings{}.photons;
    int photonK = PhotonSettings{}.nearest;
    int gatherRays = GatherSettings{}.gatherRays;
    int spp = 0;  // 0: the integrator's default (its registry entry)
};

Baseline baselineFor(bool quick) {
    Baseline b;
    if (quick) {
        b.patches = 500;
        b.photons = 200000;
        b.spp = 4;
    }
    return b;
}

Setting baseSetting(const Baseline& b, const std::string& method, const std::string& sweep) {
    return {method,
            sweep,
            b.patches,
            b.visibilityRays,
            b.ffTolerance,
            0,  // the default form factors
            b.tolerance,
            b.specularRays,
            b.photons,
            b.photonK,
            b.gatherRays,
            b.spp > 0 && method == "final-gather" ? b.spp : findIntegrator(method).defaultSpp};
}

// Adds one run per value and method: the baseline with one setting changed by `set`.
template <typename T, typename Set>
void vary(std::vector<Setting>& plan, const Baseline& b, std::initializer_list<const char*> methods, const char* sweep,
          const std::vector<T>& values, const Set& set) {
    for (const T& v : values)
        for (const char* method : methods) {
            Setting s = baseSetting(b, method, sweep);
            set(s, v);
            plan.push_back(s);
        }
}

// The runs, one setting varied at a time from the baseline, then in combinations, then the path tracer.
std::vector<Setting> planRuns(const Scene& scene, bool quick, const Baseline& b) {
    using Ints = std::vector<int>;
    std::vector<Setting> plan;
    const auto both = {"final-gather", "radiosity"};
    const auto gather = {"final-gather"};
    vary(plan, b, both, "default", Ints{0}, [](Setting&, int) {});
    vary(plan, b, both, "patches", quick ? Ints{250, 1000} : Ints{250, 500, 1000, 2000, 4000, 8000, 16000},
         [](Setting& s, int v) { s.patches = v; });
    // The analytic cubature's own settings (they change nothing of ray-cast form factors).
    if (!quick) vary(plan, b, both, "analytic", Ints{-1}, [](Setting& s, int v) { s.ffRays = v; });
    vary(plan, b, gather, "visibility-rays", quick ? Ints{1} : Ints{1, 16},
         [](Setting& s, int v) { s.visibilityRays = v, s.ffRays = -1; });
    vary(plan, b, both, "ff-tolerance", quick ? std::vector<double>{1e-3} : std::vector<double>{1e-3, 1e-4},
         [](Setting& s, double v) { s.ffTolerance = v, s.ffRays = -1; });
    vary(plan, b, both, "ff-rays", quick ? Ints{1024} : Ints{64, 1024, 4096}, [](Setting& s, int v) { s.ffRays = v; });
    vary(plan, b, both, "tolerance", quick ? std::vector<double>{1e-2} : std::vector<double>{1e-1, 1e-2, 1e-3, 1e-4},
         [](Setting& s, double v) { s.tolerance = v; });
    if (scene.hasSpecular()) {  // photons matter only where there are mirrors or glass
        vary(plan, b, gather, "photons",
             quick ? std::vector<int64_t>{50000} : std::vector<int64_t>{10000, 100000, 4000000},
             [](Setting& s, int64_t v) { s.photons = v; });
        vary(plan, b, gather, "photon-k", quick ? Ints{25} : Ints{25, 400}, [](Setting& s, int v) { s.photonK = v; });
        vary(plan, b, gather, "specular-rays", quick ? Ints{8} : Ints{8, 512},
             [](Setting& s, int v) { s.specularRays = v; });
    }
    vary(plan, b, gather, "gather-rays", quick ? Ints{4} : Ints{4, 64}, [](Setting& s, int v) { s.gatherRays = v; });
    // The final gather's solve and photons as `render` makes them for an image of that many samples.
    vary(plan, b, gather, "spp", quick ? Ints{1} : Ints{1, 4, 8, 32, 64}, [](Setting& s, int v) {
        const GatherEffort e = gatherEffortFor(v);
        s.spp = v;
        s.patches = int(std::lround(s.patches * e.patches));
        s.photons = std::llround(double(s.photons) * e.photons);
        s.specularRays = std::max(1, int(std::lround(s.specularRays * e.specularPaths)));
    });
    vary(plan, b, {"radiosity"}, "spp", quick ? Ints{16} : Ints{1, 16}, [](Setting& s, int v) { s.spp = v; });
    // Combinations along the diagonal, coarse and fast to fine and slow: (patches, spp, gather rays),
    // the fast ones with a looser cubature (the gather reads B one bounce later, where its error fades).
    struct Combo {
        int patches, spp, gatherRays;
        double ffTolerance;
        int specularRays;
    };
    const int sr = b.specularRays;
    vary(plan, b, gather, "combined",
         quick ? std::vector<Combo>{{250, 1, 4, 1e-3, 8}}
               : std::vector<Combo>{{500, 4, 8, 1e-3, 16},
                                    {1000, 4, 8, 1e-3, 16},
                                    {1000, 8, 4, 1e-3, 16},
                                    {1000, 8, 8, 1e-3, 16},
                                    {1000, 16, 4, 1e-3, 16},
                                    {1000, 8, 16, 1e-3, sr},
                                    {2000, 16, 16, 1e-4, sr},
                                    {8000, 64, 32, 1e-5, sr}},
         [](Setting& s, const Combo& c) {
             s.patches = c.patches, s.spp = c.spp, s.gatherRays = c.gatherRays, s.ffTolerance = c.ffTolerance;
             s.specularRays = c.specularRays;
         });
    // The plain radiosity view on finer meshes with the loose cubature: the cheapest views of all, once solved.
    vary(plan, b, {"radiosity"}, "combined", quick ? Ints{1000} : Ints{4000, 6000, 8000}, [](Setting& s, int v) {
        s.patches = v;
        s.ffTolerance = 1e-3;
    });
    // Meshes that model only what the light needs, against the uniform patch sweep: adaptive
    // subdivision from 250 patches, and the hierarchy (its finest elements those of a uniform mesh
    // of this many patches).
    // (By budget: on the Cornell box every tolerance from 0.1 down runs into the budget, so the
    // budget is what draws the curve.)
    vary(plan, b, {"radiosity"}, "adaptive", quick ? Ints{800} : Ints{1000, 2000, 4000, 8000},
         [](Setting& s, int v) { s.patches = 250, s.refine = 0.02, s.refineBudget = v; });
    if (!scene.hasSpecular())
        vary(plan, b, {"radiosity"}, "hierarchical", quick ? Ints{1000} : Ints{1000, 4000, 16000, 64000, 256000},
             [](Setting& s, int v) { s.patches = v, s.solver = "hierarchical"; });
    if (!scene.hasSpecular())  // no specular transport to trade: every run shares the solves
        for (Setting& s : plan) s.specularRays = b.specularRays;
    vary(plan, b, {"path"}, "spp", quick ? Ints{4, 16, 64} : Ints{4, 16, 64, 256, 1024, 2048},
         [](Setting& s, int v) { s.spp = v; });
    return plan;
}

std::string machineDescription() {
    std::ifstream cpu("/proc/cpuinfo");
    std::string line, model = "unknown processor";
    while (std::getline(cpu, line))
        if (line.rfind("model name", 0) == 0) {
            model = line.substr(line.find(':') + 2);
            break;
        }
    const double gib = double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGE_SIZE)) / double(1ull << 30);
    std::ostringstream out;
    out << sysconf(_SC_NPROCESSORS_ONLN) << " cores, " << int(gib + 0.5) << " GiB, " << model << ", " << threadCount()
        << " threads";
    return out.str();
}

std::string defaultCacheDir() {
    if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg) return cat(xdg, "/penumbra");
    if (const char* home = std::getenv("HOME"); home && *home) return cat(home, "/.cache/penumbra");
    return (std::filesystem::temp_directory_path() / "penumbra-cache").string();
}

// A solve, kept for the runs that share it: the solution as solveScene made it (without its matrix,
// which only the solves to other tolerances read), and what the bench measured of it.
struct SolveRecord {
    SolveResult solved;
    double solveSeconds = 0;  // the iterations and the display's vertex radiosity
    double peakMiB = 0, matrixMiB = 0, storageMiB = 0;
    uint64_t rayCount = 0;        // rays of the solve, every stage
    std::vector<Rgb> objectMean;  // area-weighted mean B per object
    const PatchSet& patches() const { return solved.patches; }
};

// Area of each scene object, m^2, as meshed.
std::vector<double> objectAreas(const Scene& scene, const PatchSet& patches) {
    std::vector<double> area(scene.objects.size(), 0.0);
    for (size_t i = 0; i < patches.size(); ++i) area[size_t(patches.object[i])] += patches.area[i];
    return area;
}

// Relative error of each diffuse object's mean radiosity (all channels together) against the
// reference solve's: {max, area-weighted mean} over the objects that receive light.
std::pair<double, double> objectErrors(const Scene& scene, const PatchSet& patches, const std::vector<Rgb>& mean,
                                       const std::vector<Rgb>& reference) {
    const std::vector<double> area = objectAreas(scene, patches);
    double worst = 0, weighted = 0, total = 0;
    for (size_t o = 0; o < scene.objects.size(); ++o) {
        if (scene.materialOf(scene.objects[o]).type != MaterialType::Diffuse || !(reference[o].sum() > 0)) continue;
        const double e = std::abs(mean[o].sum() - reference[o].sum()) / reference[o].sum();
        worst = std::max(worst, e);
        weighted += area[o] * e;
        total += area[o];
    }
    return {worst, total > 0 ? weighted / total : 0};
}

class Bench {
public:
    Bench(const BenchOptions& options, const Scene& scene)
        : options_(options), scene_(scene), baseline_(baselineFor(options.quick)), userLevel_(logLevel()) {}

    BenchResult run();

private:
    // Runs `f` with the stages' own logs and progress bars silenced (the bench draws its own).
    template <typename F>
    auto quietly(const F& f) {
        setLogLevel(userLevel_ == LogLevel::Debug ? LogLevel::Debug : std::max(userLevel_, LogLevel::Warning));
        struct Restore {
            LogLevel level;
            ~Restore() { setLogLevel(level); }
        } restore{userLevel_};
        return f();
    }
    Camera camera() const;
    const Image& reference(BenchResult& result);
    const SolveRecord& solveFor(const Setting& s);
    Row runOne(const Setting& s);
    void measureLimits(BenchResult& result);
    void measureObjects(BenchResult& result);
    void measureThreads(BenchResult& result);

    const BenchOptions& options_;
    const Scene& scene_;
    Baseline baseline_;
    LogLevel userLevel_;
    std::vector<Setting> plan_;
    // The solves made so far, by what makes one: every setting of the solve, with this tolerance.
    using SolveKey = std::tuple<int, int, double, int, int, double, double, int, std::string, double, bool>;
    static SolveKey keyOf(const Setting& s, double tolerance) {
        return {s.patches, s.visibilityRays, s.ffTolerance, s.ffRays,    s.specularRays,      tolerance,
                s.refine,  s.refineBudget,   s.solver,      s.ffNoise(), s.displayedCorners()};
    }
    std::map<SolveKey, std::unique_ptr<SolveRecord>> solves_;
    PatchSet pathPatches_;
    std::unique_ptr<SceneTracer> pathTracer_;
    double pathSetupSeconds_ = 0;
    Image reference_;
};

Camera Bench::camera() const {
    Camera c = scene_.camera;
    if (options_.width > 0) {
        c.width = options_.width;
        c.height = options_.height;
    } else {
        const int w = options_.quick ? 64 : 256;
        c.height = std::max(1, int(std::lround(double(w) * scene_.camera.height / scene_.camera.width)));
        c.width = w;
    }
    return c;
}

const Image& Bench::reference(BenchResult& result) {
    const Camera cam = camera();
    const std::string dir = options_.cache.empty() ? defaultCacheDir() : options_.cache;
    char name[160];
    std::snprintf(name, sizeof name, "reference-%016llx-%dx%d-%dspp-seed%llu.exr",
                  static_cast<unsigned long long>(scene_.fileFingerprint), cam.width, cam.height, result.referenceSpp,
                  static_cast<unsigned long long>(options_.seed));
    const std::string path = (std::filesystem::path(dir) / name).string();
    if (std::filesystem::exists(path)) {
        reference_ = readLinearImage(path);
        if (reference_.width == cam.width && reference_.height == cam.height) {
            logInfo("bench: path-traced reference from the cache: ", path);
            return reference_;
        }
    }
    logInfo("bench: rendering the path-traced reference (", result.referenceSpp, " spp at ", cam.width, "x", cam.height,
            "), cached in ", path);
    Timer timer;
    reference_ = quietly([&] {
        return renderPath(*pathTracer_, cam, result.referenceSpp, streamSeed(options_.seed, Stream::BenchReference));
    });
    result.referenceSeconds = timer.seconds();
    ensureDirectory(dir);
    writeLinearImage(reference_, path);
    return reference_;
}

// The per-object reference (cached as one line per object: index, the three channels, the relative
// error, the points) and the default solve against it at 8 seeds (quick: 2).
void Bench::measureObjects(BenchResult& result) {
    const double target = options_.quick ? 0.005 : 0.001;
    result.objectReferenceError = target;
    const std::string dir = options_.cache.empty() ? defaultCacheDir() : options_.cache;
    char name[160];
    std::snprintf(name, sizeof name, "objects-%016llx-%g-seed%llu.txt",
                  static_cast<unsigned long long>(scene_.fileFingerprint), target,
                  static_cast<unsigned long long>(options_.seed));
    const std::string path = (std::filesystem::path(dir) / name).string();
    std::vector<ObjectEstimate> reference(scene_.objects.size());
    bool cached = false;
    if (std::ifstream in(path); in) {
        size_t k;
        double r, g, b, relative;
        int64_t points;
        size_t read = 0;
        while (in >> k >> r >> g >> b >> relative >> points)
            if (k < reference.size()) reference[k].radiosity = Rgb(r, g, b), reference[k].samples = points, ++read;
        cached = read > 0;
    }
    if (!cached) {
        logInfo("bench: path-traced per-object reference (", 100 * target, "% per object), cached in ", path);
        ObjectReferenceSettings settings;
        settings.targetError = target;
        settings.seed = options_.seed;
        Timer timer;
        reference = quietly([&] { return pathObjectRadiosity(*pathTracer_, settings); });
        result.objectReferenceSeconds = timer.seconds();
        std::string text;
        for (size_t k = 0; k < reference.size(); ++k) {
            const ObjectEstimate& e = reference[k];
            if (e.samples == 0) continue;
            text += cat(k, " ", e.radiosity[0], " ", e.radiosity[1], " ", e.radiosity[2], " ", e.relativeError, " ",
                        e.samples, "\n");
        }
        ensureDirectory(dir);
        writeFileAtomic(path, text);
    }
    const int seeds = options_.quick ? 2 : 8;
    for (int seed = 1; seed <= seeds; ++seed) {
        SolveOptions o;
        o.formFactors.seed = uint64_t(seed);
        const SolveResult r = quietly([&] { return solveScene(scene_, o); });
        ObjectRun run;
        run.seed = uint64_t(seed);
        run.seconds = r.secondsMeshing + r.secondsFormFactors + r.secondsSpecular + r.secondsSolve + r.secondsVertices;
        run.formFactorSeconds = r.secondsFormFactors;
        run.castRays = double(r.counters.at("form_factors.cast_rays"));
        run.visibilityRays = double(r.counters.at("form_factors.visibility_rays"));
        run.transportSeconds = r.secondsSpecular;
        if (const auto t = r.counters.find("specular.rays"); t != r.counters.end())
            run.transportRays = double(t->second);
        const std::vector<Rgb> mean = objectRadiosity(r, scene_.objects.size());
        for (size_t k = 0; k < mean.size(); ++k) {
            if (reference[k].samples == 0 || !(reference[k].radiosity.sum() > 0)) continue;
            const double e = std::abs(mean[k].sum() / reference[k].radiosity.sum() - 1);
            if (e < run.worstError) continue;
            run.worstError = e;
            run.worst = scene_.objects[k].name;
            run.worstStated = k < r.objectNoise.size() ? r.objectNoise[k] : 0;
        }
        logInfo("bench: default solve, seed ", seed, ": ", run.seconds, " s, worst object ", run.worst, " ",
                100 * run.worstError, "%");
        result.objectRuns.push_back(run);
    }
}

const SolveRecord& Bench::solveFor(const Setting& s) {
    const auto key = keyOf(s, s.tolerance);
    if (auto it = solves_.find(key); it != solves_.end()) return *it->second;
    // Every tolerance the plan asks of this mesh comes from one matrix: only the solve differs.
    std::vector<double> tolerances{s.tolerance};
    for (const Setting& p : plan_)
        if (p.method != "path" && p.patches == s.patches && p.visibilityRays == s.visibilityRays &&
            p.ffTolerance == s.ffTolerance && p.ffRays == s.ffRays && p.specularRays == s.specularRays &&
            p.refine == s.refine && p.refineBudget == s.refineBudget && p.solver == s.solver &&
            p.ffNoise() == s.ffNoise() && p.displayedCorners() == s.displayedCorners() && s.solver != "hierarchical" &&
            std::find(tolerances.begin(), tolerances.end(), p.tolerance) == tolerances.end())
            tolerances.push_back(p.tolerance);
    SolveOptions o;
    o.meshing.targetPatches = s.patches;
    o.formFactors.visibilityRays = s.visibilityRays;
    o.formFactors.cubature.tolerance = s.ffTolerance;
    if (s.ffRays != 0) o.formFactors.method = s.ffRays > 0 ? "rays" : "analytic";
    if (s.ffRays > 0) o.formFactors.raysPerPatch = s.ffRays, o.manyObjectsRays = 0;
    o.formFactors.seed = options_.seed;
    o.formFactors.objectNoise = s.ffNoise();
    o.forSolvedIndirectGather = !s.displayedCorners();
    o.specular.pathsPerPatch = s.specularRays;
    o.solverSettings.tolerance = tolerances.front();
    o.solver = s.solver;
    o.refine.tolerance = s.refine;
    if (s.refine > 0) o.refine.maxPatches = s.refineBudget;
    resetPeakMemory();
    SolveResult r = quietly([&] { return solveScene(scene_, o); });
    const double peak = peakMemoryBytes() / (1 << 20);
    const uint64_t rays = r.counters.at("rays.occlusion") + r.counters.at("rays.nearest");
    const double matrixMiB = double(r.F.bytes()) / (1 << 20);
    auto keep = [&](double tolerance) {
        auto rec = std::make_unique<SolveRecord>();
        FormFactorMatrix F = std::move(r.F);  // the copy goes without the matrix
        rec->solved = r;
        r.F = std::move(F);
        rec->solveSeconds = r.secondsSolve + r.secondsVertices;  // the display's vertex radiosity counts too
        rec->peakMiB = peak;
        rec->matrixMiB = matrixMiB;
        rec->storageMiB = r.solverName == "hierarchical" ? r.hierarchy.bytes / (1 << 20) : matrixMiB;
        rec->rayCount = rays;
        rec->objectMean = objectRadiosity(r, scene_.objects.size());
        solves_[keyOf(s, tolerance)] = std::move(rec);
    };
    keep(tolerances.front());
    for (size_t k = 1; k < tolerances.size(); ++k) {
        // The same matrix to another tolerance: the tail of the solve again, timed afresh.
        SolveOptions again = o;
        again.solver = r.solverName;
        again.solverSettings.tolerance = tolerances[k];
        r.secondsSolve = r.secondsVertices = 0;
        quietly([&] {
            solveBuiltMatrix(again, {}, r);
            return 0;
        });
        keep(tolerances[k]);
    }
    return *solves_.at(key);
}

Row Bench::runOne(const Setting& s) {
    Row row;
    row.setting = s;
    const Camera cam = camera();
    Image image;
    if (s.method == "path") {
        const uint64_t rays0 = raysCast();
        resetPeakMemory();
        Timer timer;
        image = quietly([&] { return renderPath(*pathTracer_, cam, s.spp, options_.seed); });
        row.render = timer.seconds();
        row.meshing = pathSetupSeconds_;
        row.patchesMade = int(pathPatches_.size());
        row.rays = raysCast() - rays0;
        row.peakMiB = peakMemoryBytes() / (1 << 20);
    } else {
        const SolveRecord& rec = solveFor(s);
        const SolveResult& solved = rec.solved;
        row.patchesMade = int(solved.patches.size());
        row.formFactorMethod = solved.formFactorMethod;
        row.meshing = solved.secondsMeshing, row.formFactors = solved.secondsFormFactors,
        row.specular = solved.secondsSpecular, row.solve = rec.solveSeconds;
        row.matrixMiB = rec.matrixMiB;
        row.links = solved.hierarchy.links;
        row.storageMiB = rec.storageMiB;
        const uint64_t rays0 = raysCast();
        resetPeakMemory();
        if (s.method == "radiosity") {
            Timer timer;
            image = quietly([&] {
                return renderRadiosityView(scene_, cam, solved.patches, solved.rays, solved.corners,
                                           {s.spp, options_.seed});
            });
            row.render = timer.seconds();
        } else {
            GatherSettings gather;
            gather.gatherRays = s.gatherRays;
            PhotonSettings photons;
            photons.photons = s.photons;
            photons.nearest = s.photonK;
            Timer setup;
            const auto views = quietly([&] {
                return std::make_unique<SolvedScene>(scene_, solved.patches, solved.corners, gather, photons,
                                                     options_.seed, solved.rays, nullptr, solved.indirect);
            });
            row.photons = setup.seconds();
            const uint64_t rays1 = raysCast();
            Timer timer;
            image = quietly([&] { return views->render(cam, s.spp, options_.seed); });
            row.render = timer.seconds();
            row.renderRays = raysCast() - rays1;
        }
        row.rays = rec.rayCount + (raysCast() - rays0);
        row.peakMiB = std::max(rec.peakMiB, peakMemoryBytes() / (1 << 20));
    }
    const ImageError blurred = compareBlurred(image, reference_), raw = compareImages(image, reference_);
    row.imageError = blurred.pooledL1;
    row.imageErrorRaw = blurred.meanRelative;
    row.rmse = raw.rmse;
    return row;
}

void Bench::measureLimits(BenchResult& result) {
    result.embree = measureEmbreeLimit(pathPatches_, options_.quick ? 1000000 : 4000000, options_.seed);
    logInfo("bench: Embree alone on ", pathPatches_.size(), " patches, ", result.embree.threads,
            " threads: ", result.embree.occluded1 / 1e6, " M occlusion rays/s (8-wide packets ",
            result.embree.occluded8 / 1e6, " M/s), ", result.embree.intersect1 / 1e6, " M nearest-hit rays/s");
    result.bandwidth = measureBandwidth(options_.quick ? 4000 : 16000, options_.seed);
    const BandwidthLimit& b = result.bandwidth;
    logInfo("bench: memory on a ", b.n, "^2 float matrix (", b.matrixBytes / (1 << 20), " MiB): read ", b.readGBs,
            " GB/s, copy ", b.copyGBs, " GB/s; Jacobi sweep ", b.jacobiGBs, " GB/s, Gauss-Seidel sweep ",
            b.gaussSeidelGBs, " GB/s");
}

void Bench::measureThreads(BenchResult& result) {
    const int all = threadCount();
    auto timed = [&](int threads, const auto& f) {
        setThreadCount(threads);
        Timer timer;
        auto value = quietly(f);
        return std::make_pair(timer.seconds(), std::move(value));
    };
    auto record = [&](const std::string& stage, const std::string& size, double one, double many, bool identical) {
        result.threads.push_back({stage, size, one, many, all, identical});
        logInfo("bench: ", stage, " (", size, "): ", one, " s on 1 thread, ", many, " s on ", all, " (x", one / many,
                identical ? "), identical results" : "), results DIFFER");
    };
    {
        const PatchSet patches = meshScene(scene_, {options_.quick ? 300 : 1500, 0});
        const RayScene rays(patches);
        FormFactorSettings settings;
        settings.seed = options_.seed;
        auto ff = [&] { return computeFormFactors(patches, rays, settings).dense(); };
        const auto one = timed(1, ff), many = timed(all, ff);
        record("form factors", cat(patches.size(), " patches"), one.first, many.first, one.second == many.second);
    }
    if (scene_.hasSpecular()) {
        PhotonSettings settings;
        settings.photons = options_.quick ? 200000 : 1000000;
        settings.seed = options_.seed;
        auto trace = [&] { return PhotonMap(*pathTracer_, settings).stats(); };
        const auto one = timed(1, trace), many = timed(all, trace);
        record("photon tracing", cat(settings.photons, " photons"), one.first, many.first,
               one.second.stored == many.second.stored && (one.second.storedPower == many.second.storedPower).all());
    }
    const Camera cam = camera();
    const SolveRecord& rec = solveFor(baseSetting(baseline_, "final-gather", "default"));
    const auto solved = quietly([&] {
        return std::make_unique<SolvedScene>(scene_, rec.solved.patches, rec.solved.corners, GatherSettings{},
                                             PhotonSettings{}, options_.seed, rec.solved.rays);
    });
    const int spp = options_.quick ? 1 : 4;
    auto gather = [&] { return solved->render(cam, spp, options_.seed).rgb; };
    const auto g1 = timed(1, gather), gn = timed(all, gather);
    record("final gather", cat(cam.width, "x", cam.height, ", ", spp, " spp"), g1.first, gn.first,
           g1.second == gn.second);
    auto path = [&] { return renderPath(*pathTracer_, cam, spp * 4, options_.seed).rgb; };
    const auto p1 = timed(1, path), pn = timed(all, path);
    record("path tracer", cat(cam.width, "x", cam.height, ", ", spp * 4, " spp"), p1.first, pn.first,
           p1.second == pn.second);
    setThreadCount(all);
}

BenchResult Bench::run() {
    BenchResult result;
    result.scene = scene_.path;
    result.machine = machineDescription();
    const Camera cam = camera();
    result.width = cam.width, result.height = cam.height;
    result.referenceSpp = options_.referenceSpp > 0 ? options_.referenceSpp : options_.quick ? 1024 : 4096;
    plan_ = planRuns(scene_, options_.quick, baseline_);
    if (!options_.only.empty()) {
        const auto& only = options_.only;
        plan_.erase(std::remove_if(plan_.begin(), plan_.end(),
                                   [&](const Setting& s) {
                                       const std::string name = s.method == "path" ? "path" : s.sweep;
                                       return name != "default" &&
                                              std::find(only.begin(), only.end(), name) == only.end();
                                   }),
                    plan_.end());
    }
    logInfo("bench: ", scene_.path, " at ", cam.width, "x", cam.height, ", ", plan_.size(), " runs on ",
            result.machine);

    Timer setup;
    pathPatches_ = meshScene(scene_, MeshingOptions{});
    pathTracer_ = std::make_unique<SceneTracer>(scene_, pathPatches_);
    pathSetupSeconds_ = setup.seconds();
    reference(result);

    Progress progress("bench", int64_t(plan_.size()) + 2);
    std::vector<const SolveRecord*> records;
    for (size_t k = 0; k < plan_.size(); ++k) {
        const Setting& s = plan_[k];
        result.rows.push_back(runOne(s));
        records.push_back(s.method == "path" ? nullptr : &solveFor(s));
        const Row& row = result.rows.back();
        if (s.method == "final-gather" && s.sweep == "default") {
            result.gatherRays = double(row.renderRays);
            result.gatherSeconds = row.render;
            const SolveRecord& rec = *records.back();
            result.formFactorRays = double(rec.solved.counters.at("form_factors.visibility_rays"));
            result.formFactorCastRays = double(rec.solved.counters.at("form_factors.cast_rays"));
            result.formFactorSeconds = rec.solved.secondsFormFactors;
        }
        logInfo("bench: [", k + 1, "/", plan_.size(), "] ", cat(s.method, ", ", settingText(s)), ": ", row.total(),
                " s, error ", 100 * row.imageError, "%");
        progress.update();
    }
    // Radiosity per object against the finest solve of the sweep (whose own rows have none).
    const SolveRecord* finest = nullptr;
    for (const auto& [key, rec] : solves_)
        if (rec->solved.hierarchy.links == 0 && (!finest || rec->patches().size() > finest->patches().size()))
            finest = rec.get();  // a matrix solve
    for (size_t k = 0; k < result.rows.size(); ++k) {
        if (!records[k] || !finest || records[k]->patches().size() == finest->patches().size()) continue;
        const auto [worst, mean] =
            objectErrors(scene_, records[k]->patches(), records[k]->objectMean, finest->objectMean);
        result.rows[k].objectErrorMax = worst;
        result.rows[k].objectErrorMean = mean;
    }
    markPareto(result.rows);

    measureObjects(result);
    measureLimits(result);
    progress.update();
    measureThreads(result);
    progress.done();
    return result;
}

}  // namespace

BenchResult runBench(const BenchOptions& options) {
    const Scene scene = loadScene(options.scene);
    if (!scene.hasCamera)
        throw Error(cat(scene.path, ": camera: the bench measures image error from the scene's camera; add a camera"));
    if (!scene.hasEmitter()) throw Error(cat(scene.path, ": the scene emits no light: nothing to measure"));
    Bench bench(options, scene);
    return bench.run();
}

}  // namespace penumbra::bench
