// libFuzzer target: the mesh-file readers (OBJ, OFF, PLY, STL: the first byte picks the format, the
// rest is the file) through readPolygonSoup, our checks first and OpenMesh's reader after them. A
// polygon soup or one penumbra::Error are the only outcomes allowed (issue 15).
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <string>

#include "core/error.h"
#include "mesh/mesh_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size == 0) return 0;
    static const char* kExtensions[] = {".obj", ".off", ".ply", ".stl"};
    const std::string path = "/tmp/penumbra-fuzz-mesh-" + std::to_string(getpid()) + kExtensions[data[0] % 4];
    FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) return 0;
    std::fwrite(data + 1, 1, size - 1, f);
    std::fclose(f);
    try {
        penumbra::readPolygonSoup(path, "fuzz");
    } catch (const penumbra::Error&) {
    }
    std::remove(path.c_str());
    return 0;
}
