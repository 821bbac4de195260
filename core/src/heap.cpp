#include "pneuma/core/heap.h"

#include <cstdlib>  // defines __GLIBC__ where the C library is glibc

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace pneuma {

bool keep_large_blocks_in_heap() {
#if defined(__GLIBC__)
  constexpr int kLarge = 1 << 30;  // 1 GiB: every block a run allocates
  // Fixing the mapping threshold also turns off glibc's dynamic one (which only rises to 32 MiB).
  return mallopt(M_MMAP_THRESHOLD, kLarge) == 1 && mallopt(M_TRIM_THRESHOLD, kLarge) == 1;
#else
  return false;
#endif
}

}  // namespace pneuma
