// The `penumbra` command line: parses, calls the library, catches once, exits. The verbs and
// options are those of shared/CONTRACT.md plus extensions listed in `penumbra --help`.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <thread>
#include <tuple>

#include "allocator.h"
#include "bench/trade.h"
#include "core/cluster.h"
#include "core/counters.h"
#include "core/error.h"
#include "core/image_file.h"
#include "core/log.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "core/timer.h"
#include "io/atomic_file.h"
#include "io/checkpoint.h"
#include "io/export.h"
#include "io/image_io.h"
#include "io/output_set.h"
#include "io/report.h"
#include "io/solution.h"
#include "mesh/gltf_scene.h"
#include "mesh/scene.h"
#include "render/final_gather.h"
#include "render/image_metrics.h"
#include "render/integrators.h"
#include "render/object_reference.h"
#include "render/orbit.h"
#include "render/path_tracer.h"
#include "render/photon_map.h"
#include "render/radiosity_view.h"
#include "render/regions.h"
#include "solver/solve.h"
#include "viewer/viewer.h"

using namespace penumbra;

namespace {

struct CommonOptions {
    int threads = 0;
    bool quiet = false, verbose = false, progress = false;
    uint64_t seed = 1;
};

struct SolveCli {
    std::string scene, out;
    SolveOptions options;
    double maxMemoryGiB = 0;
    int viewSpp = 4;
    bool resume = false;  // solve --resume: carry on from OUT/checkpoint.bin
    CLI::Option *patches = nullptr, *perObject = nullptr, *ffRays = nullptr, *ffNoise = nullptr,
                *specularRays = nullptr, *vertexRadiosity = nullptr;

    // The options as the solve takes them, with what the command line leaves to depend on others.
    SolveOptions resolved(const CommonOptions& common) const {
        SolveOptions o = options;
        o.formFactors.seed = common.seed;
        o.maxMemoryBytes = maxMemoryGiB * double(1ull << 30);
        // Adaptive subdivision starts coarse, unless told where to start.
        if (o.refine.tolerance > 0 && patches->count() == 0 && !(o.meshing.patchSize > 0))
            o.meshing.targetPatches = std::min(kRefineStartPatches, o.refine.maxPatches);
        // An explicit --patches is the user's number; the default has a floor per object.
        if ((patches->count() > 0 || o.refine.tolerance > 0) && perObject->count() == 0) o.meshing.patchesPerObject = 0;
        // An explicit --ff-rays holds in a scene of many objects too.
        if (ffRays->count() > 0) o.manyObjectsRays = 0;
        return o;
    }
    static constexpr int kRefineStartPatches = 400;
};

struct RenderCli {
    std::string scene, out, solution, integrator = "final-gather", camera, resolution;
    std::string indirect = "solution";  // the final gather's indirect light: read from the solve, or gathered
    int spp = 0;                        // 0: the integrator's default
    int orbit = 0;                      // > 0: that many turntable views
    double exposure = 0;
    GatherSettings gather;
    PhotonSettings photons;
    CLI::Option* photonsOption = nullptr;
};

// Any positive number: one short message, where CLI11's own check quotes the largest double.
const CLI::Validator kPositive(
    [](std::string& text) {
        double v = 0;
        return finiteNumber(text, v) && v > 0 ? std::string() : cat("expected a positive number, got ", text);
    },
    "POSITIVE");

// A number in [lo, hi], with one short message: CLI11's own check said "Value abc not in range",
// printed a double's bounds in 309 digits and let NaN through.
CLI::Validator inRange(double lo, double hi) {
    auto text = [](double v) {
        char buffer[32];
        std::snprintf(buffer, sizeof buffer, "%.15g", v);
        return std::string(buffer);
    };
    return CLI::Validator(
        [=](std::string& value) {
            double v = 0;
            return finiteNumber(value, v) && v >= lo && v <= hi
                       ? std::string()
                       : cat("expected a number in [", text(lo), ", ", text(hi), "], got ", value);
        },
        "");
}

// Every number an option takes is finite: CLI11's range checks let NaN through (--tolerance nan ran
// 20,000 iterations) and strtod reads "inf". Added to every FLOAT option of `app` and its commands.
const CLI::Validator kFinite(
    [](std::string& text) {
        double v = 0;
        return finiteNumber(text, v) ? std::string() : cat("expected a finite number, got ", text);
    },
    "");

// Unsigned options take whole numbers only: CLI11 read "--seed -5" as 2^64 - 5.
const CLI::Validator kWhole(
    [](std::string& text) {
        return !text.empty() && text.size() <= 20 && text.find_first_not_of("0123456789") == std::string::npos
                   ? std::string()
                   : cat("expected a whole number, got ", text);
    },
    "");

void requireFiniteNumbers(CLI::App& app) {
    for (CLI::Option* o : app.get_options()) {
        if (o->get_type_name().rfind("FLOAT", 0) == 0) o->check(kFinite);
        if (o->get_type_name().rfind("UINT", 0) == 0) o->check(kWhole);
    }
    for (CLI::App* sub : app.get_subcommands(std::function<bool(CLI::App*)>())) requireFiniteNumbers(*sub);
}

// --threads: 0 (all cores) up to 8 threads a core (at least 64). More went straight to TBB and ran
// out of memory building the ray scene at 2,000,000,000; -1 silently meant all cores.
const CLI::Validator kThreads(
    [](std::string& text) {
        const long cap = std::max(64L, 8L * long(std::max(1u, std::thread::hardware_concurrency())));
        char* end = nullptr;
        const long v = std::strtol(text.c_str(), &end, 10);
        return end != text.c_str() && *end == 0 && v >= 0 && v <= cap
                   ? std::string()
                   : cat("expected 0 (all cores) or a thread count up to ", cap, ", got ", text);
    },
    "");

void addSolveOptions(CLI::App* cmd, SolveCli& s) {
    for (const SolveSetting& e : solveSettings(s.options)) {
        CLI::Option* option = std::visit([&](auto* value) { return cmd->add_option(e.flag, *value, e.help); }, e.value);
        option->check(std::isinf(e.max) && e.min == 0 && !std::holds_alternative<int*>(e.value)
                          ? kPositive
                          : inRange(e.min, e.max));
        if (e.showDefault) option->capture_default_str();
        if (std::string(e.key) == "patches") s.patches = option;
        if (std::string(e.key) == "patches_per_object") s.perObject = option;
        if (std::string(e.key) == "ff_rays") s.ffRays = option;
        if (std::string(e.key) == "ff_noise") s.ffNoise = option;
        if (std::string(e.key) == "specular_rays") s.specularRays = option;
    }
    std::string solverHelp;
    for (const SolverInfo& e : solverRegistry())
        solverHelp += cat(solverHelp.empty() ? "" : "; ", e.name, ": ", e.summary);
    cmd->add_option("--solver", s.options.solver, solverHelp)->capture_default_str();
    cmd->add_option("--form-factors", s.options.formFactors.method,
                    cat("auto: analytic while at most ", kAnalyticFacingPairs,
                        " patch pairs face each other, else rays (the log and report say which and why); "
                        "analytic: cubature of the point-to-polygon kernel with visibility rays (accurate, the closed "
                        "forms' mode; cost grows with the pairs); rays: the share of each patch's cosine rays that "
                        "lands on each patch (rows sum to one by construction, at Embree's ray rate, a sparse matrix; "
                        "noise about 1/sqrt(--ff-rays))"))
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "analytic", "rays"}));
    s.vertexRadiosity =
        cmd->add_option(
               "--vertex-radiosity", s.options.vertexRadiosity,
               "Displayed radiosity at the patch corners: gather (the radiosity equation at each vertex: every "
               "patch in view, a ray each), direct (the mean of the patches around it, with the direct light of "
               "small sources taken at the vertex itself: shadows and penumbrae for about 64 shadow rays per "
               "vertex) or average (the mean of the patches around it; cheapest, blurs edges, contacts and "
               "shadows)")
            ->capture_default_str()
            ->check(CLI::IsMember({"gather", "direct", "average"}));
    cmd->add_option("--max-memory", s.maxMemoryGiB, "Memory budget in GiB for the matrix (default: what is available)")
        ->check(kPositive);
}

