#pragma once
// Shapes with known area and volume, and small helpers shared by the mesh tests.
#include <Eigen/Geometry>
#include <cmath>
#include <numbers>

#include "pneuma/mesh/geometry/triangle_mesh.h"
#include "pneuma/mesh/io/mesh_io.h"

namespace pneuma::mesh::test {

// An axis-aligned cube of side `side` centred at `centre`, outward CCW triangles.
inline TriangleMesh make_cube(double side, const Eigen::Vector3d& centre = Eigen::Vector3d::Zero()) {
  TriangleMesh m;
  for (int i = 0; i < 8; ++i) {
    m.vertices.push_back(centre + side * Eigen::Vector3d((i & 1) - 0.5, ((i >> 1) & 1) - 0.5, ((i >> 2) & 1) - 0.5));
  }
  m.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                 {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  return m;
}

// A torus of radii R > r around the z axis: nu x nv vertices on the surface, 2 nu nv triangles.
inline TriangleMesh make_torus(double R, double r, int nu, int nv) {
  TriangleMesh m;
  for (int i = 0; i < nu; ++i) {
    for (int j = 0; j < nv; ++j) {
      const double u = 2 * std::numbers::pi * i / nu, v = 2 * std::numbers::pi * j / nv;
      m.vertices.emplace_back((R + r * std::cos(v)) * std::cos(u), (R + r * std::cos(v)) * std::sin(u),
                              r * std::sin(v));
    }
  }
  auto id = [&](int i, int j) { return static_cast<std::uint32_t>(((i + nu) % nu) * nv + (j + nv) % nv); };
  for (int i = 0; i < nu; ++i) {
    for (int j = 0; j < nv; ++j) {
      m.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      m.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  }
  return m;
}

inline TriangleMesh translated(TriangleMesh m, const Eigen::Vector3d& offset) {
  for (auto& v : m.vertices) v += offset;
  return m;
}

inline TriangleMesh joined(const TriangleMesh& a, const TriangleMesh& b) {
  TriangleMesh m = a;
  const auto n = static_cast<std::uint32_t>(a.vertices.size());
  m.vertices.insert(m.vertices.end(), b.vertices.begin(), b.vertices.end());
  for (Triangle t : b.triangles) m.triangles.push_back({t[0] + n, t[1] + n, t[2] + n});
  return m;
}

// The numbering read_mesh() gives back.
inline TriangleMesh canonical(TriangleMesh m) {
  renumber_vertices_by_first_use(m);
  return m;
}

}  // namespace pneuma::mesh::test
