#pragma once
// Voxel files written through ITK 5.2 (voxels_itk.cpp, the module's one ITK translation unit), by the
// name's ending: .nii / .nii.gz (NIfTI-1) or .mha (MetaImage, one file). Every file is written
// atomically (a temporary name in the same folder, then a rename): a failure leaves nothing.
//
// DVFs: 3 float32 components per voxel in LPS millimetres (ITK's convention for vector images,
// which ITK 5.2's NIfTI writer stores as they are: dim = (nx, ny, nz, 1, 3), intent_code 1007
// NIFTI_INTENT_VECTOR; plastimatch, ANTs and ITK-based tools read them so), on the grid's
// geometry (qform and sform; NIfTI's RAS+ world, so the affine is diag(-1, -1, 1) * ijk_to_lps,
// in mm). Label maps: the smallest of uint8, int16 or int32 holding every label. Images: float32.
#include <filesystem>

#include "pneuma/image/label_map.h"
#include "pneuma/voxels/dvf.h"
#include "pneuma/voxels/warp.h"

namespace pneuma::voxels {

// Throws ValueError for another ending and IoError when the file cannot be written.
void write_dvf(const std::filesystem::path& path, const DisplacementField& field);
void write_label_map(const std::filesystem::path& path, const image::LabelMap& map);
void write_image(const std::filesystem::path& path, const Image& image);

// A scalar image (a CT) of any numeric voxel type, as float, by image::read_scalar_image()
// (pneuma/image/scalar_image.h: read_label_map()'s formats, transform rule and checks). Throws
// IoError when the file cannot be opened and InputError "<file>: <what was expected>" when it is
// not a 3D scalar image of a known format or is truncated.
Image read_image(const std::filesystem::path& path);

}  // namespace pneuma::voxels
