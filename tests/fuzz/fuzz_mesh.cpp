// libFuzzer target: the mesh-file readers (OBJ, OFF, PLY, STL: the first byte picks the format, the
// rest is the file) through readPolygonSoup, our checks first and OpenMesh's reader after them. A
// polygon soup or one penumbra::Error are the only outcomes allowed (issue 15).
#include <cstdio>

#include "core/error.h"
#include "fuzz_input.h"
#include "mesh/mesh_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size == 0) return 0;
    static const char* kExtensions[] = {".obj", ".off", ".ply", ".stl"};
    const std::string path = penumbra::fuzz::inputFile("mesh", kExtensions[data[0] % 4], data + 1, size - 1);
    if (path.empty()) return 0;
    try {
        penumbra::readPolygonSoup(path, "fuzz");
    } catch (const penumbra::Error&) {
    }
    std::remove(path.c_str());
    return 0;
}
