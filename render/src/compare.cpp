#include "pneuma/render/compare.h"

#include <algorithm>
#include <cstdlib>
#include <string>

#include "pneuma/core/error.h"

namespace pneuma::render {

Difference compare(const Image& a, const Image& b, int pixel_threshold) {
  if (a.width != b.width || a.height != b.height) {
    throw UnsupportedError("render: images differ in size: " + std::to_string(a.width) + "x" +
                           std::to_string(a.height) + " and " + std::to_string(b.width) + "x" +
                           std::to_string(b.height));
  }
  Difference d;
  d.pixel_count = a.pixel_count();
  d.pixel_threshold = pixel_threshold;
  d.image = Image(a.width, a.height);
  std::array<std::uint64_t, 4> sum{};
  for (std::size_t p = 0; p < d.pixel_count; ++p) {
    const std::uint8_t* pa = a.rgba.data() + 4 * p;
    const std::uint8_t* pb = b.rgba.data() + 4 * p;
    int largest = 0;
    for (int c = 0; c < 4; ++c) {
      const int diff = std::abs(int{pa[c]} - int{pb[c]});
      d.max[c] = std::max(d.max[c], diff);
      sum[c] += static_cast<std::uint64_t>(diff);
      largest = std::max(largest, diff);
    }
    std::uint8_t* out = d.image.rgba.data() + 4 * p;
    if (largest > pixel_threshold) {
      ++d.pixels_over;
      out[0] = static_cast<std::uint8_t>(std::min(255, 128 + largest));  // red, brighter for a larger difference
      out[1] = out[2] = 0;
    } else {
      // A's luminance at a third, tinted yellow where there is a difference under the threshold.
      const int grey = (2 * pa[0] + 5 * pa[1] + pa[2]) / 24;
      out[0] = out[1] = static_cast<std::uint8_t>(std::min(255, grey + (largest > 0 ? 48 : 0)));
      out[2] = static_cast<std::uint8_t>(grey);
    }
    out[3] = 255;
  }
  for (int c = 0; c < 4; ++c) {
    d.mean[c] = d.pixel_count ? static_cast<double>(sum[c]) / static_cast<double>(d.pixel_count) : 0.0;
  }
  return d;
}

}  // namespace pneuma::render
