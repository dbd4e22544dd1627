#include "core/log.h"

#include <atomic>
#include <charconv>
#include <cstdio>
#include <mutex>

namespace penumbra {
namespace {
std::atomic<LogLevel> g_level{LogLevel::Info};
std::mutex g_mutex;
}  // namespace

void setLogLevel(LogLevel level) { g_level = level; }
LogLevel logLevel() { return g_level; }

void logMessage(LogLevel level, const std::string& message) {
    if (level < g_level) return;
    static const char* kTags[] = {"debug", "info", "warning", "error"};
    std::lock_guard<std::mutex> lock(g_mutex);
    std::fprintf(stderr, "penumbra: %s: %s\n", kTags[static_cast<int>(level)], message.c_str());
}

std::string exact(double v) {
    char text[32];
    const auto end = std::to_chars(text, text + sizeof text, v).ptr;
    return std::string(text, end);
}

void checkFailed(const char* file, int line, const std::string& what) {
    std::fprintf(stderr, "penumbra: internal error at %s:%d: %s\n", file, line, what.c_str());
    std::abort();
}

}  // namespace penumbra
