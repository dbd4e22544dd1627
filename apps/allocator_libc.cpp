#include "allocator.h"

namespace penumbra {

const char* allocatorName() { return "the C library's malloc"; }

}  // namespace penumbra
