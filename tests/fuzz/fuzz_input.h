// The fuzz targets' input as a file, since the code under test reads files: written to
// /tmp/penumbra-fuzz-NAME-PID.EXT (one per process, so parallel fuzzers do not share it).
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <set>
#include <string>

namespace penumbra::fuzz {

// The path written, or "" if it could not be. The file goes when the fuzzer exits.
inline std::string inputFile(const std::string& name, const std::string& ext, const uint8_t* data, size_t size) {
    const std::string path = "/tmp/penumbra-fuzz-" + name + "-" + std::to_string(getpid()) + ext;
    struct Written {
        std::set<std::string> paths;
        ~Written() {
            for (const std::string& p : paths) std::remove(p.c_str());
        }
    };
    static Written written;
    written.paths.insert(path);
    FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) return "";
    const bool whole = std::fwrite(data, 1, size, f) == size;
    return std::fclose(f) == 0 && whole ? path : "";
}

}  // namespace penumbra::fuzz
