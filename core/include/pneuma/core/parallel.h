#pragma once
// A loop over indices on every core, told to ThreadSanitizer (tsan.h).
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cstddef>

#include "pneuma/core/tsan.h"

namespace pneuma::core {

// f(i) for i in [0, n) on every thread, in ranges of at least `grain` (1 where each i is a
// slice of a volume); f writes slot i only, so the result is the same at any thread count.
template <class F>
void for_each_index(std::size_t n, const F& f, std::size_t grain = 4096) {
  const tsan::Region region;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain),
                    region.wrap([&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t i = range.begin(); i < range.end(); ++i) f(i);
                    }));
  region.join();
}

}  // namespace pneuma::core
