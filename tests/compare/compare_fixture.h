#pragma once
// Helpers shared by the comparison tests: lattice symmetries and an independent dense solve
// of a spring network's equilibrium.
#include <Eigen/Dense>
#include <array>
#include <cstdint>
#include <vector>

#include "pneuma/paper/comparators.h"

namespace pneuma::test {

// The 8 symmetries of a side x side lattice (dihedral group D4), as vertex maps.
inline std::vector<std::vector<std::uint32_t>> lattice_symmetries(std::uint32_t side) {
  std::vector<std::vector<std::uint32_t>> maps(8, std::vector<std::uint32_t>(std::size_t{side} * side));
  const std::uint32_t e = side - 1;
  for (std::uint32_t r = 0; r < side; ++r) {
    for (std::uint32_t c = 0; c < side; ++c) {
      const std::array<std::array<std::uint32_t, 2>, 8> images{{{r, c},
                                                                {c, e - r},        // rotation by 90 degrees
                                                                {e - r, e - c},    // 180
                                                                {e - c, r},        // 270
                                                                {r, e - c},        // mirror left-right
                                                                {e - r, c},        // mirror up-down
                                                                {c, r},            // main diagonal
                                                                {e - c, e - r}}};  // anti-diagonal
      for (std::size_t k = 0; k < 8; ++k) maps[k][r * side + c] = images[k][0] * side + images[k][1];
    }
  }
  return maps;
}

// K u = b on the free vertices, assembled from the network's springs and anchors and solved
// with a dense Cholesky factorisation (independent of the explicit Euler code).
inline std::vector<double> direct_equilibrium(const paper::SpringNetwork& n, const std::vector<double>& load) {
  std::vector<int> index(n.vertex_count, -1);
  int free_count = 0;
  for (std::uint32_t i = 0; i < n.vertex_count; ++i) {
    if (!n.clamped[i]) index[i] = free_count++;
  }
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(free_count, free_count);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(free_count);
  for (std::uint32_t i = 0; i < n.vertex_count; ++i) {
    if (index[i] < 0) continue;
    k(index[i], index[i]) += n.anchor[i];
    b[index[i]] = n.load_scale[i] * load[i];
  }
  for (std::size_t s = 0; s < n.springs.size(); ++s) {
    const int p = index[n.springs[s][0]], q = index[n.springs[s][1]];
    const double c = n.stiffness[s];
    if (p >= 0) k(p, p) += c;
    if (q >= 0) k(q, q) += c;
    if (p >= 0 && q >= 0) {
      k(p, q) -= c;
      k(q, p) -= c;
    }
  }
  const Eigen::VectorXd u = k.llt().solve(b);
  std::vector<double> out(n.vertex_count, 0.0);
  for (std::uint32_t i = 0; i < n.vertex_count; ++i) {
    if (index[i] >= 0) out[i] = n.output_scale[i] * u[index[i]];
  }
  return out;
}

inline double max_abs(const std::vector<double>& v) {
  double m = 0.0;
  for (double x : v) m = std::max(m, std::abs(x));
  return m;
}

inline double max_abs_difference(const std::vector<double>& a, const std::vector<double>& b) {
  double m = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) m = std::max(m, std::abs(a[i] - b[i]));
  return m;
}

}  // namespace pneuma::test
