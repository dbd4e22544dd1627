// Levelled logging to stderr. `--quiet` shows warnings and errors only; `--verbose` adds debug.
#pragma once

#include <string>

#include "core/error.h"

namespace penumbra {

enum class LogLevel { Debug = 0, Info = 1, Warning = 2, Error = 3 };

void setLogLevel(LogLevel level);
LogLevel logLevel();
void logMessage(LogLevel level, const std::string& message);

// A run refused in its first moments (a budget known only once the scene is meshed, a solve that
// did not converge) printed its info lines and warnings and then the error; the error alone says it
// better. While held, the lines below errors wait, for at most a second: the first progress bar, a
// line after that second, or releaseHeldLog prints them; dropHeldLog discards them (before the
// error is printed).
void holdLog();
void releaseHeldLog();
void dropHeldLog();

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