void setupLogging(const CommonOptions& c) {
    // Under mpirun the leader logs; the other ranks say only their own errors (cluster.h).
    setLogLevel(!cluster::leader() ? LogLevel::Error
                : c.quiet          ? LogLevel::Warning
                : c.verbose        ? LogLevel::Debug
                                   : LogLevel::Info);
    int threads = c.threads;
    if (threads == 0 && cluster::ranksOnHost() > 1) {
        // The host's cores shared among its ranks, unless mpirun already bound each to its own.
        const int cores = int(std::thread::hardware_concurrency()), usable = threadCount();
        threads = usable < cores ? usable : std::max(1, usable / cluster::ranksOnHost());
    }
    setThreadCount(threads);
    setProgressForced(c.progress);
    logDebug("memory: ", allocatorName());
}

// Under mpirun, each rank's host, once.
void logRanks() {
    if (!cluster::distributed()) return;
    std::string ranks;
    for (int r = 0; r < cluster::size(); ++r) ranks += cat(r ? ", " : "", cluster::rankName(r));
    logInfo("mpirun: ", cluster::size(), " ranks (", ranks, "), threads per rank: ", threadCount());
    if (!progressForced())
        logInfo("mpirun gives the ranks a pipe for stderr, not the terminal: --progress draws rank 0's progress bars");
}

// Under mpirun, a command that one rank does (export, compare, reference): the leader runs it, the
// others wait for it asleep. The viewer and the bench (which times one process) are refused.
int onLeader(const char* command, const std::function<int()>& run) {
    if (cluster::distributed() && (std::string(command) == "view" || std::string(command) == "bench"))
        throw Error(cat(command, " runs in one process: start it without mpirun"));
    int status = 0;
    if (cluster::leader()) {
        const cluster::Alone alone;
        status = run();
    }
    cluster::barrier();
    return status;
}

constexpr double kMostUnshot = 1e-4;

int runSolve(SolveCli& s, const CommonOptions& common) {
    const Scene scene = loadScene(s.scene);
    // The outputs appear as one set or not at all (output_set.h); --out is checked before the work.
    // Under mpirun every rank solves, sharing the form factors' rows and the picture's (cluster.h),
    // and the leader writes.
    std::vector<std::string> names{"solution.bin", "convergence.csv", "report.json"};
    if (scene.hasCamera) names.insert(names.end(), {"radiosity.exr", "radiosity.png"});
    std::optional<OutputSet> outputs;
    if (cluster::leader()) outputs.emplace(s.out, names);
    SolveOptions options = s.resolved(common);
    // The ray-cast rows go into OUT/checkpoint.bin as they are made; with --resume, those of a killed
    // run are read back (io/checkpoint.h). The file goes when this run ends, written or failed: only a
    // killed run leaves it.
    SolveCheckpoint checkpoint((std::filesystem::path(s.out) / "checkpoint.bin").string(),
                               checkpointIdentity(scene.fingerprint, options));
    struct RemoveAtEnd {
        SolveCheckpoint& c;
        ~RemoveAtEnd() { c.remove(); }
    } removeAtEnd{checkpoint};
    if (s.resume) {
        // The leader reads the file and sends the other ranks its passes (those in row blocks cut to
        // their tag: each rank reads its own rows, DIR/checkpoint.bin.rank-R).
        std::string shared;
        if (cluster::leader()) {
            std::ifstream in((std::filesystem::path(s.out) / "checkpoint.bin").string(), std::ios::binary);
            const std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
            if (!bytes.empty()) {
                checkpoint.resume(bytes);
                shared = checkpoint.shareable();
            }
        }
        shared = cluster::broadcast(shared);
        if (!cluster::leader()) {
            if (!shared.empty()) checkpoint.resume(shared);
            std::ifstream own(checkpoint.ownPath(), std::ios::binary);
            const std::string mine{std::istreambuf_iterator<char>(own), std::istreambuf_iterator<char>()};
            try {
                if (!mine.empty()) checkpoint.resumeOwn(mine);
            } catch (const Error& e) {  // another run's: this rank computes its rows again
                logWarning(e.what(), " (not used)");
            }
        }
        if (shared.empty()) {
            logInfo("--resume: no checkpoint in ", s.out, ": solving from the start");
        } else {
            logInfo("--resume: carrying on from ", s.out, "/checkpoint.bin (", checkpoint.passesResumed(),
                    " form-factor passes saved)");
        }
    }
    options.formFactors.checkpoint = &checkpoint;
    // A report balances emitted = absorbed + escaped to 1e-4 of the emitted power (the contract's
    // check-report): a looser tolerance stopped with up to that much unshot and wrote a report
    // that failed it (--tolerance 1e308: 17% unaccounted, exit 0).
    if (options.solverSettings.tolerance > kMostUnshot)
        throw Error(cat("--tolerance ", options.solverSettings.tolerance, ": a solve's report balances its power to ",
                        kMostUnshot, " of the emitted power, so its tolerance may be at most that (render takes any)"));
    const SolveResult r = solveScene(scene, options);
    const CornerValues& corners = r.corners;
    // A solve stopped with light still unshot has not accounted for it: past a ten-thousandth of
    // the emitted power (what the report's balance allows) it is refused, and nothing written;
    // below, the warning the solver gave. (Reflectance 0.9999999 left 0.996 unshot after 20,000
    // iterations and exited 0 with a report whose balance failed.)
    if (!(r.solution.residual <= kMostUnshot))
        throw Error(cat(s.scene, ": the solve did not converge: ", r.solution.residual,
                        " of the emitted power still unshot after ", r.solution.iterations, " iterations (--tolerance ",
                        options.solverSettings.tolerance,
                        "); raise --max-iterations or loosen --tolerance; nothing written"));

    Image view;
    if (scene.hasCamera)
        view = renderRadiosityView(scene, scene.camera, r.patches, r.rays, corners, {s.viewSpp, common.seed});
    if (!cluster::leader()) return cluster::barrier(), 0;
    outputs->write("solution.bin", [&](const std::string& path) { writeSolution(path, r); });
    outputs->write("convergence.csv", [&](const std::string& path) { writeFileAtomic(path, convergenceCsv(r)); });
    if (scene.hasCamera) {
        outputs->write("radiosity.exr", [&](const std::string& path) { writeLinearImage(view, path); });
        outputs->write("radiosity.png", [&](const std::string& path) { writePreviewPng(view, path); });
    }
    outputs->write("report.json",
                   [&](const std::string& path) { writeFileAtomic(path, reportJson(scene, r, peakMemoryBytes())); });
    // Under mpirun the files go into place only once every rank is known to be alive: a rank lost
    // before this leaves nothing behind.
    cluster::barrier();
    outputs->commit();
    const double m2 = scene.squareMetresPerUnit();  // inside units to m^2 and W
    logInfo("wrote ", s.out, ": ", r.patches.size(), " patches, emitted ", r.power.totalEmitted.sum() * m2,
            " W, absorbed ", r.power.totalAbsorbed.sum() * m2, " W, escaped ", r.power.escaped.sum() * m2, " W");
    return 0;
}

