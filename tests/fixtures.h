// Test helpers: scenes written from JSON text into a temporary folder and loaded through the real
// loader, and sums of patch-level results per object.
#pragma once

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>

#include "core/error.h"
#include "mesh/scene.h"
#include "solver/solve.h"

namespace penumbra::test {

struct CommandResult {
    int status;
    std::string output;   // stderr and stdout together
};

// Runs the penumbra executable with `args` (a shell command line) and collects what it prints.
inline CommandResult run(const std::string& args) {
    const std::string command = std::string(PENUMBRA_EXE) + " " + args + " 2>&1";
    FILE* pipe = popen(command.c_str(), "r");
    std::string out;
    std::array<char, 4096> buffer;
    while (size_t n = fread(buffer.data(), 1, buffer.size(), pipe)) out.append(buffer.data(), n);
    const int status = pclose(pipe);
    return {WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status), out};
}

inline std::string tempDir() {
    static const std::string dir = [] {
        auto d = std::filesystem::temp_directory_path() / ("penumbra-test-" + std::to_string(::getpid()));
        std::filesystem::create_directories(d);
        return d.string();
    }();
    return dir;
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
inline std::string cubeScene(const std::string& materials, const std::string& top = "m",
                             const std::string& extra = "", const std::string& tail = "") {
    return R"({"materials": {)" + materials + R"(},
      "objects": [
        {"name": "bottom", "type": "quad", "material": "m", "vertices": [[0,0,0],[0,0,1],[1,0,1],[1,0,0]]},
        {"name": "top",    "type": "quad", "material": ")" + top + R"(", "vertices": [[0,1,0],[1,1,0],[1,1,1],[0,1,1]]},
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

}  // namespace penumbra::test
