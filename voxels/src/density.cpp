// The Jacobian image and the mass-preserving CT (density.h): the lungs' rest tets rasterised
// (rasterize.h), the image with the recovered gradient's Jacobian at each voxel's rest point, the
// CT with each tet's exact Jacobian; outside the lungs, central differences of the field.
#include "pneuma/voxels/density.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/LU>  // determinant(), inverse()
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/core/fresh_pages.h"
#include "pneuma/core/tsan.h"
#include "pneuma/voxels/jacobian.h"
#include "rasterize.h"

namespace pneuma::voxels {
namespace {

// Each lung's tets at rest, and the Jacobian of each tet at the lung's scale: the mass-preserving
// CT's, which keeps each tet's mass exactly (rest HU + 1000 over J, times J; the recovered
// Jacobian lost 0.04-0.14 % more of the lungs' mass at end-inspiration on the six CT cases:
// docs/voxels.md, "Density and ventilation").
struct RestTets {
  std::vector<detail::TetSet> sets;
  std::vector<std::vector<double>> jacobians;
};

RestTets rest_tets(std::span<const LungMotion> lungs) {
  RestTets out{detail::rest_tet_sets(lungs), {}};
  for (const LungMotion& lung : lungs) out.jacobians.push_back(tet_jacobians(lung));
  return out;
}

// Each lung's recovered gradients, each lung's own: nothing is averaged across the pleura.
std::vector<std::vector<Eigen::Matrix3d>> lung_gradients(std::span<const LungMotion> lungs) {
  std::vector<std::vector<Eigen::Matrix3d>> out;
  out.reserve(lungs.size());
  for (const LungMotion& lung : lungs) out.push_back(recovered_gradients(lung));
  return out;
}

}  // namespace

float mass_preserving_hu(float hu, double jacobian) {
  if (!(hu >= kAirHu && hu <= kWaterHu) || !(jacobian > 0.0)) return hu;
  const double moved = (static_cast<double>(hu) - kAirHu) / jacobian + kAirHu;
  return static_cast<float>(std::clamp(moved, static_cast<double>(kAirHu), static_cast<double>(kWaterHu)));
}

namespace {

// jacobian_image's voxels outside the lungs (`owner` 0): central differences of the field.
void jacobian_outside(const DisplacementField& forward, const std::vector<std::uint8_t>& owner, Image& out) {
  const Grid& grid = forward.grid;
  // grad u = (du/d index) (d index/dx): the grid's direction and spacing, inverted once.
  const Eigen::Matrix3d to_index = grid.ijk_to_lps.block<3, 3>(0, 0).inverse();
  const std::size_t nx = grid.size[0], ny = grid.size[1], nz = grid.size[2];
  const std::array<std::size_t, 3> stride{1, nx, nx * ny};
  const tsan::Region region;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nz), region.wrap([&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t k = r.begin(); k != r.end(); ++k) {
      for (std::size_t j = 0; j < ny; ++j) {
        for (std::size_t i = 0; i < nx; ++i) {
          const std::size_t v = i + nx * (j + ny * k);
          if (owner[v] != 0) continue;
          // Central differences between the neighbours outside the lungs, one-sided where only one
          // is, 0 where neither is; the neighbours found by their strides (the voxel stage runs
          // this at every voxel outside the lungs of every time point, #50).
          const std::array<std::size_t, 3> at{i, j, k};
          Eigen::Matrix3d d;
          for (std::size_t a = 0; a < 3; ++a) {
            const std::size_t step = stride[a];
            const bool has_lo = at[a] > 0 && owner[v - step] == 0;
            const bool has_hi = at[a] + 1 < grid.size[a] && owner[v + step] == 0;
            const auto u = [&](std::size_t w) { return forward.displacement_m[w].cast<double>(); };
            const auto col = static_cast<Eigen::Index>(a);
            if (has_lo && has_hi) {
              d.col(col) = 0.5 * (u(v + step) - u(v - step));
            } else if (has_hi) {
              d.col(col) = u(v + step) - u(v);
            } else if (has_lo) {
              d.col(col) = u(v) - u(v - step);
            } else {
              d.col(col).setZero();
            }
          }
          out.values[v] = static_cast<float>((Eigen::Matrix3d::Identity() + d * to_index).determinant());
        }
      }
    }
  }));
  region.join();
}

}  // namespace

