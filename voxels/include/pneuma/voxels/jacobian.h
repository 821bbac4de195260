#pragma once
// The Jacobian determinant of the forward map x -> x + s U(x), exact for P1 tets: constant in
// each tet, det(I + s grad U) = (deformed signed volume) / (rest volume).
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

// Over every tet of every lung (sums in a fixed order). Throws ValueError as check_lung_motion().
JacobianStats jacobian_stats(std::span<const LungMotion> lungs);

}  // namespace pneuma::voxels
