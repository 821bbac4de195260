#pragma once
// Helpers shared by the comparators' .cpp files (not installed).
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "pneuma/paper/comparators.h"

#include "pneuma/core/stopwatch.h"
#include "pneuma/field/shot_unshot_loop.h"

namespace pneuma::paper::detail {

// splitmix64 (Steele, Lea, Flood 2014): tiny, seedable, and the same numbers on every
// platform, unlike the standard library's distributions.
class SplitMix64 {
 public:
  explicit SplitMix64(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }
  // Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }

 private:
  std::uint64_t state_;
};

// Records a trace at steps 0, 1, 2, ... growing by about 3 % each time (a few hundred records
// for millions of steps), and wherever force_next() asks.
class TraceSampler {
 public:
  bool due(std::uint64_t step) const { return step >= next_; }
  void force_next() { next_ = 0; }
  void record(ConvergenceTrace& trace, std::uint64_t step, std::uint64_t operations, double residual, double probe) {
    if (!trace.step.empty() && trace.step.back() == step) {  // the final record replaces a same-step one
      trace.step.pop_back();
      trace.operations.pop_back();
      trace.residual.pop_back();
      trace.probe.pop_back();
    }
    trace.step.push_back(step);
    trace.operations.push_back(operations);
    trace.residual.push_back(residual);
    trace.probe.push_back(probe);
    next_ = std::max(step + 1, static_cast<std::uint64_t>(std::ceil(static_cast<double>(step) * 1.03)));
  }

 private:
  std::uint64_t next_ = 0;
};

}  // namespace pneuma::paper::detail
