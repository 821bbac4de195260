#pragma once
// Image comparison for regression tests and `pneuma render --compare`.
//
// Two renders of the same scene on different machines differ by llvmpipe rounding: a few
// levels at anti-aliased edges. A real change (a colour, a camera, a shape) moves many
// pixels by much more. So a pixel "differs" when one of its channels differs by more than
// `pixel_threshold`, and two images match when the share of differing pixels is at most
// `max_share_over`.
#include <array>

#include "pneuma/render/image.h"

namespace pneuma::render {

struct Tolerance {
  int pixel_threshold = 8;        // 0..255, per channel
  double max_share_over = 0.005;  // share of all pixels (0.5 %)
};
inline constexpr Tolerance default_tolerance{};

struct Difference {
  std::array<int, 4> max{};      // largest absolute difference per channel R, G, B, A (0..255)
  std::array<double, 4> mean{};  // mean absolute difference per channel
  std::size_t pixels_over = 0;   // pixels with a channel difference above the threshold
  std::size_t pixel_count = 0;
  int pixel_threshold = 0;  // the threshold the count used
  Image image;              // for the eye: A in dim grey, differing pixels in red

  double share_over() const {
    return pixel_count ? static_cast<double>(pixels_over) / static_cast<double>(pixel_count) : 0.0;
  }
  bool within(const Tolerance& t) const { return share_over() <= t.max_share_over; }
};

// Compares two images of the same size. Throws UnsupportedError when the sizes differ:
// "render: images differ in size: 160x120 and 100x80".
Difference compare(const Image& a, const Image& b, int pixel_threshold = default_tolerance.pixel_threshold);

}  // namespace pneuma::render
