// A progress bar on stderr for long loops (pbrt's ProgressReporter): drawn only when stderr is a
// terminal and the log level shows info; thread-safe `update`, rate-limited redraws.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

namespace penumbra {

// Bars drawn even when stderr is no terminal (--progress: under mpirun, whose ranks write to a pipe).
void setProgressForced(bool forced);
bool progressForced();

class Progress {
public:
    Progress(std::string title, int64_t total);
    ~Progress();
    Progress(const Progress&) = delete;
    Progress& operator=(const Progress&) = delete;

    void update(int64_t done = 1);
    void done();

private:
    void draw(bool final);

    std::string title_;
    int64_t total_;
    std::atomic<int64_t> count_{0};
    bool enabled_;
    bool finished_ = false;
    std::mutex mutex_;
    std::chrono::steady_clock::time_point start_, lastDraw_;
};

}  // namespace penumbra
