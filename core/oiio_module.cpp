#include "core/oiio_module.h"

#include <dlfcn.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "core/error.h"

namespace penumbra {

const OiioModule& oiioModule() {
    static const OiioModule module = [] {
        std::vector<std::string> candidates;
        if (const char* given = std::getenv("PENUMBRA_OIIO_MODULE")) candidates.push_back(given);
#ifdef PENUMBRA_OIIO_MODULE_PATH
        candidates.push_back(PENUMBRA_OIIO_MODULE_PATH);
#endif
        std::error_code ec;
        const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
        if (!ec) candidates.push_back((self.parent_path() / "libpenumbra_oiio.so").string());
        std::string tried;
        for (const std::string& path : candidates) {
            void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
            if (!handle) {
                const char* why = dlerror();
                tried += cat(tried.empty() ? "" : "; ", why ? why : path);
                continue;
            }
            OiioModule m;
            m.write = reinterpret_cast<decltype(m.write)>(dlsym(handle, "penumbra_oiio_write"));
            m.read = reinterpret_cast<decltype(m.read)>(dlsym(handle, "penumbra_oiio_read"));
            if (m.write && m.read) return m;
            tried += cat(tried.empty() ? "" : "; ", path, ": not Penumbra's OpenImageIO module");
        }
        throw Error(cat("cannot load the OpenImageIO module (", tried.empty() ? "no candidate" : tried,
                        "); set PENUMBRA_OIIO_MODULE to libpenumbra_oiio.so"));
    }();
    return module;
}

}  // namespace penumbra
