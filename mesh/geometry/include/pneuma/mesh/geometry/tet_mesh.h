#pragma once
// A tetrahedral mesh of a lung's inside, in metres (LPS), and the per-node fields on it. Plain
// Eigen code: meshing (CGAL Mesh_3) lives in mesh/volume, the interior field in field/,
// sampling on voxel grids in voxels/.
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

// The one `rest + s u` of the inside (mesh::DeformedSurface is the surface's): node x moved by
// the breath s along its unit displacement u. Every tetrahedral position in pneuma (DVFs,
// Jacobians, the unfolding) is made here, so they agree bit for bit.
inline Eigen::Vector3d moved_node(const Eigen::Vector3d& x, const Eigen::Vector3d& u, double s) { return x + s * u; }

// The corners of tet `q` of `mesh` at the breath s, with `u` per node.
inline std::array<Eigen::Vector3d, 4> moved_corners(const TetMesh& mesh, const Tetrahedron& q,
                                                    const std::vector<Eigen::Vector3d>& u, double s) {
  std::array<Eigen::Vector3d, 4> x;
  for (std::size_t c = 0; c < 4; ++c) x[c] = moved_node(mesh.nodes[q[c]], u[q[c]], s);
  return x;
}

// Six times the signed volume of tet `q` at the breath s.
inline double deformed_volume6(const TetMesh& mesh, const Tetrahedron& q, const std::vector<Eigen::Vector3d>& u,
                               double s) {
  const std::array<Eigen::Vector3d, 4> x = moved_corners(mesh, q, u, s);
  return tet_volume6(x[0], x[1], x[2], x[3]);
}

}  // namespace pneuma::mesh
