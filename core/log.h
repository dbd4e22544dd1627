// Levelled logging to stderr. `--quiet` shows warnings and errors only; `--verbose` adds debug.
#pragma once

#include <string>

#include "core/error.h"

namespace penumbra {

enum class LogLevel { Debug = 0, Info = 1, Warning = 2, Error = 3 };

void setLogLevel(LogLevel level);
LogLevel logLevel();
void logMessage(LogLevel level, const std::string& message);

template <typename... Parts>
void logInfo(const Parts&... parts) {
    if (logLevel() <= LogLevel::Info) logMessage(LogLevel::Info, cat(parts...));
}
template <typename... Parts>
void logDebug(const Parts&... parts) {
    if (logLevel() <= LogLevel::Debug) logMessage(LogLevel::Debug, cat(parts...));
}
template <typename... Parts>
void logWarning(const Parts&... parts) {
    logMessage(LogLevel::Warning, cat(parts...));
}

}  // namespace penumbra
