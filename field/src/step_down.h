// A smooth step shared by the field's surface rules (heart.cpp, thin_lung.cpp).
#pragma once

#include <algorithm>

namespace pneuma::field::detail {

// 1 below 0, 0 above 1, smooth (cubic, zero slope at both ends) between.
inline double step_down(double x) {
  const double s = std::clamp(x, 0.0, 1.0);
  return 1.0 - s * s * (3.0 - 2.0 * s);
}

}  // namespace pneuma::field::detail
