// libFuzzer target: the scene loader on arbitrary bytes, and the same bytes as a --camera argument.
// A Scene (a Camera) or one penumbra::Error are the only outcomes allowed; a crash, a hang, a leak
// or any other exception is a defect (issue 15).
#include <cstdio>

#include "core/error.h"
#include "core/log.h"
#include "fuzz_input.h"
#include "mesh/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    penumbra::setLogLevel(penumbra::LogLevel::Error);
    const std::string path = penumbra::fuzz::inputFile("scene", ".json", data, size);
    if (path.empty()) return 0;
    try {
        penumbra::loadScene(path);
    } catch (const penumbra::Error&) {
    }
    // --camera: parsed against a scene loaded once (its unit and inside unit).
    static const penumbra::Scene scene = [] {
        const char text[] = R"({"unit_scale": 0.001, "materials": {"m": {"type": "diffuse", "reflectance": 0.5}},
            "objects": [{"name": "q", "type": "quad", "material": "m",
                         "vertices": [[0,0,0],[100,0,0],[100,100,0],[0,100,0]]}]})";
        const std::string room =
            penumbra::fuzz::inputFile("room", ".json", reinterpret_cast<const uint8_t*>(text), sizeof text - 1);
        penumbra::Scene s = penumbra::loadScene(room);
        std::remove(room.c_str());
        return s;
    }();
    try {
        penumbra::parseCamera(std::string(reinterpret_cast<const char*>(data), size), scene, "--camera");
    } catch (const penumbra::Error&) {
    }
    return 0;
}
