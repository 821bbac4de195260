#pragma once
// A scalar image (a CT) read by the rules of read_label_map() (label_map.h): the format by the name's
// ending (.nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd), the NIfTI voxel-to-world transform by
// pneuma's rule from the header's own bytes (so that a CT and its label map overlay), the data
// the header promises checked against the file (also inside gzip) before anything is allocated,
// ITK 5.2 for the voxels; any numeric voxel type, as float.
#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <string>
#include <vector>

namespace pneuma::image {

struct ScalarImage {
  std::array<std::size_t, 3> size{0, 0, 0};
  Eigen::Matrix4d ijk_to_lps = Eigen::Matrix4d::Identity();  // metres, LPS, as LabelMap's
  std::string transform_source;                              // "sform", "qform", ... as LabelMap's
  std::vector<float> values;                                 // i fastest

  std::size_t voxel_count() const { return size[0] * size[1] * size[2]; }
};

// Throws IoError when the file cannot be opened and InputError ("<file>: <what was expected>")
// when it is not a 3D scalar image of a known format or is truncated.
ScalarImage read_scalar_image(const std::filesystem::path& path);

}  // namespace pneuma::image
