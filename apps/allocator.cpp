// The allocator's settings, read by jemalloc when it starts (MALLOC_CONF in the environment still
// overrides them). Transparent huge pages for the heap: a solve's buffers are touched once, fresh,
// and on this machine's virtualised kernel every 4 KiB page's first touch is a fault that costs
// microseconds. Measured on cornell-glass (2026-12-05): minor faults 31.7k -> 7.5k, the stages
// 0.59-0.64 s -> 0.48-0.53 s; the one-sided building's 165k -> 12k, 7.9 s -> 7.3 s; peak RSS
// about +10% (190 -> 218 MB, 626 -> 693 MB).
#include "allocator.h"

extern "C" {
// NOLINTNEXTLINE: the name and type are jemalloc's.
const char* malloc_conf = "thp:always,metadata_thp:always";
}

namespace penumbra {

const char* allocatorName() { return "jemalloc (transparent huge pages)"; }

}  // namespace penumbra
