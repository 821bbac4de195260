#pragma once
// Voxel files by the name's ending: .nii / .nii.gz (NIfTI-1, written from memory with ITK 5.2's
// header: voxels/src/nifti_write.h), .mha (MetaImage, one file) or .nrrd (NRRD, one file, gzip),
// these two through ITK 5.2 (voxels_itk.cpp, the module's one ITK C++ translation unit). Every
// file is written atomically (a temporary name in the same folder, then a rename): a failure
// leaves nothing.
//
// DVFs: 3 float32 components per voxel in millimetres, on the grid's geometry, each file saying
// which way it points and in which frame its components are (docs/formats.md, "Which reader reads
// which DVF"):
// - NIfTI, DvfConvention::itk (the default): the components in LPS as ITK 5.2's NIfTI writer
//   stores vector images (dim = (nx, ny, nz, 1, 3), intent_code 1007 NIFTI_INTENT_VECTOR;
//   plastimatch, elastix 5.0 and ITK 5.2 read them so); DvfConvention::nifti: in RAS with
//   intent_code 1006 NIFTI_INTENT_DISPVECT, the NIfTI standard's vectors (nibabel, ITK >= 5.3).
//   Either way `descrip` names the direction, the frame and the jump at the pleura. The qform and
//   sform are the grid's in NIfTI's RAS+ world (diag(-1, -1, 1) * ijk_to_lps, in mm).
// - NRRD: as 3D Slicer reads a displacement field: kinds `vector domain domain domain`, space
//   left-posterior-superior, the identity measurement frame (components in LPS), and
//   `displacement field type:=resampling` (pull-back) or `modeling` (forward), `intent_code:=1006`.
// - MetaImage: LPS components, as ITK writes vector images.
// Label maps: the smallest of uint8, int16 or int32 holding every label. Images: float32.
#include <filesystem>
#include <string>

#include "pneuma/image/label_map.h"
#include "pneuma/voxels/dvf.h"
#include "pneuma/voxels/warp.h"

namespace pneuma::voxels {

// Which way a DVF points (dvf.h): forward u (x -> x + u(x), Slicer's `modeling`) or pull-back v
// (out(x) = in(x + v(x)), Slicer's `resampling`).
enum class DvfDirection { forward, pullback };
// The frame of a NIfTI DVF's components: LPS with intent 1007 (ITK <= 5.2, plastimatch, elastix)
// or RAS with intent 1006 (the NIfTI standard, ITK >= 5.3, nibabel). Other formats are always LPS.
enum class DvfConvention { itk, nifti };

// NIfTI's `descrip` of a DVF (at most 79 characters).
std::string dvf_description(DvfDirection direction, DvfConvention convention);

// Throws ValueError for another ending or DvfConvention::nifti with a non-NIfTI name, and IoError
// when the file cannot be written.
void write_dvf(const std::filesystem::path& path, const DisplacementField& field,
               DvfDirection direction = DvfDirection::pullback, DvfConvention convention = DvfConvention::itk);
void write_label_map(const std::filesystem::path& path, const image::LabelMap& map);
void write_image(const std::filesystem::path& path, const Image& image);

// A scalar image (a CT) of any numeric voxel type, as float, by image::read_scalar_image()
// (pneuma/image/scalar_image.h: read_label_map()'s formats, transform rule and checks). Throws
// IoError when the file cannot be opened and InputError "<file>: <what was expected>" when it is
// not a 3D scalar image of a known format or is truncated.
Image read_image(const std::filesystem::path& path);

}  // namespace pneuma::voxels
