#pragma once
// Small meshes and oracles shared by the field tests.
#include <Eigen/Core>
#include <cmath>
#include <vector>

#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::test {

// A flat nx x ny grid of squares (spacing h), each split into two triangles: a regular mesh.
inline mesh::TriangleMesh regular_grid(int nx, int ny, double h) {
  mesh::TriangleMesh m;
  for (int j = 0; j <= ny; ++j) {
    for (int i = 0; i <= nx; ++i) m.vertices.emplace_back(i * h, j * h, 0.0);
  }
  auto id = [nx](int i, int j) { return static_cast<std::uint32_t>(j * (nx + 1) + i); };
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      m.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      m.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  }
  return m;
}

inline mesh::TriangleMesh single_triangle() {
  mesh::TriangleMesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 2, 0}};
  m.triangles = {{0, 1, 2}};
  return m;
}

// An ellipsoid: an icosphere scaled along the axes (irregular edge lengths).
inline mesh::TriangleMesh ellipsoid(double a, double b, double c, int subdivisions) {
  mesh::TriangleMesh m = mesh::make_icosphere(1.0, subdivisions);
  for (auto& v : m.vertices) v = Eigen::Vector3d(a * v.x(), b * v.y(), c * v.z());
  return m;
}

// Shear modulus rising linearly along `axis` (default z) from `low` at the bottom to `high` at the top.
inline std::vector<double> graded_modulus(const mesh::TriangleMesh& m, double low, double high, int axis = 2) {
  const auto box = mesh::bounding_box(m.vertices);
  const double span = box[1][axis] - box[0][axis];
  std::vector<double> mu;
  for (const auto& v : m.vertices) mu.push_back(low + (high - low) * (v[axis] - box[0][axis]) / span);
  return mu;
}

// 100:1 contrast: stiff (100) where x > 0, soft (1) elsewhere.
inline std::vector<double> contrast_modulus(const mesh::TriangleMesh& m) {
  std::vector<double> mu;
  for (const auto& v : m.vertices) mu.push_back(v.x() > 0 ? 100e3 : 1e3);
  return mu;
}

inline double max_abs_difference(const std::vector<double>& a, const std::vector<double>& b, std::size_t n) {
  double worst = 0.0;
  for (std::size_t i = 0; i < n; ++i) worst = std::max(worst, std::abs(a[i] - b[i]));
  return worst;
}

}  // namespace pneuma::test
