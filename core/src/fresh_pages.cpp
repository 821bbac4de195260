// Large buffers mapped before they are first written (pneuma/core/fresh_pages.h).
#include "pneuma/core/fresh_pages.h"

#include <sys/mman.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>

#include "pneuma/core/tsan.h"

namespace pneuma::core {

void map_for_writing(void* data, std::size_t bytes) {
#ifdef MADV_POPULATE_WRITE
  // Below this the faults cost less than a task's set-up (and a sliver of a page-aligned range).
  constexpr std::size_t kSmallest = std::size_t{8} << 20;
  // One madvise per slice: few enough calls, enough slices for both cores to share.
  constexpr std::size_t kSlice = std::size_t{16} << 20;
  if (data == nullptr || bytes < kSmallest) return;
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  // Only whole pages inside the buffer: its first and last pages may hold other blocks' bytes
  // (madvise needs a page-aligned start; the kernel maps the partial ones on first touch).
  const std::size_t lead = (page - reinterpret_cast<std::uintptr_t>(data) % page) % page;
  if (bytes <= lead) return;
  char* const begin = static_cast<char*>(data) + lead;
  const std::size_t whole = (bytes - lead) / page * page;
  const std::size_t slices = (whole + kSlice - 1) / kSlice;
  const tsan::Region region;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, slices, 1), region.wrap([&](const auto& r) {
    for (std::size_t s = r.begin(); s != r.end(); ++s) {
      const std::size_t from = s * kSlice, length = std::min(kSlice, whole - from);
      // A refusal (EINVAL before Linux 5.14, ENOMEM, EFAULT) leaves the pages to be mapped on
      // first touch: nothing else changes, so the result is ignored.
      (void)madvise(begin + from, length, MADV_POPULATE_WRITE);
    }
  }));
  region.join();
#else
  (void)data;
  (void)bytes;
#endif
}

}  // namespace pneuma::core
