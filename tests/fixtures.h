// Test helpers: scenes written from JSON text into a temporary folder and loaded through the real
// loader, and sums of patch-level results per object.
#pragma once

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/error.h"
#include "mesh/scene.h"
#include "solver/radiosity/escape.h"
#include "solver/solve.h"
#include "solver/tracer.h"

namespace penumbra::test {

// True in the AddressSanitizer build, which runs every test 5-15 times slower: the heaviest quick
// tests take smaller sizes there (memory errors do not need big scenes to show).
#ifdef PENUMBRA_SANITIZED
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif

struct CommandResult {
    int status;
    std::string output;  // stderr and stdout together
};

// Runs the penumbra executable with `args` (a shell command line) and collects what it prints;
// `launcher` goes before it (variables, mpirun and its options).
inline CommandResult run(const std::string& args, const std::string& launcher = "") {
    const std::string command = launcher + std::string(PENUMBRA_EXE) + " " + args + " 2>&1";
    FILE* pipe = popen(command.c_str(), "r");
    std::string out;
    std::array<char, 4096> buffer;
    while (size_t n = fread(buffer.data(), 1, buffer.size(), pipe)) out.append(buffer.data(), n);
    const int status = pclose(pipe);
    return {WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status), out};
}

// The test program's scratch folder, removed when it exits (each run left hundreds of megabytes in
// /tmp: 8.8 GB after a few sessions of runs). PENUMBRA_KEEP_TEST_FILES=1 keeps it for a look.
inline std::string tempDir() {
    struct Scratch {
        std::filesystem::path path =
            std::filesystem::temp_directory_path() / ("penumbra-test-" + std::to_string(::getpid()));
        pid_t owner = ::getpid();
        Scratch() { std::filesystem::create_directories(path); }
        ~Scratch() {
            const char* keep = std::getenv("PENUMBRA_KEEP_TEST_FILES");
            std::error_code ignored;  // a folder that cannot be removed stays: nothing to fail for
            if (::getpid() == owner && !(keep && std::string(keep) == "1")) std::filesystem::remove_all(path, ignored);
        }
    };
    static const Scratch scratch;
    return scratch.path.string();
}

inline std::string writeText(const std::string& name, const std::string& text) {
    const std::string path = tempDir() + "/" + name;
    std::ofstream(path) << text;
    return path;
}

inline Scene sceneFromJson(const std::string& json, const std::string& name = "scene.json") {
    return loadScene(writeText(name, json));
}

// Object-to-object form factor F(a -> b) = sum_{i in a, j in b} A_i F(i,j) / A_a.
inline double objectFormFactor(const SolveResult& r, int a, int b) {
    double num = 0, area = 0;
    for (size_t i = 0; i < r.patches.size(); ++i) {
        if (r.patches.object[i] != a) continue;
        area += r.patches.area[i];
        for (size_t j = 0; j < r.patches.size(); ++j)
            if (r.patches.object[j] == b) num += r.patches.area[i] * double(r.F(i, j));
    }
    return num / area;
}

inline SolveResult solve(const std::string& json, int patches, const std::string& solver = "gauss-seidel",
                         double tolerance = 1e-6, const StepObserver& observer = {}) {
    SolveOptions o;
    o.meshing.targetPatches = patches;
    o.solver = solver;
    o.solverSettings.tolerance = tolerance;
    o.solverSettings.maxIterations = 200000;
    return solveScene(sceneFromJson(json), o, observer);
}

