#pragma once
// Private to mesh/volume: tet quality and the lattice mesher, shared by the two meshers.
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include "pneuma/mesh/volume/tetrahedralize.h"

namespace pneuma::mesh::detail {

// The smallest of the six dihedral angles (degrees): between the two faces at each edge.
inline double min_dihedral_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                               const Eigen::Vector3d& d) {
  const std::array<Eigen::Vector3d, 4> p{a, b, c, d};
  // Outward face normals (face i opposite vertex i); the dihedral at the edge shared by faces i
  // and j is pi minus the angle between their outward normals.
  std::array<Eigen::Vector3d, 4> normal;
  for (std::size_t i = 0; i < 4; ++i) {
    const Eigen::Vector3d& q0 = p[(i + 1) % 4];
    Eigen::Vector3d n = (p[(i + 2) % 4] - q0).cross(p[(i + 3) % 4] - q0);
    if (n.dot(p[i] - q0) > 0.0) n = -n;
    normal[i] = n.normalized();
  }
  double smallest = 180.0;
  for (std::size_t i = 0; i < 4; ++i) {
    for (std::size_t j = i + 1; j < 4; ++j) {
      const double cosine = std::clamp(-normal[i].dot(normal[j]), -1.0, 1.0);
      smallest = std::min(smallest, std::acos(cosine) * 180.0 / std::numbers::pi);
    }
  }
  return smallest;
}

// TetMesher::lattice for a surface already checked to be closed (tetrahedralize_lattice.cpp).
VolumeMesh tetrahedralize_lattice(const TriangleMesh& closed_surface, double edge_m);

}  // namespace pneuma::mesh::detail