// --resolution WIDTHxHEIGHT, each side in [1, 16384].
std::pair<int, int> parseResolution(const std::string& text) {
    int w = 0, h = 0, used = 0;
    if (std::sscanf(text.c_str(), "%dx%d%n", &w, &h, &used) != 2 || size_t(used) != text.size())
        throw Error(cat("--resolution: expected WIDTHxHEIGHT such as 512x512, got '", text, "'"));
    if (w < 1 || h < 1 || w > 16384 || h > 16384) throw Error("--resolution: width and height must lie in [1, 16384]");
    return {w, h};
}

Camera cameraFor(const Scene& scene, const RenderCli& c) {
    Camera camera = scene.camera;
    if (!c.camera.empty()) {
        camera = parseCamera(c.camera, scene, "--camera");
    } else if (!scene.hasCamera) {
        throw Error(
            cat(scene.path,
                ": camera: the scene has no camera; add one or pass --camera '{\"position\": ..., \"look_at\": ...}'"));
    }
    if (!c.resolution.empty()) std::tie(camera.width, camera.height) = parseResolution(c.resolution);
    return camera;
}

SolveResult solveOrRead(const Scene& scene, const RenderCli& c, SolveCli& s, const CommonOptions& common,
                        int gatherSpp);

// The stored solution, or a solve made now; `gatherSpp` > 0: for final-gathered images of that many
// samples per pixel. Under mpirun the ranks solve together, or the leader reads the stored one and
// sends it to the others, and every rank (the leader too) renders from the copy sent.
SolveResult solutionFor(const Scene& scene, const RenderCli& c, SolveCli& s, const CommonOptions& common,
                        int gatherSpp) {
    // Every rank solves together (the form factors' rows shared); a stored one the leader reads.
    if (!cluster::distributed() || c.solution.empty()) return solveOrRead(scene, c, s, common, gatherSpp);
    std::string bytes;
    if (cluster::leader()) {
        const cluster::Alone alone;
        bytes = solutionBytes(solveOrRead(scene, c, s, common, gatherSpp));
    }
    bytes = cluster::broadcast(bytes);
    logInfo("mpirun: the solution sent to every rank, ", double(bytes.size()) / (1 << 20), " MiB");
    return solutionFromBytes(bytes, c.solution);
}

SolveResult solveOrRead(const Scene& scene, const RenderCli& c, SolveCli& s, const CommonOptions& common,
                        int gatherSpp) {
    if (!c.solution.empty()) {
        SolveResult stored = readSolution((std::filesystem::path(c.solution) / "solution.bin").string());
        if (stored.sceneFingerprint != scene.fingerprint)
            throw Error(cat(c.solution, ": this solution was solved for another version of ", c.scene,
                            " (or another scene): solve again"));
        for (int o : stored.patches.object)
            if (o < 0 || size_t(o) >= scene.objects.size()) throw Error(cat(c.solution, ": solution file is damaged"));
        return stored;
    }
    logInfo("no --solution given: solving first");
    SolveOptions options = s.resolved(common);
    // A solve for final-gathered images of few samples need not be quieter than they are
    // (gatherEffortFor); what the command line gives stays.
    if (gatherSpp > 0) {
        const GatherEffort e = gatherEffortFor(gatherSpp);
        std::string chosen;
        if (s.ffNoise->count() == 0 && e.ffNoise != options.formFactors.objectNoise) {
            options.formFactors.objectNoise = e.ffNoise;
            chosen += cat(", --ff-noise ", e.ffNoise);
        }
        if (s.patches->count() == 0 && e.patches < 1 && !(options.refine.tolerance > 0) &&
            !(options.meshing.patchSize > 0)) {
            options.meshing.targetPatches = int(std::lround(options.meshing.targetPatches * e.patches));
            chosen += cat(", --patches ", options.meshing.targetPatches);
        }
        if (s.specularRays->count() == 0 && e.specularPaths < 1 && scene.hasSpecular()) {
            options.specular.pathsPerPatch =
                std::max(1, int(std::lround(options.specular.pathsPerPatch * e.specularPaths)));
            chosen += cat(", --specular-rays ", options.specular.pathsPerPatch);
        }
        if (!chosen.empty())
            logInfo("for images of ", gatherSpp,
                    " samples per pixel, whose own noise hides the solve's below it: ", chosen.substr(2));
    }
    // Nor need its corners show the light at each vertex where the gather reads none of them
    // (SolveOptions::forSolvedIndirectGather): the same image, bit for bit, without the Cornell box's
    // 0.016 s of vertex shadow rays (its 1-spp image took 0.28-0.30 s with them).
    options.forSolvedIndirectGather = gatherSpp > 0 && c.gather.solvedIndirect && s.vertexRadiosity->count() == 0;
    SolveResult r = solveScene(scene, options);
    r.F = FormFactorMatrix();  // views need the radiosity, not the matrix
    return r;
}

