// libFuzzer target: the solution reader (a solve's solution.bin, which render, view and export
// read back) on arbitrary bytes. A solution or one penumbra::Error are the only outcomes allowed
// (issue 15).
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <string>

#include "core/error.h"
#include "io/solution.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    static const std::string path = "/tmp/penumbra-fuzz-solution-" + std::to_string(getpid()) + ".bin";
    FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) return 0;
    std::fwrite(data, 1, size, f);
    std::fclose(f);
    try {
        penumbra::readSolution(path);
    } catch (const penumbra::Error&) {
    }
    return 0;
}
