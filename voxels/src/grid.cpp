#include "pneuma/voxels/grid.h"

#include <Eigen/LU>  // inverse()

#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "pneuma/core/error.h"

namespace pneuma::voxels {

std::pair<Eigen::Vector3d, Eigen::Vector3d> Grid::centres_box_m() const {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d p = centre_m((c & 1) ? size[0] - 1 : 0, (c & 2) ? size[1] - 1 : 0, (c & 4) ? size[2] - 1 : 0);
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return {lo, hi};
}

Eigen::Vector3d Grid::spacing_m() const {
  return {ijk_to_lps.block<3, 1>(0, 0).norm(), ijk_to_lps.block<3, 1>(0, 1).norm(),
          ijk_to_lps.block<3, 1>(0, 2).norm()};
}

double Grid::voxel_volume_m3() const { return std::abs(ijk_to_lps.block<3, 3>(0, 0).determinant()); }

Eigen::Matrix4d Grid::lps_to_ijk() const { return ijk_to_lps.inverse(); }

Grid grid_of(const image::LabelMap& map) { return Grid{map.size, map.ijk_to_lps}; }

Grid grid_with_spacing(const Grid& grid, double spacing_m) {
  if (!(spacing_m > 0.0) || !std::isfinite(spacing_m)) {
    throw ValueError("voxel spacing " + std::to_string(spacing_m) + " m: expected a positive length");
  }
  const Eigen::Vector3d old_spacing_m = grid.spacing_m();
  const Eigen::Vector3d corner_m =
      grid.ijk_to_lps.block<3, 3>(0, 0) * Eigen::Vector3d::Constant(-0.5) + grid.ijk_to_lps.block<3, 1>(0, 3);
  Grid out;
  double voxels = 1.0;
  Eigen::Vector3d origin_m = corner_m;
  for (int a = 0; a < 3; ++a) {
    const auto au = static_cast<std::size_t>(a);
    const double extent_m = static_cast<double>(grid.size[au]) * old_spacing_m[a];
    const double n = std::max(1.0, std::ceil(extent_m / spacing_m - 1e-9));
    voxels *= n;
    if (!(voxels <= 2147483648.0)) {
      throw ValueError("voxel spacing " + std::to_string(spacing_m * 1e3) +
                       " mm: expected a grid of at most 2^31 voxels over the image's extent");
    }
    out.size[au] = static_cast<std::size_t>(n);
    const Eigen::Vector3d axis = grid.ijk_to_lps.block<3, 1>(0, a) / old_spacing_m[a];
    out.ijk_to_lps.block<3, 1>(0, a) = axis * spacing_m;
    origin_m += axis * (0.5 * spacing_m);
  }
  out.ijk_to_lps.block<3, 1>(0, 3) = origin_m;
  return out;
}

}  // namespace pneuma::voxels