int runRender(RenderCli& c, SolveCli& s, const CommonOptions& common) {
    const Scene scene = loadScene(c.scene);
    const Camera camera = cameraFor(scene, c);
    const IntegratorEntry& entry = findIntegrator(c.integrator);
    const std::string& integrator = c.integrator;
    const std::filesystem::path out(c.out);
    const std::string ext = out.extension().string();
    if (ext != ".exr" && ext != ".hdr") throw Error(cat("--out ", c.out, ": expected an .exr or .hdr file name"));
    const int spp = c.spp > 0 ? c.spp : entry.defaultSpp;
    c.gather.solvedIndirect = c.indirect == "solution";
    // Nor need the caustic photons of a final-gathered image of few samples be more (gatherEffortFor).
    if (integrator == "final-gather" && c.photonsOption->count() == 0 && scene.hasSpecular()) {
        const double share = gatherEffortFor(spp).photons;
        if (share < 1) {
            c.photons.photons = std::max<int64_t>(1, std::llround(double(c.photons.photons) * share));
            logInfo("caustic photons: ", c.photons.photons, " for images of ", spp,
                    " samples per pixel, whose own noise hides theirs below it");
        }
    }
    // One camera, or a turntable of them: OUT-000.exr, OUT-001.exr, ... and OUT-orbit.json, each
    // image with its preview; all appear together, or none (output_set.h), and --out is checked now.
    std::vector<std::string> names{out.filename().string()};
    if (c.orbit > 0) {
        names.clear();
        for (int k = 0; k < c.orbit; ++k) {
            char suffix[16];
            std::snprintf(suffix, sizeof suffix, "-%03d", k);
            names.push_back(out.stem().string() + suffix + ext);
        }
    }
    std::vector<std::string> files;
    for (const std::string& name : names) files.insert(files.end(), {name, previewPathFor(name)});
    const std::string orbitList = out.stem().string() + "-orbit.json";
    if (c.orbit > 0) files.push_back(orbitList);
    // Under mpirun every rank renders its share and the leader writes.
    std::optional<OutputSet> outputs;
    if (cluster::leader())
        outputs.emplace(out.parent_path().string(), files, cat(".", out.filename().string(), ".lock"));

    // The geometry: the solve's patches, or (path tracer) the scene meshed as a solve would mesh it.
    SolveResult stored;
    if (!entry.needsSolution) {
        if (!c.solution.empty())
            logInfo("the ", integrator, " integrator needs no solution: --solution ", c.solution, " is not read");
        stored.patches = meshScene(scene, s.options.meshing);
    } else {
        stored = solutionFor(scene, c, s, common, integrator == "final-gather" ? spp : 0);
    }
    std::vector<Camera> cameras{camera};
    if (c.orbit > 0) cameras = orbitCameras(camera, patchesCentre(stored.patches), c.orbit);

    Timer timer;
    const CounterValues before = counterValues();
    const std::vector<Image> images =
        entry.render(RenderInputs{scene, stored.patches, stored.corners, stored.rays, c.gather, c.photons, common.seed,
                                  &stored.solution.display, &stored.indirect},
                     cameras, spp);
    const double seconds = timer.seconds();
    std::string counted;
    for (const auto& [name, value] : countersSince(before))
        if (value > 0) counted += cat(counted.empty() ? "" : ", ", name, " ", value);
    logInfo("render counters: ", counted);

    if (!cluster::leader()) return cluster::barrier(), 0;
    // Everything is rendered before the first file is written.
    std::vector<std::string> paths;  // where the images land, as the orbit list names them
    for (size_t k = 0; k < images.size(); ++k) {
        outputs->write(names[k], [&](const std::string& path) { writeLinearImage(images[k], path); });
        outputs->write(previewPathFor(names[k]),
                       [&](const std::string& path) { writePreviewPng(images[k], path, c.exposure); });
        paths.push_back((out.parent_path() / names[k]).string());
    }
    const std::string list = (out.parent_path() / orbitList).string();
    if (c.orbit > 0)
        outputs->write(orbitList, [&](const std::string& path) {
            writeFileAtomic(path, orbitJson(cameras, paths, scene.sceneUnit()));
        });
    cluster::barrier();  // every rank alive (as the solve's)
    outputs->commit();
    if (c.orbit > 0) {
        logInfo("wrote ", images.size(), " orbit views ", paths.front(), " .. ", paths.back(), " and their cameras in ",
                list, " (", camera.width, "x", camera.height, ", ", integrator, ", ", spp, " spp) in ", seconds, " s");
    } else {
        logInfo("wrote ", c.out, " and ", previewPathFor(c.out), " (", camera.width, "x", camera.height, ", ",
                integrator, ", ", spp, " spp) in ", seconds, " s");
    }
    return 0;
}

int runView(RenderCli& c, SolveCli& s, ViewerOptions& options, const CommonOptions& common) {
    const Scene scene = loadScene(c.scene);
    const Camera camera = cameraFor(scene, c);
    const std::string shot = options.screenshot.empty() ? "" : lowerExtension(options.screenshot);
    if (!options.screenshot.empty() && shot != ".png" && (shot != ".exr" || options.wholeWindow))
        throw Error(cat("--screenshot ", options.screenshot, ": expected a .png file name",
                        options.wholeWindow ? " (the window as shown is 8-bit)" : " (or .exr: linear radiance)"));
    requireDisplay();  // before any solving
    const SolveResult stored = solutionFor(scene, c, s, common, 0);
    if (!c.solution.empty()) {
        std::ifstream report((std::filesystem::path(c.solution) / "report.json").string());
        std::stringstream text;
        text << report.rdbuf();
        options.statistics = summariseReport(text.str());
    }
    if (!options.screenshot.empty()) {
        const std::string parent = std::filesystem::path(options.screenshot).parent_path().string();
        if (!parent.empty()) ensureDirectory(parent);
    }
    releaseHeldLog();  // the window may stay open for long: what led to it, now
    runViewer(scene, stored.patches, stored.corners, stored.solution.display, stored.indirect, camera, options);
    return 0;
}

struct ExportCli {
    std::string dir, out, format, scene, geometry = "auto", holds = "light";
    double stops = 0;
    int lightmap = 0;
};

