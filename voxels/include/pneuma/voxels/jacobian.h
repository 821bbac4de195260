#pragma once
// The Jacobian determinant of the forward map x -> x + s U(x), exact for P1 tets: constant in
// each tet, det(I + s grad U) = (deformed signed volume) / (rest volume). And the same map's
// recovered gradient: continuous across the tets, without the per-tet steps of the exact one.
#include <Eigen/Core>
#include <cstddef>
#include <span>
#include <vector>

#include "pneuma/voxels/lung_motion.h"

namespace pneuma::voxels {

struct JacobianStats {
  std::size_t tets = 0;
  double min = 0.0, max = 0.0;          // over the tets
  std::size_t folded_tets = 0;          // det <= 0
  double folded_count_fraction = 0.0;   // folded_tets / tets
  double folded_volume_fraction = 0.0;  // rest volume of the folded tets / rest volume
  double rest_volume_m3 = 0.0;          // sum of the rest tets' volumes
  double deformed_volume_m3 = 0.0;      // sum of the deformed tets' signed volumes
};

// det(I + s grad U) of each tet, in the mesh's order.
std::vector<double> tet_jacobians(const LungMotion& lung);

// The recovered displacement gradient s grad U at each node: the mean of the P1 gradients of the
// node's tets weighted by their rest volumes (one lung's tets only; a node of no tet gets zero).
// Interpolated linearly inside each tet (recovered_jacobian), it is the gradient recovery of
// finite elements: exact for an affine map, and at nodes whose tets surround them symmetrically
// exact for a quadratic one, so one order more accurate inside the mesh than the per-tet gradient
// (first order at the lung's surface). The per-tet Jacobians step by a few % from tet to tet where
// the field bends (docs/voxels.md, "The lung on the heart"); the recovered one does not.
// Sums in the mesh's tet order: the same at any thread count. Throws ValueError as
// check_lung_motion().
std::vector<Eigen::Matrix3d> recovered_gradients(const LungMotion& lung);

// det(I + sum_c l_c G_c) over the corners c of `tet` with barycentric coordinates `l`: the
// Jacobian of the recovered gradient `gradients` (recovered_gradients of the tet's lung) there.
double recovered_jacobian(std::span<const Eigen::Matrix3d> gradients, const mesh::Tetrahedron& tet,
                          const Eigen::Vector4d& l);

// Over every tet of every lung (sums in a fixed order). Throws ValueError as check_lung_motion().
JacobianStats jacobian_stats(std::span<const LungMotion> lungs);

}  // namespace pneuma::voxels
