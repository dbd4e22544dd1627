// Parallel loops over TBB (which Embree already uses). Work is split by index ranges; callers seed
// randomness per work item, never per thread, so results do not depend on the thread count.
#pragma once

#include <cstdint>
#include <functional>

namespace penumbra {

// Limits every parallel loop to `threads` threads (0: all cores). Lives for the process.
void setThreadCount(int threads);
int threadCount();

// Calls body(begin, end) on disjoint chunks covering [0, count).
void parallelFor(int64_t count, const std::function<void(int64_t, int64_t)>& body, int64_t grain = 1);

}  // namespace penumbra