// The scene file a solve was of: --scene, else the one its report.json names.
std::string solvedSceneFile(const ExportCli& c) {
    if (!c.scene.empty()) return c.scene;
    const std::string report = (std::filesystem::path(c.dir) / "report.json").string();
    std::ifstream in(report);
    nlohmann::json j;
    try {
        if (in) j = nlohmann::json::parse(in);
    } catch (const nlohmann::json::exception&) {
    }
    if (!j.contains("scene") || !j["scene"].contains("file") || !j["scene"]["file"].is_string())
        throw Error(cat(report, ": names no scene file: give --scene"));
    // As given to the solve, else as it was from where the solve ran.
    const std::string given = j["scene"]["file"].get<std::string>();
    if (std::filesystem::exists(given) || !j["scene"].contains("absolute_file") ||
        !j["scene"]["absolute_file"].is_string())
        return given;
    return j["scene"]["absolute_file"].get<std::string>();
}

int runExport(ExportCli c) {
    const std::string ext = std::filesystem::path(c.out).extension().string();
    std::string& format = c.format;
    if (format.empty()) format = ext == ".ply" ? "ply" : (ext == ".glb" || ext == ".gltf") ? "gltf" : "";
    if (format != "gltf" && format != "ply")
        throw Error(cat("--format: expected gltf or ply (or an --out ending in .glb, .gltf or .ply), got '",
                        format.empty() ? ext : format, "'"));
    if (c.geometry != "auto" && c.geometry != "scene" && c.geometry != "patches")
        throw Error(cat("--geometry: expected auto, scene or patches, got '", c.geometry, "'"));
    // The user's own file back, with the light baked in, where the solve was of a glTF file.
    std::string sceneFile;
    if (c.geometry == "scene") {
        sceneFile = solvedSceneFile(c);
    } else if (c.geometry == "auto") {
        try {
            sceneFile = solvedSceneFile(c);
        } catch (const Error&) {  // a solve without its report: the patches
        }
    }
    const bool roundTrip = c.geometry == "scene" || (c.geometry == "auto" && format == "gltf" && isGltfPath(sceneFile));
    if (roundTrip && (format != "gltf" || !isGltfPath(sceneFile)))
        throw Error(cat("--geometry scene: writes the glTF file the scene came from again (", sceneFile,
                        " is not one), as .glb or .gltf"));
    const std::filesystem::path target(c.out);
    const std::string name = target.filename().string();
    OutputSet outputs(target.parent_path().string(), {name}, cat(".", name, ".lock"));
    const SolveResult stored = readSolution((std::filesystem::path(c.dir) / "solution.bin").string());
    if (roundTrip) {
        const Scene scene = loadScene(sceneFile);
        if (scene.fingerprint != stored.sceneFingerprint)
            throw Error(cat(c.dir, ": its solution is not of ", sceneFile, " as it is now (solve it again)"));
        RoundTrip r;
        const LightmapHolds holds = c.holds == "radiance" ? LightmapHolds::Radiance : LightmapHolds::Light;
        outputs.write(name, [&](const std::string& path) {
            r = writeGltfRoundTrip(scene, stored, path, c.stops, c.lightmap, holds);
        });
        outputs.commit();
        logInfo("wrote ", c.out, ": ", sceneFile, "'s ", r.nodes, " nodes, ", r.primitives, " primitives, ", r.vertices,
                " vertices with COLOR_0 = min(1, ", r.exposure, " x irradiance / pi) and _RADIANCE",
                r.meshesCopied ? cat("; ", r.meshesCopied, " meshes placed twice copied") : "",
                r.verticesOffCorners
                    ? cat("; ", r.verticesOffCorners, " vertices off the patch corners took the nearest")
                    : "",
                r.lightmaps ? cat("; ", r.lightmaps, " lightmaps of ", c.lightmap, "^2 texels on TEXCOORD_1, at least ",
                                  r.texelsPerMetre, " texels a metre",
                                  r.texelsMissed ? cat(" (", r.texelsMissed, " texels found no patch: 0)") : "")
                            : "");
        return 0;
    }
    if (c.lightmap > 0) throw Error("--lightmap: only for the round trip of a glTF scene (--geometry scene)");
    const double stops = c.stops;
    // The materials of the scene solved, where it can be found as it was: mirrors and glass then go
    // out as glTF's own materials (else by their radiance, which is black).
    std::optional<Scene> scene;
    try {
        Scene s = loadScene(solvedSceneFile(c));
        if (s.fingerprint == stored.sceneFingerprint)
            scene = std::move(s);
        else
            logInfo("export: ", s.path, " has changed since the solve: mirrors and glass go out by their radiance");
    } catch (const Error& e) {
        logInfo("export: ", e.what(), ": mirrors and glass go out by their radiance");
    }
    ExportMesh mesh = exportMesh(stored.patches, stored.corners, scene ? &*scene : nullptr);
    for (auto& p : mesh.positions) p *= stored.metresPerUnit;  // metres, whatever the scene's size
    const double exposure = exportExposure(mesh, stops);
    outputs.write(name, [&](const std::string& path) {
        if (format == "gltf")
            writeGltf(mesh, path, exposure);
        else
            writePly(mesh, path, exposure);
    });
    outputs.commit();
    logInfo("wrote ", c.out, ": ", mesh.positions.size(), " vertices, ", mesh.triangles.size(),
            " triangles, colours = ", format == "gltf" ? "min(1, " : "sRGB(", exposure, " x radiance)");
    return 0;
}

struct ReferenceCli {
    std::string scene, out;
    ObjectReferenceSettings settings;
    int patches = 3000;
};

// Each object's mean radiosity by path tracing, to a stated standard error: what a solve's
// report.json is measured against (`penumbra compare report.json reference.json`).
int runReference(ReferenceCli& c, const CommonOptions& common) {
    const std::string ext = std::filesystem::path(c.out).extension().string();
    if (ext != ".json") throw Error(cat("--out ", c.out, ": expected a .json file name"));
    if (c.settings.minSamples > c.settings.maxSamples)
        throw Error(cat("--min-points ", c.settings.minSamples, " is above --max-points ", c.settings.maxSamples));
    const Scene scene = loadScene(c.scene);
    const std::filesystem::path target(c.out);
    const std::string name = target.filename().string();
    OutputSet outputs(target.parent_path().string(), {name}, cat(".", name, ".lock"));
    MeshingOptions meshing;
    meshing.targetPatches = c.patches;
    const PatchSet patches = meshScene(scene, meshing);
    const SceneTracer tracer(scene, patches);
    if (!tracer.hasEmitters()) throw Error(cat(c.scene, ": no object emits light: every radiosity is zero"));
    c.settings.seed = common.seed;
    ObjectReferenceSettings inside = c.settings;  // --min-area in the scene's inside units
    inside.minArea /= scene.squareMetresPerUnit();
    Timer timer;
    const std::vector<ObjectEstimate> estimates = pathObjectRadiosity(tracer, inside);
    const double seconds = timer.seconds();
    int64_t points = 0;
    double worst = 0;
    for (const ObjectEstimate& e : estimates) {
        points += e.samples;
        worst = std::max(worst, e.relativeError);
    }
    outputs.write(name, [&](const std::string& path) {
        writeFileAtomic(path, objectReferenceJson(scene, estimates, c.settings, seconds));
    });
    outputs.commit();
    logInfo("wrote ", c.out, ": ", points, " points on ", scene.objects.size(), " objects in ", seconds,
            " s, largest standard error ", 100 * worst, "%");
    return 0;
}

