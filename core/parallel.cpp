#include "core/parallel.h"

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>

#include <memory>

namespace penumbra {
namespace {
std::unique_ptr<tbb::global_control> g_control;
int g_threads = 0;
}  // namespace

void setThreadCount(int threads) {
    g_threads = threads > 0 ? threads : tbb::info::default_concurrency();
    g_control = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(g_threads));
}

int threadCount() { return g_threads > 0 ? g_threads : tbb::info::default_concurrency(); }

void parallelFor(int64_t count, const std::function<void(int64_t, int64_t)>& body, int64_t grain) {
    if (count <= 0) return;
    tbb::parallel_for(tbb::blocked_range<int64_t>(0, count, grain > 0 ? grain : 1),
                      [&](const tbb::blocked_range<int64_t>& r) { body(r.begin(), r.end()); });
}

}  // namespace penumbra
