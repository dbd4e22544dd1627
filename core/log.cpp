#include "core/log.h"

#include <atomic>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <string>
#include <vector>

namespace penumbra {
namespace {
std::atomic<LogLevel> g_level{LogLevel::Info};
std::mutex g_mutex;
bool g_holding = false;  // under g_mutex
std::chrono::steady_clock::time_point g_heldSince;
std::vector<std::string> g_held;

void printHeldLocked() {
    for (const std::string& line : g_held) std::fputs(line.c_str(), stderr);
    g_held.clear();
    g_holding = false;
}
}  // namespace

void holdLog() {
    std::lock_guard<std::mutex> lock(g_mutex);
    g_holding = true;
    g_heldSince = std::chrono::steady_clock::now();
}

void releaseHeldLog() {
    std::lock_guard<std::mutex> lock(g_mutex);
    printHeldLocked();
}

void dropHeldLog() {
    std::lock_guard<std::mutex> lock(g_mutex);
    g_held.clear();
    g_holding = false;
}

void setLogLevel(LogLevel level) { g_level = level; }
LogLevel logLevel() { return g_level; }

void logMessage(LogLevel level, const std::string& message) {
    if (level < g_level) return;
    static const char* kTags[] = {"debug", "info", "warning", "error"};
    std::lock_guard<std::mutex> lock(g_mutex);
    const std::string line = cat("penumbra: ", kTags[static_cast<int>(level)], ": ", message, "\n");
    if (g_holding) {
        if (level < LogLevel::Error && std::chrono::steady_clock::now() - g_heldSince < std::chrono::seconds(1)) {
            g_held.push_back(line);
            return;
        }
        printHeldLocked();
    }
    std::fputs(line.c_str(), stderr);
}

std::string exact(double v) {
    char text[32];
    const auto end = std::to_chars(text, text + sizeof text, v).ptr;
    return std::string(text, end);
}

bool finiteNumber(const std::string& text, double& v) {
    char* end = nullptr;
    v = std::strtod(text.c_str(), &end);
    return end != text.c_str() && *end == 0 && std::isfinite(v);
}

void checkFailed(const char* file, int line, const std::string& what) {
    std::fprintf(stderr, "penumbra: internal error at %s:%d: %s\n", file, line, what.c_str());
    std::abort();
}

}  // namespace penumbra
