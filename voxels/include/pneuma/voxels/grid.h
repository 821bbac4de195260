#pragma once
// A voxel grid: its size and the map from voxel indices to DICOM LPS metres, as a LabelMap has
// them. Voxel (i, j, k) is number i + nx * (j + ny * k) and its centre lies at
// ijk_to_lps * (i, j, k, 1).
#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <utility>

#include "pneuma/image/label_map.h"

namespace pneuma::voxels {

struct Grid {
  std::array<std::size_t, 3> size{0, 0, 0};
  Eigen::Matrix4d ijk_to_lps = Eigen::Matrix4d::Identity();  // metres, LPS

  std::size_t voxel_count() const { return size[0] * size[1] * size[2]; }
  std::size_t index(std::size_t i, std::size_t j, std::size_t k) const { return i + size[0] * (j + size[1] * k); }
  // Inline: the voxel loops ask it at every voxel (#50).
  Eigen::Vector3d centre_m(std::size_t i, std::size_t j, std::size_t k) const {
    return ijk_to_lps.block<3, 3>(0, 0) *
               Eigen::Vector3d(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k)) +
           ijk_to_lps.block<3, 1>(0, 3);
  }
  // The axis-aligned box (LPS metres) of the voxel centres: the least and the greatest corner.
  std::pair<Eigen::Vector3d, Eigen::Vector3d> centres_box_m() const;
  // Lengths of the voxel edges along i, j, k (metres).
  Eigen::Vector3d spacing_m() const;
  double voxel_volume_m3() const;
  // LPS metres -> continuous index (voxel centres at integers).
  Eigen::Matrix4d lps_to_ijk() const;
};

// The grid of a label map (same size and transform).
Grid grid_of(const image::LabelMap& map);

// A grid over the same extent (the box from the first voxel's outer corner to the last voxel's
// outer corner, along the same axes) with voxels of `spacing_m` along every axis: size
// ceil(extent / spacing) per axis, first voxel's outer corner on the extent's, so the last
// voxel may reach out by less than one voxel. Throws ValueError for a spacing that is not
// positive and finite or that would make a grid of more than 2^31 voxels.
Grid grid_with_spacing(const Grid& grid, double spacing_m);

}  // namespace pneuma::voxels
