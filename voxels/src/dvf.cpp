// The forward and pull-back DVFs: the lungs' tets rasterised (rasterize.h), then the voxels
// outside every lung from the OutsideField.
#include "pneuma/voxels/dvf.h"

#include <algorithm>
#include <numeric>
#include <string>

#include "pneuma/core/error.h"
#include "pneuma/core/fresh_pages.h"
#include "rasterize.h"

namespace pneuma::voxels {

std::size_t DisplacementField::inside_count() const {
  return static_cast<std::size_t>(std::count_if(lung.begin(), lung.end(), [](std::uint8_t l) { return l != 0; }));
}

DisplacementField forward_dvf(const Grid& grid, std::span<const LungMotion> lungs, const OutsideField& outside) {
  DisplacementField field;
  forward_dvf(grid, lungs, field, outside);
  return field;
}

DisplacementField pullback_dvf(const Grid& grid, std::span<const LungMotion> lungs, const OutsideField& outside) {
  DisplacementField field;
  pullback_dvf(grid, lungs, field, outside);
  return field;
}

std::vector<std::uint8_t> rest_lungs(const Grid& grid, std::span<const LungMotion> lungs) {
  const std::vector<detail::TetSet> sets = detail::rest_tet_sets(lungs);
  std::vector<std::uint8_t> owner;
  detail::rasterize(
      grid, std::span<const detail::TetSet>(sets), owner,
      [](std::size_t, std::size_t, std::size_t, const Eigen::Vector4d&, std::size_t, std::size_t, std::size_t) {},
      [](std::size_t, std::size_t, std::size_t, std::size_t) {});
  return owner;
}

bool RestRaster::holds(const Grid& on, std::span<const LungMotion> lungs) const {
  if (on.size != grid.size || on.ijk_to_lps != grid.ijk_to_lps || lungs.size() != tets.size() ||
      grid.voxel_count() == 0)
    return false;
  for (std::size_t s = 0; s < lungs.size(); ++s) {
    if (!std::equal(lungs[s].mesh.tets.begin(), lungs[s].mesh.tets.end(), tets[s].begin(), tets[s].end()) ||
        !std::equal(lungs[s].mesh.nodes.begin(), lungs[s].mesh.nodes.end(), nodes[s].begin(), nodes[s].end()))
      return false;
  }
  return true;
}

void forward_dvf(const Grid& grid, std::span<const LungMotion> lungs, DisplacementField& field,
                 const OutsideField& outside, RestRaster* rest) {
  field.grid = grid;
  core::resize_mapped(field.displacement_m, grid.voxel_count());  // not zeroed: rasterize() writes every voxel once
  const auto visit = [&](std::size_t v, std::size_t s, std::size_t t, const Eigen::Vector4d& l) {
    field.displacement_m[v] = detail::tet_displacement(lungs[s], t, l).cast<float>();
  };
  const auto empty = [&](std::size_t v, std::size_t i, std::size_t j, std::size_t k) {
    detail::set_outside(field, outside, v, i, j, k);
  };
  detail::rasterize_rest_tets(grid, lungs, rest, field.lung, visit, empty);
}

void pullback_dvf(const Grid& grid, std::span<const LungMotion> lungs, DisplacementField& field,
                  const OutsideField& outside) {
  std::vector<detail::TetSet> sets = detail::rest_tet_sets(lungs);  // checked; their nodes moved below
  std::vector<std::vector<Eigen::Vector3d>> deformed(lungs.size());
  for (std::size_t s = 0; s < lungs.size(); ++s) {
    const LungMotion& lung = lungs[s];
    deformed[s].resize(lung.mesh.node_count());
    for (std::size_t n = 0; n < deformed[s].size(); ++n) {
      deformed[s][n] = mesh::moved_node(lung.mesh.nodes[n], lung.unit_displacement_m[n], lung.scale);
    }
    sets[s].nodes = deformed[s];
  }
  field.grid = grid;
  core::resize_mapped(field.displacement_m, grid.voxel_count());  // not zeroed: rasterize() writes every voxel once
  detail::rasterize(
      grid, std::span<const detail::TetSet>(sets), field.lung,
      [&](std::size_t v, std::size_t s, std::size_t t, const Eigen::Vector4d& l, std::size_t, std::size_t,
          std::size_t) {
        // x = sum l_c (rest_c + s U_c), so the rest point is x - s sum l_c U_c: v = -s sum l_c U_c,
        // the same inverse without cancelling coordinates against each other (a time point at rest,
        // s = 0, is an exact zero field, not rounding noise).
        field.displacement_m[v] = (-detail::tet_displacement(lungs[s], t, l)).cast<float>();
      },
      [&](std::size_t v, std::size_t i, std::size_t j, std::size_t k) {
        detail::set_outside(field, outside, v, i, j, k);
      });
}

}  // namespace pneuma::voxels
