#pragma once
// A smooth function of one variable on [lo, hi], tabulated at Chebyshev points and evaluated by
// the barycentric formula (Trefethen, "Approximation Theory and Approximation Practice", ch. 5):
// stable at any degree, O(n) per evaluation. Built adaptively, the way Chebfun does: the number
// of intervals doubles (the points are nested, so every sample is kept) until the interpolant at
// n intervals predicts the n new samples of 2n within the tolerance, or the limit is reached
// (a kink or a steep feature in [lo, hi]: no table then, and the caller evaluates exactly).
#include <cstddef>
#include <functional>
#include <optional>
#include <span>
#include <vector>

namespace pneuma {

class ChebyshevTable {
 public:
  // f(x, values) writes `components` values at x. The table is accepted when every new sample of
  // the last doubling was predicted within relative_tolerance x (the largest |value| of that
  // component over all samples). No table when lo > hi, either is not finite, or the limit of
  // `max_intervals` (a power of two >= 16) is reached first. lo == hi gives a one-point table.
  using Sample = std::function<void(double x, std::span<double> values)>;
  static std::optional<ChebyshevTable> fit(const Sample& f, std::size_t components, double lo, double hi,
                                           double relative_tolerance, std::size_t max_intervals = 256);

  double lo() const { return lo_; }
  double hi() const { return hi_; }
  bool covers(double x) const { return x >= lo_ && x <= hi_; }
  std::size_t intervals() const { return nodes_.size() - 1; }
  // The largest difference seen in the last doubling, relative as in fit().
  double estimated_error() const { return estimated_error_; }
  // The interpolant at x (covers(x) must hold): values.size() == components. At a node, the
  // sample itself.
  void evaluate(double x, std::span<double> values) const;

 private:
  double lo_ = 0.0, hi_ = 0.0, estimated_error_ = 0.0;
  std::size_t components_ = 0;
  std::vector<double> nodes_;    // x_j, j = 0..n, descending from hi to lo
  std::vector<double> samples_;  // components per node
};

}  // namespace pneuma
