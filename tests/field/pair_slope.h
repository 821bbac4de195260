// Displacement fields on point sets for the contraction tests (field::is_contraction and the
// deflation's ladder, model::field_for_deflation), and their oracle: the slope over every pair,
// counted directly.
#pragma once

#include <Eigen/Core>

#include <algorithm>
#include <cstddef>
#include <vector>

namespace pneuma::test {

// d(x) for each point, as a new vector.
template <typename F>
std::vector<Eigen::Vector3d> field_at(const std::vector<Eigen::Vector3d>& x, F&& d) {
  std::vector<Eigen::Vector3d> out;
  out.reserve(x.size());
  for (const Eigen::Vector3d& p : x) out.push_back(d(p));
  return out;
}

// s u, per vertex.
inline std::vector<Eigen::Vector3d> times(double s, const std::vector<Eigen::Vector3d>& u) {
  return field_at(u, [s](const Eigen::Vector3d& v) -> Eigen::Vector3d { return s * v; });
}

// The largest |d_i - d_j| / |x_i - x_j| over every pair, counted directly: the oracle.
inline double slope_over_all_pairs(const std::vector<Eigen::Vector3d>& x, const std::vector<Eigen::Vector3d>& d) {
  double steepest = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    for (std::size_t j = i + 1; j < x.size(); ++j)
      steepest = std::max(steepest, (d[i] - d[j]).norm() / (x[i] - x[j]).norm());
  }
  return steepest;
}

}  // namespace pneuma::test
