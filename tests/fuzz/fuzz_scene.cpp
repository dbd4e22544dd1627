// libFuzzer target: the scene loader on arbitrary bytes, and the same bytes as a --camera argument.
// A Scene (a Camera) or one penumbra::Error are the only outcomes allowed; a crash, a hang, a leak
// or any other exception is a defect (issue 15).
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <string>

#include "core/error.h"
#include "core/log.h"
#include "mesh/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    static const std::string path = "/tmp/penumbra-fuzz-scene-" + std::to_string(getpid()) + ".json";
    penumbra::setLogLevel(penumbra::LogLevel::Error);
    FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) return 0;
    std::fwrite(data, 1, size, f);
    std::fclose(f);
    try {
        penumbra::loadScene(path);
    } catch (const penumbra::Error&) {
    }
    // --camera: parsed against a scene loaded once (its unit and inside unit).
    static const penumbra::Scene scene = [] {
        const std::string room = path + ".room.json";
        FILE* r = std::fopen(room.c_str(), "wb");
        const char text[] = R"({"unit_scale": 0.001, "materials": {"m": {"type": "diffuse", "reflectance": 0.5}},
            "objects": [{"name": "q", "type": "quad", "material": "m",
                         "vertices": [[0,0,0],[100,0,0],[100,100,0],[0,100,0]]}]})";
        if (r) std::fwrite(text, 1, sizeof text - 1, r), std::fclose(r);
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
