// Google Benchmark timings of the inner kernels: the unoccluded form-factor kernel, the dense
// sweeps (with bytes per second, to set against the memory bandwidth), a visibility ray, the
// caustic photon map's k-nearest query and one final-gather shading point. Scenes come from
// scenes/; each fixture is built once. Run: ./build/bin/penumbra-kernels [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include <map>
#include <memory>

#include "core/log.h"
#include "core/rng.h"
#include "mesh/scene.h"
#include "render/final_gather.h"
#include "render/photon_map.h"
#include "solver/radiosity/form_factor_kernel.h"
#include "solver/radiosity/ray_form_factors.h"
#include "solver/radiosity/system.h"
#include "solver/solve.h"
#include "solver/tracer.h"

namespace penumbra {
namespace {

const Scene& sceneNamed(const char* name) {
    static std::map<std::string, std::unique_ptr<Scene>> scenes;
    auto& s = scenes[name];
    if (!s) {
        setLogLevel(LogLevel::Warning);
        s = std::make_unique<Scene>(loadScene(std::string(PENUMBRA_SOURCE_DIR) + "/scenes/" + name));
    }
    return *s;
}

// The Cornell box solved at 1000 patches, with its final gather.
struct SolvedBox {
    SolveResult solve;
    std::unique_ptr<SolvedScene> view;
    SolvedBox() {
        SolveOptions o;
        o.meshing.targetPatches = 1000;
        solve = solveScene(sceneNamed("cornell-box.json"), o);
        view = std::make_unique<SolvedScene>(sceneNamed("cornell-box.json"), solve.patches, solve.solution.display,
                                             GatherSettings{}, PhotonSettings{}, 1);
    }
};
SolvedBox& solvedBox() {
    static SolvedBox box;
    return box;
}

// Pairs of the Cornell box at 1000 patches that face each other, as the form-factor stage meets them.
void BM_FormFactorKernel(benchmark::State& state) {
    const PatchSet& p = solvedBox().solve.patches;
    const CubatureSettings settings;
    std::vector<std::pair<size_t, size_t>> pairs;
    for (Rng rng(7); pairs.size() < 20000;) {
        const size_t i = rng.next() % p.size(), j = rng.next() % p.size();
        if (p.normal[i].dot(p.centroid[j] - p.centroid[i]) > 0 && p.normal[j].dot(p.centroid[i] - p.centroid[j]) > 0)
            pairs.emplace_back(p.area[i] <= p.area[j] ? i : j, p.area[i] <= p.area[j] ? j : i);
    }
    uint64_t evaluations = 0;
    size_t k = 0;
    for (auto _ : state) {
        const auto [i, j] = pairs[k++ % pairs.size()];
        benchmark::DoNotOptimize(unoccludedAreaFactors(p, i, j, settings, &evaluations));
    }
    state.counters["evaluations/pair"] = double(evaluations) / double(state.iterations());
    state.SetItemsProcessed(int64_t(state.iterations()));
}
BENCHMARK(BM_FormFactorKernel);

void BM_VisibilityRay(benchmark::State& state) {
    const SolveResult& s = solvedBox().solve;
    const PatchSet& p = s.patches;
    Rng rng(11);
    prepareTracingThread();
    for (auto _ : state) {
        const size_t i = rng.next() % p.size(), j = rng.next() % p.size();
        benchmark::DoNotOptimize(
            s.rays->occluded(p.centroid[i] + 1e-4 * p.normal[i], p.centroid[j] + 1e-4 * p.normal[j]));
    }
    state.SetItemsProcessed(int64_t(state.iterations()));
}
BENCHMARK(BM_VisibilityRay);

// The form-factor stage's ray casting on the Cornell box's default mesh (3,204 patches), 144 rays a
// patch, each ray's landing point noted for the reading: rays per second, to set against
// BM_VisibilityRay's and the bench's Embree-alone rate. Argument 1: with the lamp's exact columns
// (the default), 0: rays alone.
void BM_CastFormFactors(benchmark::State& state) {
    static const Scene& scene = sceneNamed("cornell-box.json");
    static const PatchSet patches = meshScene(scene, {});
    static const auto rays = buildRayScene(scene, patches);
    static const RadiositySystem system = buildSystem(scene, patches);
    const std::vector<char> analytic = state.range(0) ? smallSources(system) : std::vector<char>{};
    std::vector<char> emitting(patches.size(), 0);
    for (size_t i = 0; i < patches.size(); ++i) emitting[i] = system.emission[i].maxCoeff() > 0;
    FormFactorSettings settings;
    uint64_t cast = 0;
    for (auto _ : state) {
        HitReadings readings;
        const FormFactorMatrix F = castFormFactors(patches, *rays, settings, analytic, emitting, &readings);
        benchmark::DoNotOptimize(F.entries());
        cast += uint64_t(patches.size()) * uint64_t(settings.raysPerPatch);
    }
    state.counters["rays/s"] = benchmark::Counter(double(cast), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_CastFormFactors)->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond)->UseRealTime();

// A random matrix of n x n (rows summing to 0.9) and its system, for the sweeps.
struct Sweep {
    FormFactorMatrix F;
    RadiositySystem s;
    std::vector<Rgb> B;
    explicit Sweep(size_t n) : F(n), B(n, Rgb(0.1, 0.2, 0.3)) {
        Rng rng(3);
        for (size_t i = 0; i < n; ++i)
            for (size_t j = 0; j < n; ++j) F(i, j) = float(rng.uniform() * 1.8 / double(n));
        s.area.assign(n, 1.0);
        s.reflectance.assign(n, Rgb(0.7, 0.5, 0.3));
        s.emission.assign(n, Rgb::Zero());
    }
};

void BM_JacobiSweep(benchmark::State& state) {
    Sweep w(size_t(state.range(0)));
    for (auto _ : state) benchmark::DoNotOptimize(gatherIrradiance(w.s, w.F, w.B));
    state.SetBytesProcessed(int64_t(state.iterations()) * state.range(0) * state.range(0) * int64_t(sizeof(float)));
}
BENCHMARK(BM_JacobiSweep)->Arg(1000)->Arg(4000)->Arg(8000)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_GaussSeidelSweep(benchmark::State& state) {
    Sweep w(size_t(state.range(0)));
    for (auto _ : state) gaussSeidelPass(w.s, w.F, w.B);
    state.SetBytesProcessed(int64_t(state.iterations()) * state.range(0) * state.range(0) * int64_t(sizeof(float)));
}
BENCHMARK(BM_GaussSeidelSweep)->Arg(1000)->Arg(4000)->Arg(8000)->Unit(benchmark::kMillisecond)->UseRealTime();

// cornell-glass with 1 M caustic photons; queries at random points of the floor.
void BM_PhotonQuery(benchmark::State& state) {
    static const Scene& scene = sceneNamed("cornell-glass.json");
    static const PatchSet patches = meshScene(scene, {});
    static const SceneTracer tracer(scene, patches);
    static const PhotonMap map(tracer, PhotonSettings{});
    int floor = 0;
    for (size_t o = 0; o < scene.objects.size(); ++o)
        if (scene.objects[o].name == "floor") floor = int(o);
    std::vector<size_t> floorPatches;
    for (size_t i = 0; i < patches.size(); ++i)
        if (patches.object[i] == floor) floorPatches.push_back(i);
    Rng rng(5);
    for (auto _ : state) {
        const size_t i = floorPatches[rng.next() % floorPatches.size()];
        const Vec3 x = samplePatchPoint(patches, i, rng.uniform(), rng.uniform(), rng.uniform());
        benchmark::DoNotOptimize(map.irradiance(x, patches.normal[i]));
    }
    state.SetItemsProcessed(int64_t(state.iterations()));
}
BENCHMARK(BM_PhotonQuery);

// One shading point of the Cornell box's final gather (4 emitter samples, 16 gather rays).
void BM_GatherPoint(benchmark::State& state) {
    SolvedBox& box = solvedBox();
    const FinalGather& gather = box.view->gather();
    const PatchSet& p = box.solve.patches;
    Rng rng(9);
    prepareTracingThread();
    for (auto _ : state) {
        const size_t i = rng.next() % p.size();
        SurfaceHit hit;
        hit.found = true;
        hit.point = samplePatchPoint(p, i, rng.uniform(), rng.uniform(), rng.uniform());
        hit.normal = p.normal[i];
        hit.patch = int(i);
        hit.object = p.object[i];
        hit.material =
            &sceneNamed("cornell-box.json").materialOf(sceneNamed("cornell-box.json").objects[size_t(p.object[i])]);
        benchmark::DoNotOptimize(gather.reflected(hit, rng, 0));
    }
    state.SetItemsProcessed(int64_t(state.iterations()));
}
BENCHMARK(BM_GatherPoint);

}  // namespace
}  // namespace penumbra

BENCHMARK_MAIN();
