// Which allocator the program runs on: jemalloc with transparent huge pages where the build found
// it (apps/allocator.cpp), the C library's malloc otherwise (sanitizer builds, which bring their own).
#pragma once

namespace penumbra {

const char* allocatorName();

}  // namespace penumbra
