#pragma once
// A tetrahedral mesh of a lung's inside, in metres (LPS), and the per-node fields on it. Plain
// Eigen code: meshing (CGAL Mesh_3) lives in mesh/volume, the interior field in engine/field,
// sampling on voxel grids in engine/voxels.
#include <Eigen/Core>
#include <Eigen/Geometry>  // cross(), in tet_volume6
#include <array>
#include <cstdint>
#include <vector>

namespace pneuma::mesh {

// Node indices of one tetrahedron, ordered so that its signed volume is positive:
// (b - a) . ((c - a) x (d - a)) > 0.
using Tetrahedron = std::array<std::uint32_t, 4>;

struct TetMesh {
  std::vector<Eigen::Vector3d> nodes;  // metres
  std::vector<Tetrahedron> tets;

  std::size_t node_count() const { return nodes.size(); }
  std::size_t tet_count() const { return tets.size(); }
};

// Six times the signed volume of (a, b, c, d): (b - a) . ((c - a) x (d - a)).
inline double tet_volume6(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                          const Eigen::Vector3d& d) {
  return (b - a).dot((c - a).cross(d - a));
}

}  // namespace pneuma::mesh
