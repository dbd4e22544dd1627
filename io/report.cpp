#include "io/report.h"

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/parallel.h"

namespace penumbra {
namespace {
nlohmann::json rgbJson(const Rgb& c) { return nlohmann::json::array({c[0], c[1], c[2]}); }
}  // namespace

std::string orbitJson(const std::vector<Camera>& cameras, const std::vector<std::string>& images, double unitScale) {
    nlohmann::json views = nlohmann::json::array();
    auto point = [&](const Vec3& p) {
        return nlohmann::json::array({p.x() / unitScale, p.y() / unitScale, p.z() / unitScale});
    };
    for (size_t k = 0; k < cameras.size(); ++k) {
        const Camera& c = cameras[k];
        views.push_back({{"image", images[k]},
                         {"camera",
                          {{"position", point(c.position)},
                           {"look_at", point(c.lookAt)},
                           {"up", {c.up.x(), c.up.y(), c.up.z()}},
                           {"fov_y_deg", c.fovYDeg},
                           {"resolution", {c.width, c.height}}}}});
    }
    return nlohmann::json{{"views", views}}.dump(2) + "\n";
}

std::string summariseReport(const std::string& text) {
    const nlohmann::json r = nlohmann::json::parse(text, nullptr, false);
    if (r.is_discarded() || !r.contains("solver") || !r.contains("totals")) return "";
    auto sum = [&](const char* key) {
        double s = 0;
        for (const auto& v : r["totals"][key]) s += v.get<double>();
        return s;
    };
    const auto& solver = r["solver"];
    return cat(solver.value("name", std::string("?")), ": ", solver.value("patches", 0), " patches, ",
               solver.value("iterations", 0), " iterations, residual ", solver.value("residual", 0.0), "\n", "emitted ",
               sum("emitted_power_w"), " W = absorbed ", sum("absorbed_power_w"), " W + escaped ",
               sum("escaped_power_w"), " W");
}

std::string reportJson(const Scene& scene, const SolveResult& r, double peakMemory) {
    using Json = nlohmann::json;
    const size_t objects = scene.objects.size();
    std::vector<double> area(objects, 0.0);
    const std::vector<Rgb> radiosity = objectRadiosity(r, objects);
    std::vector<Rgb> emitted(objects, Rgb::Zero()), absorbed(objects, Rgb::Zero());
    std::vector<int> patchCount(objects, 0);
    for (size_t i = 0; i < r.patches.size(); ++i) {
        const size_t o = size_t(r.patches.object[i]);
        area[o] += r.patches.area[i];
        emitted[o] += r.power.emitted[i];
        absorbed[o] += r.power.absorbed[i];
        ++patchCount[o];
    }
    // Inside units to m^2 and W (Scene::metresPerUnit; 1 for all but the tiniest and largest scenes).
    const double m2 = scene.squareMetresPerUnit();
    Json report;
    Json& objs = report["objects"];
    objs = Json::object();
    for (size_t o = 0; o < objects; ++o) {
        Json entry;
        entry["area_m2"] = area[o] * m2;
        entry["radiosity_mean"] = rgbJson(radiosity[o]);
        entry["emitted_power_w"] = rgbJson(emitted[o] * m2);
        entry["absorbed_power_w"] = rgbJson(absorbed[o] * m2);
        entry["patches"] = patchCount[o];
        // Ray-cast form factors: the estimated standard error of radiosity_mean over it (solve.h).
        if (r.objectNoise.size() == objects) entry["relative_error_estimate"] = r.objectNoise[o];
        objs[scene.objects[o].name] = entry;
    }
    report["totals"] = {{"emitted_power_w", rgbJson(r.power.totalEmitted * m2)},
                        {"absorbed_power_w", rgbJson(r.power.totalAbsorbed * m2)},
                        {"escaped_power_w", rgbJson(r.power.escaped * m2)}};
    report["solver"] = {
        {"name", r.solverName},
        {"patches", r.patches.size()},
        {"iterations", r.solution.iterations},
        {"residual", r.solution.residual},
        {"converged", r.solution.converged},
        {"threads", threadCount()},
        {"seconds",
         {{"meshing", r.secondsMeshing},
          {"form_factors", r.secondsFormFactors},
          {"specular_transport", r.secondsSpecular},
          {"solve", r.secondsSolve},
          {"vertex_radiosity", r.secondsVertices}}},
        {"transfers",
         {{"back_face", r.F.backTransfers.size()},
          {"specular", r.system.transport.outTarget.size()},
          {"specular_unresolved_share", r.system.transport.unresolvedShare}}},
        {"form_factor_row_sum", {{"min", r.rowSumMin}, {"max", r.rowSumMax}}},
        {"closed_scene", r.closedScene},
        // With row blocks (docs/distributed.md), what rank 0 held: one block of this many.
        {"matrix_mib", double(r.F.bytes()) / (1 << 20)},
        {"matrix_row_blocks", r.F.inRowBlocks() ? r.F.rowBlocks().size() - 1 : 0},
        {"peak_memory_mib", peakMemory / (1 << 20)},
    };
    if (!r.solverReason.empty()) report["solver"]["chosen_because"] = r.solverReason;
    if (!r.formFactorMethod.empty()) report["solver"]["form_factors"] = r.formFactorMethod;
    if (!r.formFactorReason.empty()) report["solver"]["form_factors_chosen_because"] = r.formFactorReason;
    // Every named counter (core/counters.h), as the solve changed it: the one place they are read.
    Json& counters = report["solver"]["counters"];
    counters = Json::object();
    for (const auto& [name, value] : r.counters) counters[name] = value;
    if (r.solverName == "hierarchical") {
        const HierarchyStats& h = r.hierarchy;
        report["solver"]["hierarchy"] = {
            {"roots", h.roots},
            {"elements", h.elements},
            {"leaves", h.leaves},
            {"links", h.links},
            {"partly_visible_links", h.partlyVisibleLinks},
            {"rounds", h.rounds},
            {"storage_mib", h.bytes / (1 << 20)},
            {"matrix_of_as_many_patches_mib", double(formFactorMatrixBytes(h.leaves)) / (1 << 20)}};
    }
    if (!r.refinement.empty()) {
        Json rounds = Json::array();
        for (const RefineRound& round : r.refinement)
            rounds.push_back({{"patches", round.patches},
                              {"split", round.split},
                              {"marked_by_gradient", round.byGradient},
                              {"marked_by_shadow", round.byShadow},
                              {"seconds_so_far", round.secondsSoFar}});
        report["solver"]["refinement"] = rounds;
    }
    report["scene"] = {{"file", scene.path},
                       {"absolute_file", std::filesystem::absolute(scene.path).lexically_normal().string()},
                       {"unit_scale", scene.unitScale},
                       {"inside_metres_per_unit", scene.metresPerUnit}};
    // How the result was made: every setting of the solve, and the seed (a rerun with these gives
    // the same report, whatever the thread count).
    SolveOptions o = r.options;
    Json& settings = report["settings"];
    settings = {
        {"seed", o.formFactors.seed},
        {"form_factors", o.formFactors.method},
        {"solver", o.solver},
        {"vertex_radiosity", o.vertexRadiosity},
        {"max_memory_gib", o.maxMemoryBytes / double(1ull << 30)},
        {"threads", threadCount()},
    };
    for (const SolveSetting& e : solveSettings(o))
        settings[e.key] = std::visit([](auto* v) { return Json(*v); }, e.value);
    return report.dump(2) + "\n";
}

std::string objectReferenceJson(const Scene& scene, const std::vector<ObjectEstimate>& estimates,
                                const ObjectReferenceSettings& settings, double seconds) {
    using Json = nlohmann::json;
    Json out;
    Json& objs = out["objects"];
    objs = Json::object();
    int64_t points = 0;
    for (size_t o = 0; o < estimates.size(); ++o) {
        const ObjectEstimate& e = estimates[o];
        if (e.samples == 0) continue;
        points += e.samples;
        objs[scene.objects[o].name] = {{"area_m2", e.area * scene.squareMetresPerUnit()},
                                       {"radiosity_mean", rgbJson(e.radiosity)},
                                       {"std_error", rgbJson(e.stdError)},
                                       {"relative_error", e.relativeError},
                                       {"points", e.samples}};
    }
    out["reference"] = {{"method", "path tracing from uniform points on each object (NEE + MIS)"},
                        {"points", points},
                        {"seconds", seconds},
                        {"threads", threadCount()}};
    out["scene"] = {{"file", scene.path},
                    {"absolute_file", std::filesystem::absolute(scene.path).lexically_normal().string()},
                    {"unit_scale", scene.unitScale}};
    out["settings"] = {{"seed", settings.seed},
                       {"target_error", settings.targetError},
                       {"min_points", settings.minSamples},
                       {"max_points", settings.maxSamples},
                       {"min_area_m2", settings.minArea}};
    return out.dump(2) + "\n";
}

std::vector<ObjectComparison> compareObjectRadiosity(const std::string& valueFile, const std::string& referenceFile) {
    using Json = nlohmann::json;
    auto objectsOf = [](const std::string& file) {
        std::ifstream in(file);
        if (!in) throw Error(cat(file, ": cannot open"));
        Json j = Json::parse(in, nullptr, false);
        if (j.is_discarded() || !j.contains("objects") || !j["objects"].is_object())
            throw Error(cat(file, ": not a report.json or reference file (no \"objects\")"));
        return j["objects"];
    };
    const Json values = objectsOf(valueFile), refs = objectsOf(referenceFile);
    auto rgbOf = [](const Json& entry, const char* key, const std::string& file, const std::string& name) {
        const Json* v = entry.contains(key) ? &entry[key] : nullptr;
        if (!v || !v->is_array() || v->size() != 3 || !(*v)[0].is_number() || !(*v)[1].is_number() ||
            !(*v)[2].is_number())
            throw Error(cat(file, ": object ", name, ": ", key, " is not three numbers"));
        return Rgb((*v)[0].get<double>(), (*v)[1].get<double>(), (*v)[2].get<double>());
    };
    std::vector<ObjectComparison> out;
    for (const auto& [name, ref] : refs.items()) {
        if (!values.contains(name)) continue;
        ObjectComparison c;
        c.name = name;
        c.reference = rgbOf(ref, "radiosity_mean", referenceFile, name);
        c.value = rgbOf(values[name], "radiosity_mean", valueFile, name);
        c.area = ref.value("area_m2", 0.0);
        if (!(c.reference.sum() > 0)) continue;
        c.ratio = c.value.sum() / c.reference.sum();
        // Channels lit to at least a hundredth of the brightest: a red wall's blue is noise.
        for (int k = 0; k < 3; ++k)
            if (c.reference[k] > 0.01 * c.reference.maxCoeff())
                c.worstChannel = std::max(c.worstChannel, std::abs(c.value[k] / c.reference[k] - 1));
        const double relative = ref.value("relative_error", 0.0);
        if (relative > 0) c.z = (c.value.sum() - c.reference.sum()) / (relative * c.reference.sum());
        out.push_back(c);
    }
    return out;
}

std::string convergenceCsv(const SolveResult& r) {
    std::string csv = "iteration,residual,seconds\n";
    for (const auto& step : r.solution.history) csv += cat(step.iteration, ",", step.residual, ",", step.seconds, "\n");
    return csv;
}

}  // namespace penumbra
