// The interior field: P1 finite elements, the boundary eliminated, block-Jacobi preconditioned
// conjugate gradients over 3 x 3 blocks (one block per pair of free nodes sharing a tet).
#include "pneuma/field/interior.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "fixed_blocks.h"
#include "pneuma/core/error.h"

namespace pneuma::field {
namespace {

using detail::for_blocks;
using Block = Eigen::Matrix3d;
constexpr std::uint32_t kBoundary = ~std::uint32_t{0};

// Gradients of the four barycentric (hat) functions on a tet, times nothing; and its volume.
struct TetGradients {
  std::array<Eigen::Vector3d, 4> g;
  double volume = 0.0;
};

TetGradients tet_gradients(const mesh::TetMesh& mesh, std::size_t tet) {
  const auto& t = mesh.tets[tet];
  const Eigen::Vector3d& a = mesh.nodes[t[0]];
  Eigen::Matrix3d edges;
  edges.col(0) = mesh.nodes[t[1]] - a;
  edges.col(1) = mesh.nodes[t[2]] - a;
  edges.col(2) = mesh.nodes[t[3]] - a;
  const double det = edges.determinant();
  if (!(det > 0.0) || !std::isfinite(det)) {
    throw ValueError(
        fmt::format("interior field: tetrahedron {} is degenerate or inverted (6 x volume {:.3g} m^3)", tet, det));
  }
  // Rows of edges^-1 are the gradients of the barycentric coordinates of nodes 1-3.
  const Eigen::Matrix3d inv = edges.inverse();
  TetGradients out;
  out.g[1] = inv.row(0).transpose();
  out.g[2] = inv.row(1).transpose();
  out.g[3] = inv.row(2).transpose();
  out.g[0] = -(out.g[1] + out.g[2] + out.g[3]);
  out.volume = det / 6.0;
  return out;
}

// The stiffness coupling of hat functions i and j (3 x 3: force component a on i from the
// displacement component b of j), for E = 1.
Block element_block(const TetGradients& t, int i, int j, InteriorModel model, double lambda, double mu) {
  const Eigen::Vector3d& gi = t.g[static_cast<std::size_t>(i)];
  const Eigen::Vector3d& gj = t.g[static_cast<std::size_t>(j)];
  if (model == InteriorModel::harmonic) return t.volume * gi.dot(gj) * Block::Identity();
  return t.volume * (lambda * gi * gj.transpose() + mu * gj * gi.transpose() + mu * gi.dot(gj) * Block::Identity());
}

// The matrix over the free nodes: row r's columns col[offset[r] .. offset[r + 1]), sorted.
struct BlockMatrix {
  std::vector<std::size_t> offset;
  std::vector<std::uint32_t> col;
  std::vector<Block> value;

  std::size_t find(std::uint32_t row, std::uint32_t column) const {
    const auto first = col.begin() + static_cast<std::ptrdiff_t>(offset[row]);
    const auto last = col.begin() + static_cast<std::ptrdiff_t>(offset[row + 1]);
    return static_cast<std::size_t>(std::lower_bound(first, last, column) - col.begin());
  }
};

BlockMatrix pattern(const mesh::TetMesh& mesh, const std::vector<std::uint32_t>& free_index, std::size_t free_count) {
  std::vector<std::uint64_t> pairs;
  pairs.reserve(mesh.tets.size() * 12);
  for (const auto& t : mesh.tets) {
    for (int i = 0; i < 4; ++i) {
      for (int j = 0; j < 4; ++j) {
        const std::uint32_t a = free_index[t[static_cast<std::size_t>(i)]];
        const std::uint32_t b = free_index[t[static_cast<std::size_t>(j)]];
        if (i != j && a != kBoundary && b != kBoundary) pairs.push_back((std::uint64_t{a} << 32) | b);
      }
    }
  }
  for (std::uint32_t a = 0; a < free_count; ++a) pairs.push_back((std::uint64_t{a} << 32) | a);
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  BlockMatrix m;
  m.offset.assign(free_count + 1, 0);
  m.col.reserve(pairs.size());
  for (const std::uint64_t p : pairs) {
    ++m.offset[(p >> 32) + 1];
    m.col.push_back(static_cast<std::uint32_t>(p & 0xffffffffu));
  }
  for (std::size_t r = 0; r < free_count; ++r) m.offset[r + 1] += m.offset[r];
  m.value.assign(m.col.size(), Block::Zero());
  return m;
}

void multiply(const BlockMatrix& m, const std::vector<Eigen::Vector3d>& x, std::vector<Eigen::Vector3d>& y) {
  for_blocks(y.size(), [&](std::size_t, std::size_t lo, std::size_t hi) {
    for (std::size_t r = lo; r < hi; ++r) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (std::size_t k = m.offset[r]; k < m.offset[r + 1]; ++k) sum += m.value[k] * x[m.col[k]];
      y[r] = sum;
    }
  });
}

// sum_i a_i . b_i in block order.
double dot(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b, std::vector<double>& partial) {
  for_blocks(a.size(), [&](std::size_t block, std::size_t lo, std::size_t hi) {
    double s = 0.0;
    for (std::size_t i = lo; i < hi; ++i) s += a[i].dot(b[i]);
    partial[block] = s;
  });
  return detail::sum_in_order(partial);
}

}  // namespace

std::string interior_model_name(InteriorModel model) {
  return model == InteriorModel::elastic ? "elastic" : "harmonic";
}

Eigen::Matrix3d tet_displacement_gradient(const mesh::TetMesh& mesh, std::size_t tet,
                                          const std::vector<Eigen::Vector3d>& displacement) {
  const TetGradients t = tet_gradients(mesh, tet);
  Eigen::Matrix3d grad = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < 4; ++i) grad += displacement[mesh.tets[tet][i]] * t.g[i].transpose();
  return grad;
}