// The text of a scene file of the project's scenes/ folder.
inline std::string sceneFile(const std::string& name) {
    std::ifstream in(std::string(PENUMBRA_SOURCE_DIR) + "/scenes/" + name);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Howell C-11: parallel, directly opposed rectangles a x b at distance c.
inline double parallelRectangles(double a, double b, double c) {
    const double X = a / c, Y = b / c;
    return 2 / (kPi * X * Y) *
           (std::log(std::sqrt((1 + X * X) * (1 + Y * Y) / (1 + X * X + Y * Y))) +
            X * std::sqrt(1 + Y * Y) * std::atan(X / std::sqrt(1 + Y * Y)) +
            Y * std::sqrt(1 + X * X) * std::atan(Y / std::sqrt(1 + X * X)) - X * std::atan(X) - Y * std::atan(Y));
}

// A unit cube of six inward-facing quads of material "m", except the top, of material `top`.
// `materials` is the body of the "materials" object; `extra` (objects, each with a leading comma)
// and `tail` (more top-level keys, with a leading comma) are appended as given.
inline std::string cubeScene(const std::string& materials, const std::string& top = "m", const std::string& extra = "",
                             const std::string& tail = "") {
    return R"({"materials": {)" + materials + R"(},
      "objects": [
        {"name": "bottom", "type": "quad", "material": "m", "vertices": [[0,0,0],[0,0,1],[1,0,1],[1,0,0]]},
        {"name": "top",    "type": "quad", "material": ")" +
           top + R"(", "vertices": [[0,1,0],[1,1,0],[1,1,1],[0,1,1]]},
        {"name": "left",   "type": "quad", "material": "m", "vertices": [[0,0,0],[0,1,0],[0,1,1],[0,0,1]]},
        {"name": "right",  "type": "quad", "material": "m", "vertices": [[1,0,0],[1,0,1],[1,1,1],[1,1,0]]},
        {"name": "back",   "type": "quad", "material": "m", "vertices": [[0,0,1],[0,1,1],[1,1,1],[1,0,1]]},
        {"name": "front",  "type": "quad", "material": "m", "vertices": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]})" +
           extra + "]" + tail + "}";
}

// The closed unit cube, all of `material` (JSON).
inline std::string closedCube(const std::string& material) { return cubeScene(R"("m": )" + material); }

// The furnace cube: faces diffuse with reflectance rho, emitting L_e = 1. A second material
// "spec" (JSON) may be given, for the top face (specTop) or for `extra` objects; `extra` and `tail`
// as for cubeScene.
inline std::string furnaceCube(double rho, const std::string& spec = "", bool specTop = false,
                               const std::string& extra = "", const std::string& tail = "") {
    const std::string m = cat(R"("m": {"type": "diffuse", "reflectance": )", rho, R"(, "emission": 1})");
    return cubeScene(spec.empty() ? m : cat(m, R"(, "spec": )", spec), specTop ? "spec" : "m", extra, tail);
}

// The unit furnace cube (every surface reflectance rho, emission 1) holding two boxes and a sphere,
// none touching another: occluders everywhere, nothing open, no back face in sight.
// With `gap`, also a thin panel standing 1 cm off the wall x = 0: a narrow gap (ray_form_factors.cpp).
inline std::string furnaceWithOccluders(double rho, bool gap = false) {
    auto quad = [](const std::string& name, std::initializer_list<std::array<double, 3>> v) {
        std::string text = cat(R"(, {"name": ")", name, R"(", "type": "quad", "material": "m", "vertices": [)");
        bool first = true;
        for (const auto& p : v) {
            text += cat(first ? "" : ",", "[", p[0], ",", p[1], ",", p[2], "]");
            first = false;
        }
        return text + "]}";
    };
    auto box = [&](const std::string& name, double x0, double x1, double y0, double y1, double z0, double z1) {
        return quad(name + "_bottom", {{x0, y0, z0}, {x1, y0, z0}, {x1, y0, z1}, {x0, y0, z1}}) +
               quad(name + "_top", {{x0, y1, z0}, {x0, y1, z1}, {x1, y1, z1}, {x1, y1, z0}}) +
               quad(name + "_left", {{x0, y0, z0}, {x0, y0, z1}, {x0, y1, z1}, {x0, y1, z0}}) +
               quad(name + "_right", {{x1, y0, z0}, {x1, y1, z0}, {x1, y1, z1}, {x1, y0, z1}}) +
               quad(name + "_front", {{x0, y0, z0}, {x0, y1, z0}, {x1, y1, z0}, {x1, y0, z0}}) +
               quad(name + "_back", {{x0, y0, z1}, {x1, y0, z1}, {x1, y1, z1}, {x0, y1, z1}});
    };
    return furnaceCube(
        rho, "", false,
        box("box", 0.15, 0.45, 0.1, 0.55, 0.2, 0.5) + box("slab", 0.55, 0.9, 0.05, 0.2, 0.1, 0.35) +
            R"(, {"name": "ball", "type": "sphere", "material": "m", "center": [0.7, 0.6, 0.65], "radius": 0.2})" +
            (gap ? box("panel", 0.01, 0.03, 0.05, 0.85, 0.55, 0.95) : std::string()));
}

