// libFuzzer target: the glTF and OBJ scene readers (tinygltf and tinyobjloader, then our mapping and
// checks) through loadScene; the first byte picks .glb, .gltf or .obj, the rest is the file. A Scene or
// one penumbra::Error are the only outcomes allowed (issue 17: malformed files refused by name).
#include <cstdio>

#include "core/error.h"
#include "core/log.h"
#include "fuzz_input.h"
#include "mesh/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size == 0) return 0;
    penumbra::setLogLevel(penumbra::LogLevel::Error);
    static const char* kExtensions[] = {".glb", ".gltf", ".obj"};
    const std::string path = penumbra::fuzz::inputFile("import", kExtensions[data[0] % 3], data + 1, size - 1);
    if (path.empty()) return 0;
    try {
        penumbra::loadScene(path);
    } catch (const penumbra::Error&) {
    }
    std::remove(path.c_str());
    return 0;
}
