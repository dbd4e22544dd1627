// libFuzzer target: the scene loader on arbitrary bytes. A Scene or one penumbra::Error are the only
// outcomes allowed; a crash, a hang, a leak or any other exception is a defect (issue 15).
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
    return 0;
}