// Two files of report.json's form: each object's mean radiosity, value over reference.
int runCompareObjects(const std::string& valueFile, const std::string& referenceFile) {
    const std::vector<ObjectComparison> rows = compareObjectRadiosity(valueFile, referenceFile);
    if (rows.empty()) throw Error(cat(valueFile, " and ", referenceFile, ": no lit object in both"));
    std::printf("%-28s %9s %12s %12s %8s %13s %7s\n", "object", "area m2", "radiosity", "reference", "ratio",
                "worst channel", "z");
    double worst = 0, areaWithin = 0, area = 0;
    std::string worstName;
    for (const ObjectComparison& r : rows) {
        std::printf("%-28s %9.4g %12.6g %12.6g %8.4f %12.2f%% %7.2f\n", r.name.c_str(), r.area, r.value.sum(),
                    r.reference.sum(), r.ratio, 100 * r.worstChannel, r.z);
        if (std::abs(r.ratio - 1) > worst) {
            worst = std::abs(r.ratio - 1);
            worstName = r.name;
        }
        area += r.area;
        if (std::abs(r.ratio - 1) <= 0.01) areaWithin += r.area;
    }
    std::printf("%zu objects: worst %s %+.2f%%; %.1f%% of the area within 1%%\n", rows.size(), worstName.c_str(),
                100 * worst, area > 0 ? 100 * areaWithin / area : 0.0);
    return 0;
}

// The project's image measure (pooled L1 after a 5x5 blur) and, given the scene, the same per region.
int runCompare(const std::string& imageFile, const std::string& referenceFile, const std::string& sceneFile,
               const std::string& cameraJson) {
    if (std::filesystem::path(imageFile).extension() == ".json") return runCompareObjects(imageFile, referenceFile);
    const Image a = readLinearImage(imageFile), ref = readLinearImage(referenceFile);
    const ImageError raw = compareImages(a, ref), blurred = compareBlurred(a, ref);
    std::printf(
        "pooled L1 after 5x5 box blur %.4f (without blur %.4f); per-pixel relative error %.4f (after blur %.4f); "
        "RMSE %.6g; brightness ratio %.4f\n",
        blurred.pooledL1, raw.pooledL1, raw.meanRelative, blurred.meanRelative, raw.rmse, raw.meanRatio);
    if (sceneFile.empty()) return 0;
    const Scene scene = loadScene(sceneFile);
    RenderCli view;
    view.scene = sceneFile;
    view.camera = cameraJson;
    Camera camera = cameraFor(scene, view);
    camera.width = a.width;
    camera.height = a.height;
    const PatchSet patches = meshScene(scene, MeshingOptions{});
    const SceneTracer tracer(scene, patches);
    ImageRegions regions = objectRegions(tracer, camera);
    if (tracer.hasSpecular()) regions.add("caustic", causticMask(tracer, PhotonMap(tracer, {}), regions));
    std::printf("%-20s %8s %10s %18s\n", "region", "pixels", "mean ratio", "pooled L1 (blur)");
    for (const RegionError& e : compareRegions(a, ref, regions))
        std::printf("%-20s %8d %10.4f %18.4f\n", e.name.c_str(), e.pixels, e.ratio, e.pooledL1);
    return 0;
}

int runBenchCommand(bench::BenchOptions& options, const std::string& resolution) {
    if (!resolution.empty()) std::tie(options.width, options.height) = parseResolution(resolution);
    const bench::BenchResult result = bench::runBench(options);
    // Everything is measured before the first file is written.
    ensureDirectory(options.out);
    const std::filesystem::path dir(options.out);
    writeFileAtomic((dir / "trade.csv").string(), bench::tradeCsv(result.rows));
    writeFileAtomic((dir / "bench.json").string(), bench::benchJson(result));
    writeFileAtomic((dir / "summary.md").string(), bench::summaryMarkdown(result));
    const bool plotted = bench::writePlots(result, options.out);
    logInfo("wrote ", (dir / "trade.csv").string(), " (", result.rows.size(), " runs), bench.json, summary.md",
            plotted ? ", error-time.png and cost-patches.png" : " (no plots)");
    return 0;
}

}  // namespace

// An error under mpirun: one rank's alone would leave the others waiting for it, so the job ends
// (cluster::abortJob). The leader says it; another rank first gives the leader two seconds, in which an
// error that every rank meets (a bad scene) ends the job with the leader's message alone.
int failed(const std::string& message, int code) {
    if (!cluster::distributed()) {
        std::fprintf(stderr, "penumbra: %s\n", message.c_str());
        return code;
    }
    if (!cluster::leader()) std::this_thread::sleep_for(std::chrono::seconds(2));
    cluster::abortJob(cluster::leader() ? message : cat(cluster::rankName(cluster::rank()), ": ", message), code);
}

