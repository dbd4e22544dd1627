#include "io/atomic_file.h"

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "io/output_set.h"

namespace penumbra {

std::string temporarySibling(const std::string& path) {
    const std::filesystem::path p(path);
    return (p.parent_path() / cat(".", p.stem().string(), ".tmp-", getpid(), p.extension().string())).string();
}

void commitFile(const std::string& temporary, const std::string& path) {
    std::error_code ec;
    try {
        faultPoint(path);
    } catch (...) {
        std::filesystem::remove(temporary, ec);
        throw;
    }
    std::filesystem::rename(temporary, path, ec);
    if (ec) {
        std::filesystem::remove(temporary, ec);
        throw Error(cat(path, ": cannot write: ", ec.message()));
    }
}

void writeFileAtomic(const std::string& path, const std::string& contents) {
    writeFileAtomic(path, std::vector<std::string_view>{contents});
}

void writeFileAtomic(const std::string& path, const std::vector<std::string_view>& parts) {
    faultPoint(path);
    const std::string tmp = temporarySibling(path);
    {
        std::ofstream out(tmp, std::ios::binary);
        if (!out) throw Error(cat(path, ": cannot open for writing"));
        for (const std::string_view part : parts) out.write(part.data(), std::streamsize(part.size()));
        out.flush();
        if (!out) {
            std::error_code ec;
            std::filesystem::remove(tmp, ec);
            throw Error(cat(path, ": write failed (disk full?)"));
        }
    }
    commitFile(tmp, path);
}

void ensureDirectory(const std::string& dir) {
    std::error_code ec;
    if (std::filesystem::is_directory(dir, ec)) return;
    if (std::filesystem::exists(dir, ec)) throw Error(cat(dir, ": exists and is not a directory"));
    std::filesystem::create_directories(dir, ec);
    if (ec) throw Error(cat(dir, ": cannot create directory: ", ec.message()));
}

}  // namespace penumbra
