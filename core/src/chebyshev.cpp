#include "pneuma/core/chebyshev.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace pneuma {
namespace {

// x_j = mid + half cos(pi j / n): Chebyshev points of the second kind, hi first.
double node(double lo, double hi, std::size_t j, std::size_t n) {
  if (j == 0) return hi;
  if (j == n) return lo;
  const double mid = 0.5 * (lo + hi), half = 0.5 * (hi - lo);
  return mid + half * std::cos(std::numbers::pi * static_cast<double>(j) / static_cast<double>(n));
}

// The barycentric formula of the second kind with weights (-1)^j, halved at both ends.
void interpolate(const std::vector<double>& nodes, const std::vector<double>& samples, std::size_t components, double x,
                 std::span<double> values) {
  const std::size_t n = nodes.size() - 1;
  for (std::size_t j = 0; j <= n; ++j) {
    if (x == nodes[j]) {
      std::copy_n(samples.begin() + static_cast<std::ptrdiff_t>(j * components), components, values.begin());
      return;
    }
  }
  std::fill(values.begin(), values.end(), 0.0);
  double denominator = 0.0;
  for (std::size_t j = 0; j <= n; ++j) {
    double w = (j % 2 == 0 ? 1.0 : -1.0) / (x - nodes[j]);
    if (j == 0 || j == n) w *= 0.5;
    denominator += w;
    for (std::size_t c = 0; c < components; ++c) values[c] += w * samples[j * components + c];
  }
  for (double& v : values) v /= denominator;
}

}  // namespace

std::optional<ChebyshevTable> ChebyshevTable::fit(const Sample& f, std::size_t components, double lo, double hi,
                                                  double relative_tolerance, std::size_t max_intervals) {
  if (!std::isfinite(lo) || !std::isfinite(hi) || lo > hi || components == 0) return std::nullopt;
  ChebyshevTable table;
  table.lo_ = lo;
  table.hi_ = hi;
  table.components_ = components;
  if (lo == hi) {
    table.nodes_ = {lo};
    table.samples_.resize(components);
    f(lo, table.samples_);
    return table;
  }
  std::size_t n = 16;
  table.nodes_.resize(n + 1);
  table.samples_.resize((n + 1) * components);
  for (std::size_t j = 0; j <= n; ++j) {
    table.nodes_[j] = node(lo, hi, j, n);
    f(table.nodes_[j], std::span<double>(table.samples_).subspan(j * components, components));
  }
  std::vector<double> predicted(components), scale(components);
  while (2 * n <= max_intervals) {
    // The n new points of 2n intervals are the odd ones; the even ones are the current nodes.
    std::vector<double> nodes(2 * n + 1), samples((2 * n + 1) * components);
    std::vector<double> error(components, 0.0);
    for (std::size_t j = 0; j <= 2 * n; ++j) {
      const std::span<double> out(samples.data() + j * components, components);
      if (j % 2 == 0) {
        nodes[j] = table.nodes_[j / 2];
        std::copy_n(table.samples_.begin() + static_cast<std::ptrdiff_t>(j / 2 * components), components, out.begin());
        continue;
      }
      nodes[j] = node(lo, hi, j, 2 * n);
      f(nodes[j], out);
      interpolate(table.nodes_, table.samples_, components, nodes[j], predicted);
      for (std::size_t c = 0; c < components; ++c) error[c] = std::max(error[c], std::abs(predicted[c] - out[c]));
    }
    std::fill(scale.begin(), scale.end(), 0.0);
    for (std::size_t j = 0; j <= 2 * n; ++j) {
      for (std::size_t c = 0; c < components; ++c) scale[c] = std::max(scale[c], std::abs(samples[j * components + c]));
    }
    double worst = 0.0;
    bool finite = true;
    for (std::size_t c = 0; c < components; ++c) {
      finite = finite && std::isfinite(error[c]) && std::isfinite(scale[c]);
      worst = std::max(worst, scale[c] > 0.0 ? error[c] / scale[c] : error[c]);
    }
    table.nodes_ = std::move(nodes);
    table.samples_ = std::move(samples);
    table.estimated_error_ = worst;
    n *= 2;
    if (!finite) return std::nullopt;
    if (worst <= relative_tolerance) return table;
  }
  return std::nullopt;
}

void ChebyshevTable::evaluate(double x, std::span<double> values) const {
  interpolate(nodes_, samples_, components_, x, values);
}

}  // namespace pneuma