int main(int argc, char** argv) {
    cluster::start(&argc, &argv);  // under mpirun: joins the job (core/cluster.h)
    CLI::App app{"penumbra: global illumination by radiosity, photon mapping and final gathering"};
    app.require_subcommand(1);
    CommonOptions common;
    app.add_option("--threads", common.threads, "Threads (0: all cores)")->check(kThreads);
    app.add_flag("--quiet,-q", common.quiet, "Warnings and errors only");
    app.add_flag("--verbose,-v", common.verbose, "Debug output");
    app.add_flag("--progress", common.progress, "Progress bars even when stderr is not a terminal (under mpirun)");
    app.add_option("--seed", common.seed, "Random seed (results are reproducible for a seed)");

    SolveCli solve;
    CLI::App* solveCmd = app.add_subcommand("solve", "View-independent radiosity solve");
    solveCmd->add_option("scene", solve.scene, "Scene JSON file")->required();
    solveCmd->add_option("--out", solve.out, "Output directory (report.json, solution.bin, ...)")->required();
    solveCmd->add_flag("--resume", solve.resume,
                       "Carry on from the checkpoint a killed solve left in --out (same scene, settings and build)");
    solveCmd->add_option("--view-spp", solve.viewSpp, "Samples per pixel of the radiosity picture")
        ->capture_default_str();
    addSolveOptions(solveCmd, solve);

    RenderCli render;
    SolveCli renderSolve;
    CLI::App* renderCmd = app.add_subcommand("render", "Render an image of the (solved) scene");
    renderCmd->add_option("scene", render.scene, "Scene JSON file")->required();
    renderCmd->add_option("--out", render.out, "Output image (.exr or .hdr); a .png preview is written beside it")
        ->required();
    renderCmd->add_option("--solution", render.solution, "Directory of a previous solve to reuse");
    std::string integratorHelp, sppHelp;
    for (const IntegratorEntry& e : integrators()) {
        integratorHelp += cat(integratorHelp.empty() ? "" : "; ", e.name, ": ", e.summary);
        sppHelp += cat(sppHelp.empty() ? "" : ", ", e.name, " ", e.defaultSpp);
    }
    renderCmd->add_option("--integrator", render.integrator, integratorHelp)->capture_default_str();
    renderCmd->add_option("--spp", render.spp, cat("Samples per pixel (default: ", sppHelp, ")"))
        ->check(inRange(1, 1 << 20));
    renderCmd
        ->add_option("--direct-samples", render.gather.directSamples, "Final gather: emitter samples per camera sample")
        ->capture_default_str()
        ->check(inRange(1, 4096));
    renderCmd
        ->add_option("--indirect", render.indirect,
                     "Final gather: solution: the solve's indirect light read where the camera looks, with the small "
                     "sources' direct light in closed form times shadow rays at each point (no gather rays; the "
                     "fast path); gather: gathered with rays at every point (as it is anyway where the solve "
                     "holds none: the hierarchy, or lamps that are not small)")
        ->capture_default_str()
        ->check(CLI::IsMember({"solution", "gather"}));
    renderCmd->add_option("--gather-rays", render.gather.gatherRays, "Final gather: gather rays per camera sample")
        ->capture_default_str()
        ->check(inRange(1, 65536));
    renderCmd
        ->add_option("--close-factor", render.gather.closeFactor,
                     "Final gather: hits nearer than this many patch radii are shaded one bounce deeper")
        ->capture_default_str()
        ->check(inRange(0.0, 1000.0));
    render.photonsOption = renderCmd->add_option("--photons", render.photons.photons, "Caustic photons emitted");
    render.photonsOption->capture_default_str()->check(inRange(1, double(int64_t(1) << 34)));
    renderCmd
        ->add_option("--photon-aim", render.photons.aim,
                     "Aim the caustic photons at spheres around the mirrors and glass (only those count; false: "
                     "emit them over the lamps' whole hemispheres)")
        ->capture_default_str();
    renderCmd->add_option("--photon-k", render.photons.nearest, "Photons per caustic density estimate")
        ->capture_default_str()
        ->check(inRange(1, 100000));
    renderCmd
        ->add_option("--photon-precompute", render.photons.precompute,
                     "Precompute the caustic estimate at every Nth stored photon (0: estimate at every lookup)")
        ->capture_default_str()
        ->check(inRange(0, 1000000));
    renderCmd->add_option("--max-depth", render.gather.maxSpecularDepth, "Mirror and glass bounces per path")
        ->capture_default_str()
        ->check(inRange(0, 1000));
    renderCmd->add_option("--resolution", render.resolution, "WIDTHxHEIGHT, overrides the camera's");
    renderCmd->add_option("--camera", render.camera, "Camera as JSON, overrides the scene's");
    renderCmd
        ->add_option(
            "--orbit", render.orbit,
            "Render N views on a circle around the scene's centre (OUT-000.exr, ...; cameras in OUT-orbit.json)")
        ->check(inRange(1, 100000));
    renderCmd->add_option("--exposure", render.exposure, "Exposure of the PNG preview, in stops");
    addSolveOptions(renderCmd, renderSolve);

    ExportCli exportCli;
    CLI::App* exportCmd = app.add_subcommand(
        "export", "Export a solved scene with per-vertex light: a glTF scene's own file back, else the patches");
    exportCmd->add_option("solution", exportCli.dir, "Directory of a solve")->required();
    exportCmd->add_option("--out", exportCli.out, "Output file (.glb, .gltf or .ply)")->required();
    exportCmd->add_option("--format", exportCli.format, "gltf | ply (default: from the --out extension)");
    exportCmd->add_option("--exposure", exportCli.stops, "Exposure of the colours, in stops from the automatic one");
    exportCmd->add_option("--geometry", exportCli.geometry,
                          "auto | scene | patches: the glTF file the scene came from with COLOR_0 on its own "
                          "vertices (auto: for glTF scenes), or the solved patches");
    exportCmd->add_option("--scene", exportCli.scene, "The scene file solved (default: the one report.json names)");
    exportCmd
        ->add_option("--lightmap", exportCli.lightmap,
                     "Also a SIZE x SIZE lightmap per primitive on TEXCOORD_1 (the round trip of a glTF scene)")
        ->check(inRange(1, 16384));
    exportCmd
        ->add_option("--lightmap-holds", exportCli.holds,
                     "light | radiance: the lightmap's texels hold the light E/pi, as COLOR_0 (default; times the "
                     "base colour and texture at their own resolution), or the radiance, texture and emission "
                     "baked in")
        ->check(CLI::IsMember({"light", "radiance"}));

    std::string compareImage, compareReference, compareScene, compareCamera;
    CLI::App* compareCmd = app.add_subcommand("compare", "Compare an image with a reference (e.g. a path-traced one)");
    compareCmd->add_option("image", compareImage, "Image (.exr or .hdr), or a report.json")->required();
    compareCmd
        ->add_option("reference", compareReference,
                     "Reference image of the same size, or (for a report.json) a `penumbra reference` file or "
                     "another report.json: each object's mean radiosity")
        ->required();
    compareCmd->add_option(
        "--scene", compareScene,
        "The scene both images show: also compare each region (every object seen, their groups, the caustic)");
    compareCmd->add_option("--camera", compareCamera, "With --scene: the camera of the images, if not the scene's");

    ReferenceCli reference;
    CLI::App* referenceCmd = app.add_subcommand(
        "reference", "Each object's mean radiosity by path tracing, to a stated noise (a reference for solves)");
    referenceCmd->add_option("scene", reference.scene, "Scene JSON file")->required();
    referenceCmd->add_option("--out", reference.out, "Output file (.json, report.json's form)")->required();
    referenceCmd
        ->add_option("--error", reference.settings.targetError,
                     "Sample each object until its standard error is below this share of its mean")
        ->capture_default_str()
        ->check(inRange(1e-5, 1.0));
    referenceCmd->add_option("--min-points", reference.settings.minSamples, "Points on each object at least")
        ->capture_default_str()
        ->check(inRange(1, double(int64_t(1) << 40)));
    referenceCmd->add_option("--max-points", reference.settings.maxSamples, "Points on each object at most")
        ->capture_default_str()
        ->check(inRange(1, double(int64_t(1) << 40)));
    referenceCmd
        ->add_option("--min-area", reference.settings.minArea,
                     "Estimate only the objects of at least this area, m^2 (a large scene's walls and floors)")
        ->capture_default_str()
        ->check(inRange(0.0, 1e30));
    referenceCmd
        ->add_option("--patches", reference.patches,
                     "Patches the geometry is meshed into (only curved objects depend on it)")
        ->capture_default_str()
        ->check(inRange(1, 100000000));

    CLI::App* viewCmd = app.add_subcommand("view", "Browse a solved scene interactively");
    RenderCli view;
    SolveCli viewSolve;
    ViewerOptions viewer;
    viewCmd->add_option("scene", view.scene, "Scene JSON file")->required();
    viewCmd->add_option("--solution", view.solution, "Directory of a previous solve (default: solve first)");
    viewCmd->add_option("--camera", view.camera, "Starting camera as JSON, overrides the scene's");
    viewCmd->add_option("--resolution", view.resolution, "Window size WIDTHxHEIGHT (default: the camera's)");
    viewCmd->add_option("--exposure", viewer.exposureStops, "Exposure, in stops from the automatic one");
    viewCmd->add_option("--screenshot", viewer.screenshot,
                        "Draw --frames frames from the camera, save the last to this PNG (or EXR: linear radiance) "
                        "and exit");
    viewCmd->add_option("--frames", viewer.frames, "Frames drawn before --screenshot")
        ->capture_default_str()
        ->check(inRange(1, 100000));
    viewCmd
        ->add_option("--gather-passes", viewer.gatherPasses,
                     "With --screenshot: save the in-window final gather after this many passes instead")
        ->check(inRange(1, 1 << 20));
    viewCmd->add_flag("--screenshot-window", viewer.wholeWindow,
                      "With --screenshot: save the window as shown, panel included");
    viewCmd
        ->add_option("--occlusion-culling", viewer.occlusionCulling,
                     "Leave out what the scene's walls hide: auto (in scenes of more than 20,000 triangles, where "
                     "it pays), on, or off (to check that it changes nothing)")
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "on", "off"}));
    addSolveOptions(viewCmd, viewSolve);

    bench::BenchOptions benchOptions;
    std::string benchResolution;
    CLI::App* benchCmd =
        app.add_subcommand("bench", "Measure the speed-accuracy trade of a scene and this machine's limits");
    benchCmd->add_option("scene", benchOptions.scene, "Scene JSON file (with a camera)")->required();
    benchCmd->add_option("--out", benchOptions.out, "Output directory (trade.csv, summary.md, plots)")->required();
    benchCmd->add_flag("--quick", benchOptions.quick, "A one-minute version: fewer, smaller runs");
    benchCmd
        ->add_option("--only", benchOptions.only,
                     "Just these sweeps and the defaults (patches, adaptive, hierarchical, spp, path, ...)")
        ->delimiter(',');
    benchCmd->add_option("--resolution", benchResolution,
                         "WIDTHxHEIGHT of the images compared (default 256 wide, quick 64)");
    benchCmd
        ->add_option("--reference-spp", benchOptions.referenceSpp,
                     "Samples per pixel of the path-traced reference (default 4096, quick 1024)")
        ->check(inRange(1, 1 << 24));
    benchCmd->add_option("--cache", benchOptions.cache, "Folder for cached references (default ~/.cache/penumbra)");

    for (CLI::App* cmd : {solveCmd, renderCmd, viewCmd, exportCmd, benchCmd, referenceCmd}) {
        cmd->add_option("--threads", common.threads, "Threads (0: all cores)")->check(kThreads);
        cmd->add_flag("--quiet,-q", common.quiet, "Warnings and errors only");
        cmd->add_flag("--verbose,-v", common.verbose, "Debug output");
        cmd->add_flag("--progress", common.progress,
                      "Progress bars even when stderr is not a terminal (under mpirun: rank 0's, for the whole job)");
        cmd->add_option("--seed", common.seed, "Random seed");
    }

    requireFiniteNumbers(app);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        // Help and version go out as CLI11 prints them; a bad option is one error line, exit 2.
        if (e.get_exit_code() == 0) return cluster::leader() ? app.exit(e) : 0;
        if (cluster::leader()) std::fprintf(stderr, "penumbra: error: %s (see --help)\n", e.what());
        cluster::stop();
        return 2;
    }
    try {
        setupLogging(common);
        installSignalCleanup();
        holdLog();  // a refusal in the first second prints the error alone (core/log.h)
        logRanks();
        const int status = [&] {
            if (*solveCmd) return runSolve(solve, common);
            if (*renderCmd) return runRender(render, renderSolve, common);
            if (*exportCmd) return onLeader("export", [&] { return runExport(exportCli); });
            if (*compareCmd)
                return onLeader(
                    "compare", [&] { return runCompare(compareImage, compareReference, compareScene, compareCamera); });
            if (*viewCmd) return onLeader("view", [&] { return runView(view, viewSolve, viewer, common); });
            if (*referenceCmd) return onLeader("reference", [&] { return runReference(reference, common); });
            if (*benchCmd)
                return onLeader("bench", [&] {
                    benchOptions.seed = common.seed;
                    return runBenchCommand(benchOptions, benchResolution);
                });
            return 0;
        }();
        releaseHeldLog();
        if (cluster::distributed())
            logInfo("mpirun: rank 0 sent ", double(cluster::bytesSent()) / (1 << 20), " MiB to the other ranks");
        cluster::stop();
        return status;
    } catch (const Error& e) {
        dropHeldLog();
        return failed(cat("error: ", e.what()), 1);
    } catch (const std::bad_alloc&) {
        dropHeldLog();
        return failed("error: out of memory (lower --patches or the resolution)", 1);
    } catch (const std::exception& e) {
        releaseHeldLog();  // what led to an internal error
        return failed(cat("internal error: ", e.what()), 70);
    }
}
