#pragma once
// Wall-clock timing of a stage, for reports and manifests (never for results).
#include <chrono>

namespace pneuma {

using Clock = std::chrono::steady_clock;

inline double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace pneuma