void jacobian_image(std::span<const LungMotion> lungs, const DisplacementField& forward, Image& out) {
  const std::vector<detail::TetSet> sets = detail::rest_tet_sets(lungs);
  const std::vector<std::vector<Eigen::Matrix3d>> gradients = lung_gradients(lungs);
  const Grid& grid = forward.grid;
  if (forward.displacement_m.size() != grid.voxel_count())
    throw ValueError("jacobian_image: the forward field does not fill its grid");
  out.grid = grid;
  core::resize_mapped(out.values, grid.voxel_count());
  std::vector<std::uint8_t> owner;
  detail::rasterize(
      grid, std::span<const detail::TetSet>(sets), owner,
      [&](std::size_t v, std::size_t s, std::size_t t, const Eigen::Vector4d& l, std::size_t, std::size_t,
          std::size_t) { out.values[v] = static_cast<float>(recovered_jacobian(gradients[s], sets[s].tets[t], l)); },
      [&](std::size_t, std::size_t, std::size_t, std::size_t) {});
  jacobian_outside(forward, owner, out);
}

void forward_dvf_with_jacobian(const Grid& grid, std::span<const LungMotion> lungs, DisplacementField& field,
                               const OutsideField& outside, Image& jacobian, RestRaster* rest) {
  forward_dvf_with_rest_images(grid, lungs, field, outside, RestImages{&jacobian}, rest);
}

void forward_dvf_with_rest_images(const Grid& grid, std::span<const LungMotion> lungs, DisplacementField& field,
                                  const OutsideField& outside, const RestImages& images, RestRaster* rest) {
  Image* const jacobian = images.jacobian;
  const Image* const ct = images.mass_preserving_ct != nullptr ? images.ct : nullptr;
  if (ct != nullptr &&
      (ct->grid.size != grid.size || ct->grid.ijk_to_lps != grid.ijk_to_lps || ct->values.size() != grid.voxel_count()))
    throw ValueError("forward_dvf_with_rest_images: the CT is not on the field's grid");
  std::vector<std::vector<Eigen::Matrix3d>> gradients;
  std::vector<std::vector<double>> tet_j;  // each tet's exact Jacobian, as mass_preserving_ct's
  for (const LungMotion& lung : lungs) check_lung_motion(lung);
  if (jacobian != nullptr) gradients = lung_gradients(lungs);
  if (ct != nullptr)
    for (const LungMotion& lung : lungs) tet_j.push_back(tet_jacobians(lung));
  field.grid = grid;
  core::resize_mapped(field.displacement_m, grid.voxel_count());  // not zeroed: rasterize() writes every voxel once
  if (jacobian != nullptr) {
    jacobian->grid = grid;
    core::resize_mapped(jacobian->values,
                        grid.voxel_count());  // the lungs' voxels here, the rest by jacobian_image_outside
  }
  Image* const preserved = ct != nullptr ? images.mass_preserving_ct : nullptr;
  if (preserved != nullptr) {
    preserved->grid = ct->grid;
    core::resize_mapped(preserved->values, ct->values.size());
  }
  const auto visit = [&](std::size_t v, std::size_t s, std::size_t t, const Eigen::Vector4d& l) {
    field.displacement_m[v] = detail::tet_displacement(lungs[s], t, l).cast<float>();
    if (jacobian != nullptr)
      jacobian->values[v] = static_cast<float>(recovered_jacobian(gradients[s], lungs[s].mesh.tets[t], l));
    if (preserved != nullptr) preserved->values[v] = mass_preserving_hu(ct->values[v], tet_j[s][t]);
  };
  const auto empty = [&](std::size_t v, std::size_t i, std::size_t j, std::size_t k) {
    detail::set_outside(field, outside, v, i, j, k);
    if (preserved != nullptr) preserved->values[v] = ct->values[v];
  };
  detail::rasterize_rest_tets(grid, lungs, rest, field.lung, visit, empty);
}

void jacobian_image_outside(const DisplacementField& forward, Image& out) {
  if (forward.displacement_m.size() != forward.grid.voxel_count() ||
      forward.lung.size() != forward.grid.voxel_count() || out.grid.size != forward.grid.size ||
      out.values.size() != forward.grid.voxel_count())
    throw ValueError("jacobian_image_outside: expected forward_dvf_with_jacobian's field and image");
  jacobian_outside(forward, forward.lung, out);
}

void mass_preserving_ct(const Image& rest_ct, std::span<const LungMotion> lungs, Image& out,
                        std::vector<std::uint8_t>& rest_lung) {
  const RestTets tets = rest_tets(lungs);
  out.grid = rest_ct.grid;
  core::resize_mapped(out.values, rest_ct.values.size());
  detail::rasterize(
      rest_ct.grid, std::span<const detail::TetSet>(tets.sets), rest_lung,
      [&](std::size_t v, std::size_t s, std::size_t t, const Eigen::Vector4d&, std::size_t, std::size_t, std::size_t) {
        out.values[v] = mass_preserving_hu(rest_ct.values[v], tets.jacobians[s][t]);
      },
      [&](std::size_t v, std::size_t, std::size_t, std::size_t) { out.values[v] = rest_ct.values[v]; });
}

}  // namespace pneuma::voxels