InteriorSolution solve_interior(const mesh::TetMesh& mesh, std::span<const std::uint32_t> boundary_nodes,
                                std::span<const Eigen::Vector3d> boundary_displacement,
                                const InteriorOptions& options) {
  const std::size_t n = mesh.nodes.size();
  if (boundary_nodes.size() != boundary_displacement.size()) {
    throw ValueError(fmt::format("interior field: {} boundary nodes but {} boundary displacements",
                                 boundary_nodes.size(), boundary_displacement.size()));
  }
  if (boundary_nodes.empty()) throw ValueError("interior field: no boundary node (the field would be undetermined)");
  const double nu = options.poisson_ratio;
  if (options.model == InteriorModel::elastic && !(nu >= 0.0 && nu < 0.5)) {
    throw ValueError(fmt::format("interior field: expected a Poisson ratio in [0, 0.5), got {}", nu));
  }
  for (const auto& t : mesh.tets) {
    for (const std::uint32_t v : t) {
      if (v >= n) throw ValueError(fmt::format("interior field: a tetrahedron names node {} of {}", v, n));
    }
  }

  InteriorSolution out;
  out.displacement.assign(n, Eigen::Vector3d::Zero());
  std::vector<std::uint32_t> free_index(n, 0);
  for (std::size_t k = 0; k < boundary_nodes.size(); ++k) {
    const std::uint32_t v = boundary_nodes[k];
    if (v >= n) throw ValueError(fmt::format("interior field: boundary node {} of {}", v, n));
    if (free_index[v] == kBoundary) throw ValueError(fmt::format("interior field: boundary node {} given twice", v));
    free_index[v] = kBoundary;
    out.displacement[v] = boundary_displacement[k];
  }
  std::vector<std::uint32_t> free_nodes;
  for (std::uint32_t v = 0; v < n; ++v) {
    if (free_index[v] != kBoundary) {
      free_index[v] = static_cast<std::uint32_t>(free_nodes.size());
      free_nodes.push_back(v);
    }
  }
  out.report.free_nodes = free_nodes.size();
  out.report.boundary_nodes = boundary_nodes.size();
  if (free_nodes.empty()) return out;

  // Assembly, tet by tet in order (deterministic); the boundary's columns go to the right side.
  const double lambda = nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
  const double mu = 1.0 / (2.0 * (1.0 + nu));
  BlockMatrix k = pattern(mesh, free_index, free_nodes.size());
  std::vector<Eigen::Vector3d> rhs(free_nodes.size(), Eigen::Vector3d::Zero());
  for (std::size_t t = 0; t < mesh.tets.size(); ++t) {
    const TetGradients grads = tet_gradients(mesh, t);
    const auto& tet = mesh.tets[t];
    for (int i = 0; i < 4; ++i) {
      const std::uint32_t row = free_index[tet[static_cast<std::size_t>(i)]];
      if (row == kBoundary) continue;
      for (int j = 0; j < 4; ++j) {
        const std::uint32_t node_j = tet[static_cast<std::size_t>(j)];
        const Block b = element_block(grads, i, j, options.model, lambda, mu);
        const std::uint32_t column = free_index[node_j];
        if (column == kBoundary) {
          rhs[row] -= b * out.displacement[node_j];
        } else {
          k.value[k.find(row, column)] += b;
        }
      }
    }
  }

  // Block-Jacobi preconditioned CG, from zero.
  const std::size_t m = free_nodes.size();
  std::vector<Block> inverse_diagonal(m);
  for (std::uint32_t r = 0; r < m; ++r) inverse_diagonal[r] = k.value[k.find(r, r)].inverse();
  std::vector<Eigen::Vector3d> x(m, Eigen::Vector3d::Zero()), r = rhs, z(m), p(m), q(m);
  std::vector<double> partial(detail::block_count(m));
  const double rhs_norm = std::sqrt(dot(rhs, rhs, partial));
  auto precondition = [&] {
    for_blocks(m, [&](std::size_t, std::size_t lo, std::size_t hi) {
      for (std::size_t i = lo; i < hi; ++i) z[i] = inverse_diagonal[i] * r[i];
    });
  };
  if (rhs_norm > 0.0) {
    precondition();
    p = z;
    double rz = dot(r, z, partial);
    double residual = 1.0;
    std::size_t it = 0;
    while (it < options.max_iterations) {
      multiply(k, p, q);
      const double alpha = rz / dot(p, q, partial);
      for_blocks(m, [&](std::size_t, std::size_t lo, std::size_t hi) {
        for (std::size_t i = lo; i < hi; ++i) {
          x[i] += alpha * p[i];
          r[i] -= alpha * q[i];
        }
      });
      ++it;
      residual = std::sqrt(dot(r, r, partial)) / rhs_norm;
      if (residual <= options.tolerance) break;
      precondition();
      const double rz_next = dot(r, z, partial);
      const double beta = rz_next / rz;
      rz = rz_next;
      for_blocks(m, [&](std::size_t, std::size_t lo, std::size_t hi) {
        for (std::size_t i = lo; i < hi; ++i) p[i] = z[i] + beta * p[i];
      });
    }
    out.report.iterations = it;
    out.report.relative_residual = residual;
    if (residual > options.tolerance) {
      throw Error(ExitCode::failure,
                  fmt::format("interior field: conjugate gradients stopped at {} iterations with relative residual "
                              "{:.3g} (tolerance {:.3g})",
                              it, residual, options.tolerance));
    }
  }
  for (std::size_t i = 0; i < m; ++i) out.displacement[free_nodes[i]] = x[i];
  return out;
}

}  // namespace pneuma::field
