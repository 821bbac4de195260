#include "pneuma/voxels/jacobian.h"

#include <Eigen/Geometry>  // cross(), used by tet_mesh.h's tet_volume6
#include <Eigen/LU>        // determinant(), inverse()
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "pneuma/core/parallel.h"

namespace pneuma::voxels {

std::vector<double> tet_jacobians(const LungMotion& lung) {
  check_lung_motion(lung);
  const mesh::TetMesh& m = lung.mesh;
  std::vector<double> out(m.tet_count());
  const auto moved = [&](std::uint32_t n) {
    return mesh::moved_node(m.nodes[n], lung.unit_displacement_m[n], lung.scale);
  };
  // Each tet writes its own slot, on every core (#50: a time point and each of the report's
  // slices ask for every tet of both lungs).
  core::for_each_index(out.size(), [&](std::size_t t) {
    const mesh::Tetrahedron& tet = m.tets[t];
    const double rest6 = mesh::tet_volume6(m.nodes[tet[0]], m.nodes[tet[1]], m.nodes[tet[2]], m.nodes[tet[3]]);
    const double deformed6 = mesh::tet_volume6(moved(tet[0]), moved(tet[1]), moved(tet[2]), moved(tet[3]));
    out[t] = deformed6 / rest6;
  });
  return out;
}

std::vector<Eigen::Matrix3d> recovered_gradients(const LungMotion& lung) {
  check_lung_motion(lung);
  const mesh::TetMesh& m = lung.mesh;
  // Each tet's gradient on every core, then summed into its nodes in the tets' order on one (the
  // same sums in the same order at any thread count).
  std::vector<Eigen::Matrix3d> gradient(m.tet_count());
  std::vector<double> rest6(m.tet_count());
  core::for_each_index(m.tet_count(), [&](std::size_t t) {
    const mesh::Tetrahedron& tet = m.tets[t];
    Eigen::Matrix3d edges, moves;
    for (Eigen::Index c = 0; c < 3; ++c) {
      const std::uint32_t n = tet[static_cast<std::size_t>(c) + 1];
      edges.col(c) = m.nodes[n] - m.nodes[tet[0]];
      moves.col(c) = lung.unit_displacement_m[n] - lung.unit_displacement_m[tet[0]];
    }
    rest6[t] = edges.determinant();
    // A degenerate rest tet has no gradient (and holds no voxel).
    // grad U maps each rest edge to its displacement difference: moves = grad U edges.
    if (rest6[t] > 0.0) gradient[t] = lung.scale * moves * edges.inverse();
  });
  std::vector<Eigen::Matrix3d> sum(m.node_count(), Eigen::Matrix3d::Zero());
  std::vector<double> weight(m.node_count(), 0.0);
  for (std::size_t t = 0; t < m.tet_count(); ++t) {
    if (!(rest6[t] > 0.0)) continue;
    for (const std::uint32_t n : m.tets[t]) {
      sum[n] += rest6[t] * gradient[t];
      weight[n] += rest6[t];
    }
  }
  for (std::size_t n = 0; n < sum.size(); ++n)
    if (weight[n] > 0.0) sum[n] /= weight[n];
  return sum;
}

double recovered_jacobian(std::span<const Eigen::Matrix3d> gradients, const mesh::Tetrahedron& tet,
                          const Eigen::Vector4d& l) {
  Eigen::Matrix3d g = Eigen::Matrix3d::Identity();
  for (std::size_t c = 0; c < 4; ++c) g += l[static_cast<Eigen::Index>(c)] * gradients[tet[c]];
  return g.determinant();
}

JacobianStats jacobian_stats(std::span<const LungMotion> lungs) {
  JacobianStats stats;
  stats.min = std::numeric_limits<double>::infinity();
  stats.max = -std::numeric_limits<double>::infinity();
  double folded_volume_m3 = 0.0;
  for (const LungMotion& lung : lungs) {
    const std::vector<double> jacobians = tet_jacobians(lung);
    const mesh::TetMesh& m = lung.mesh;
    for (std::size_t t = 0; t < jacobians.size(); ++t) {
      const mesh::Tetrahedron& tet = m.tets[t];
      const double rest_m3 =
          mesh::tet_volume6(m.nodes[tet[0]], m.nodes[tet[1]], m.nodes[tet[2]], m.nodes[tet[3]]) / 6.0;
      const double j = jacobians[t];
      stats.min = std::min(stats.min, j);
      stats.max = std::max(stats.max, j);
      stats.rest_volume_m3 += rest_m3;
      stats.deformed_volume_m3 += j * rest_m3;
      if (!(j > 0.0)) ++stats.folded_tets, folded_volume_m3 += rest_m3;
    }
    stats.tets += jacobians.size();
  }
  if (stats.tets == 0) {
    stats.min = stats.max = 0.0;
    return stats;
  }
  stats.folded_count_fraction = static_cast<double>(stats.folded_tets) / static_cast<double>(stats.tets);
  stats.folded_volume_fraction = stats.rest_volume_m3 > 0.0 ? folded_volume_m3 / stats.rest_volume_m3 : 0.0;
  return stats;
}

}  // namespace pneuma::voxels
