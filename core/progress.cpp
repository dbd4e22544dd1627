#include "core/progress.h"

#include <unistd.h>

#include <cstdio>

#include "core/log.h"

namespace penumbra {
namespace {
bool g_forced = false;
}  // namespace

void setProgressForced(bool forced) { g_forced = forced; }
bool progressForced() { return g_forced; }

Progress::Progress(std::string title, int64_t total)
    : title_(std::move(title)),
      total_(total > 0 ? total : 1),
      enabled_((g_forced || isatty(STDERR_FILENO)) && logLevel() <= LogLevel::Info),
      start_(std::chrono::steady_clock::now()),
      lastDraw_(start_) {
    if (enabled_) releaseHeldLog();  // the lines before the bar, before it
}

Progress::~Progress() { done(); }

void Progress::update(int64_t done) {
    count_ += done;
    if (!enabled_) return;
    const auto now = std::chrono::steady_clock::now();
    if (now - lastDraw_ < std::chrono::milliseconds(100)) return;
    std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
    if (!lock.owns_lock()) return;
    lastDraw_ = now;
    draw(false);
}

void Progress::done() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (finished_) return;
    finished_ = true;
    if (enabled_) {
        count_ = total_;
        draw(true);
    }
}

void Progress::draw(bool final) {
    const double fraction = std::min(1.0, double(count_) / double(total_));
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const int width = 30;
    const int filled = int(fraction * width);
    std::string bar(filled, '#');
    bar += std::string(width - filled, ' ');
    const double remaining = fraction > 0 ? elapsed * (1 - fraction) / fraction : 0;
    std::fprintf(stderr, "\r%-14s [%s] %5.1f%%  %6.1fs%s", title_.c_str(), bar.c_str(), 100 * fraction,
                 final ? elapsed : remaining, final ? "      \n" : " left ");
    std::fflush(stderr);
}

}  // namespace penumbra
