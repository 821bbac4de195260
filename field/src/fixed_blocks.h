#pragma once
// Private to field/: parallel loops over fixed-size blocks of an index range. Reductions
// add one partial per block, in block order, so the result does not depend on how TBB spreads
// the blocks over threads (bit-for-bit determinism at any thread count).
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstddef>
#include <vector>

#include "pneuma/core/tsan.h"

namespace pneuma::field::detail {

constexpr std::size_t kBlock = 4096;

inline std::size_t block_count(std::size_t n) { return (n + kBlock - 1) / kBlock; }

// body(block, lo, hi) for each block [lo, hi) of [0, n).
template <typename Body>
void for_blocks(std::size_t n, const Body& body) {
  const std::size_t blocks = block_count(n);
  const tsan::Region region;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks),
                    region.wrap([&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t b = range.begin(); b != range.end(); ++b) {
                        body(b, b * kBlock, std::min(n, (b + 1) * kBlock));
                      }
                    }));
  region.join();
}

// body(i) for each i of [0, n), a block per task; body writes slot i only, so the result is the
// same at any thread count.
template <typename Body>
void for_each_index(std::size_t n, const Body& body) {
  for_blocks(n, [&](std::size_t /*block*/, std::size_t lo, std::size_t hi) {
    for (std::size_t i = lo; i < hi; ++i) body(i);
  });
}

// The partials added in block order.
inline double sum_in_order(const std::vector<double>& partial) {
  double total = 0.0;
  for (const double p : partial) total += p;
  return total;
}

}  // namespace pneuma::field::detail
