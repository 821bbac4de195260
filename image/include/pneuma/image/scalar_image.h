#pragma once
// A scalar image (a CT) read by the rules of read_label_map() (label_map.h): the format by the name's
// ending (.nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd), the NIfTI voxel-to-world transform by
// pneuma's rule from the header's own bytes (so that a CT and its label map overlay), the data
// the header promises checked against the file (also inside gzip) before anything is allocated,
// ITK 5.2 for the voxels; any numeric voxel type, as float. A folder is a DICOM CT series
// (dicom.h; DCMTK): Hounsfield units from the rescale slope and intercept, the grid from
// ImagePositionPatient, ImageOrientationPatient and PixelSpacing, slices in order along the normal.
#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "pneuma/image/dicom.h"

namespace pneuma::image {

struct ScalarImage {
  std::array<std::size_t, 3> size{0, 0, 0};
  Eigen::Matrix4d ijk_to_lps = Eigen::Matrix4d::Identity();  // metres, LPS, as LabelMap's
  std::string transform_source;                              // "sform", "qform", ... as LabelMap's
  std::vector<float> values;                                 // i fastest
  std::optional<DicomSource> dicom;                          // a DICOM series' patient, study, frame

  std::size_t voxel_count() const { return size[0] * size[1] * size[2]; }
};

struct ScalarImageOptions {
  // A folder holding several DICOM series: the one to read (empty: the folder must hold one).
  std::string series_instance_uid;
};

// Throws IoError when the file cannot be opened and InputError ("<file>: <what was expected>";
// for DICOM "<file>: (0008,0060) Modality: <what was expected>") when it is not a 3D scalar
// image of a known format or is truncated.
ScalarImage read_scalar_image(const std::filesystem::path& path, const ScalarImageOptions& options = {});

}  // namespace pneuma::image
