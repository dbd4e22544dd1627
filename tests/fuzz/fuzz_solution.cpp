// libFuzzer target: the solution reader (a solve's solution.bin, which render, view and export
// read back) on arbitrary bytes. A solution or one penumbra::Error are the only outcomes allowed
// (issue 15).
#include "core/error.h"
#include "fuzz_input.h"
#include "io/solution.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string path = penumbra::fuzz::inputFile("solution", ".bin", data, size);
    if (path.empty()) return 0;
    try {
        penumbra::readSolution(path);
    } catch (const penumbra::Error&) {
    }
    return 0;
}