// Form factor from a point, facing up at the origin, to the parallel rectangle [x0,x1] x [y0,y1] at
// height h facing down (Howell's case B-3 summed over the four corner rectangles).
inline double pointToRectangle(double x0, double x1, double y0, double y1, double h) {
    auto corner = [h](double a, double b) {
        const double ra = std::sqrt(a * a + h * h), rb = std::sqrt(b * b + h * h);
        return (a / ra * std::atan(b / ra) + b / rb * std::atan(a / rb)) / (2 * kPi);
    };
    return corner(x1, y1) - corner(x0, y1) - corner(x1, y0) + corner(x0, y0);
}

// A 2 m floor (reflectance 0.5) under a 0.2 m lamp at 1 m (L_e = 10, black), with, optionally, a
// black 0.4 m square halfway between them casting a shadow whose penumbra runs from 0.3 to 0.5 m off
// the axis (by similar triangles through the square's edges).
inline std::string lampOverFloor(bool occluder) {
    return std::string(R"({
      "materials": {"lamp": {"type": "diffuse", "reflectance": 0, "emission": 10},
                    "floor": {"type": "diffuse", "reflectance": 0.5},
                    "black": {"type": "diffuse", "reflectance": 0}},
      "objects": [
        {"name": "floor", "type": "quad", "material": "floor", "vertices": [[-1,-1,0],[1,-1,0],[1,1,0],[-1,1,0]]},
        {"name": "lamp", "type": "quad", "material": "lamp",
         "vertices": [[-0.1,-0.1,1],[-0.1,0.1,1],[0.1,0.1,1],[0.1,-0.1,1]]})") +
           (occluder ? R"(,
        {"name": "square", "type": "quad", "material": "black",
         "vertices": [[-0.2,-0.2,0.5],[0.2,-0.2,0.5],[0.2,0.2,0.5],[-0.2,0.2,0.5]]})"
                     : "") +
           "]}";
}

// The floor's exact radiosity under that lamp where all of it is in view: rho E F(x -> lamp).
inline double unshadowedFloor(const Vec3& x) {
    return 0.5 * kPi * 10 * pointToRectangle(-0.1 - x.x(), 0.1 - x.x(), -0.1 - x.y(), 0.1 - x.y(), 1);
}

// The power balance with its two sides computed independently: emitted (the closed form of the
// emitters) = absorbed (the solve's) + escaped, the escaped power counted by rays that leave the
// scene (estimateEscapedPower), not defined as what the solve did not absorb. Within 4.5 standard
// errors of the ray count and `bias` of the emitted power, for what the two geometries differ by
// (cubature error of the form factors, the facets of spheres the rays see exactly). Also holds the
// solve's own escaped power against the rays'.
inline void expectBalanceByRays(const Scene& scene, const SolveResult& r, double bias = 2e-3, int rays = 1024,
                                const std::string& what = "") {
    const SceneTracer tracer(scene, r.patches);
    const EscapeEstimate escape = estimateEscapedPower(tracer, r.solution.B, rays, 17);
    for (int c = 0; c < 3; ++c) {
        const double emitted = r.power.totalEmitted[c];
        if (!(emitted > 0)) continue;
        const double allowed = 4.5 * escape.standardError[c] + bias * emitted;
        EXPECT_NEAR(r.power.totalAbsorbed[c] + escape.escaped[c], emitted, allowed)
            << what << " channel " << c << ": absorbed " << r.power.totalAbsorbed[c] << " W, escaped by rays "
            << escape.escaped[c] << " +- " << escape.standardError[c] << " W";
        EXPECT_NEAR(r.power.escaped[c], escape.escaped[c], allowed)
            << what << " channel " << c << ": the solve's escaped power";
    }
}
inline void expectBalanceByRays(const std::string& json, const SolveResult& r, double bias = 2e-3, int rays = 1024,
                                const std::string& what = "") {
    expectBalanceByRays(sceneFromJson(json, "balance.json"), r, bias, rays, what);
}

}  // namespace penumbra::test
