// read_label_map(): NIfTI-1/2 label maps through niftilib (nifti2_io, which reads both
// versions, .nii and .nii.gz). niftilib's own diagnostics are silenced (debug level 0): every
// failure becomes one pneuma error line naming the file and what was expected.
#include <nifti2_io.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>

#include "pneuma/core/error.h"
#include "pneuma/mesh/io/readable_file.h"
#include "pneuma/mesh/labels/labels.h"

namespace pneuma::mesh {
namespace {

struct NiftiFree {
  void operator()(nifti_image* image) const { nifti_image_free(image); }
};
using NiftiPtr = std::unique_ptr<nifti_image, NiftiFree>;

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

bool has_nifti_extension(const std::string& name) {
  const std::string n = lower(name);
  auto ends = [&](const char* suffix) {
    const std::size_t len = std::strlen(suffix);
    return n.size() > len && n.compare(n.size() - len, len, suffix) == 0;
  };
  return ends(".nii") || ends(".nii.gz");
}

// Metres per unit of the header's xyzt_units (spatial part); unknown units are millimetres, as
// nearly every writer means.
double metres_per_unit(int xyz_units) {
  switch (xyz_units) {
    case NIFTI_UNITS_METER: return 1.0;
    case NIFTI_UNITS_MICRON: return 1e-6;
    default: return 1e-3;  // NIFTI_UNITS_MM and NIFTI_UNITS_UNKNOWN
  }
}

template <typename T>
void convert(const nifti_image& image, const std::string& name, std::vector<std::int32_t>& out) {
  const T* data = static_cast<const T*>(image.data);
  const double slope = image.scl_slope, inter = image.scl_inter;
  const bool scaled = slope != 0.0 && (slope != 1.0 || inter != 0.0);
  for (std::size_t v = 0; v < out.size(); ++v) {
    double value = static_cast<double>(data[v]);
    if (scaled) value = slope * value + inter;
    if (!(value == std::floor(value)) || std::abs(value) > 2147483647.0) {
      throw InputError(name + ": voxel " + std::to_string(v) + " holds " + std::to_string(value) +
                       ": expected integer labels (a label map, not an image)");
    }
    out[v] = static_cast<std::int32_t>(value);
  }
}

}  // namespace

Eigen::Vector3d LabelMap::spacing_m() const {
  return {ijk_to_lps.block<3, 1>(0, 0).norm(), ijk_to_lps.block<3, 1>(0, 1).norm(),
          ijk_to_lps.block<3, 1>(0, 2).norm()};
}

double LabelMap::voxel_volume_m3() const { return std::abs(ijk_to_lps.block<3, 3>(0, 0).determinant()); }

LabelMap read_label_map(const std::filesystem::path& path) {
  const std::string name = path.string();
  detail::require_readable_file(path);
  if (!has_nifti_extension(name)) {
    throw InputError(name + ": expected a NIfTI label map (.nii or .nii.gz)");
  }
  nifti_set_debug_level(0);
  NiftiPtr image(nifti_image_read(name.c_str(), 0));
  if (!image) {
    throw InputError(name +
                     ": not a NIfTI file: expected a NIfTI-1 or NIfTI-2 header (348 or 540 bytes, magic 'n+1' or "
                     "'n+2'), gzip-compressed for .nii.gz");
  }
  if (image->nifti_type == NIFTI_FTYPE_ANALYZE) {
    throw InputError(name + ": an ANALYZE 7.5 file, not NIfTI: expected a NIfTI-1 or NIfTI-2 header (it carries the "
                            "orientation)");
  }
  for (int d = 4; d <= 7; ++d) {
    if (image->dim[0] >= d && image->dim[d] > 1) {
      throw InputError(name + ": " + std::to_string(image->dim[0]) +
                       "-dimensional data: expected one 3D label volume (dimension " + std::to_string(d) + " has " +
                       std::to_string(image->dim[d]) + " entries)");
    }
  }
  if (image->nx < 1 || image->ny < 1 || image->nz < 1) throw InputError(name + ": expected a non-empty 3D volume");
  const char* type = nifti_datatype_string(image->datatype);
  const std::uint64_t expected_bytes =
      static_cast<std::uint64_t>(image->nvox) * static_cast<std::uint64_t>(image->nbyper);
  // The header's sizes are checked against the file before niftilib allocates them (a damaged
  // header claimed 37 GB, found by fuzz_nifti): gzip expands at most ~1032:1.
  const bool gzipped = lower(name).ends_with(".gz");
  std::error_code size_error;
  const double file_bytes = static_cast<double>(std::filesystem::file_size(path, size_error));
  const double claimed_bytes = static_cast<double>(image->nx) * static_cast<double>(image->ny) *
                               static_cast<double>(image->nz) * static_cast<double>(image->nbyper);
  const bool claims_too_much = !size_error && claimed_bytes > (gzipped ? 1032.0 * file_bytes + 4096.0 : file_bytes);
  if (claims_too_much || nifti_image_load(image.get()) != 0 || image->data == nullptr) {
    throw InputError(name + ": truncated or corrupt: expected " + std::to_string(image->nx) + " x " +
                     std::to_string(image->ny) + " x " + std::to_string(image->nz) + " voxels of " + type + " (" +
                     std::to_string(expected_bytes) + " bytes of data" + (gzipped ? " after decompression" : "") + ")");
  }

  LabelMap map;
  map.size = {static_cast<std::size_t>(image->nx), static_cast<std::size_t>(image->ny),
              static_cast<std::size_t>(image->nz)};
  map.labels.resize(map.voxel_count());
  switch (image->datatype) {
    case DT_UINT8: convert<std::uint8_t>(*image, name, map.labels); break;
    case DT_INT8: convert<std::int8_t>(*image, name, map.labels); break;
    case DT_INT16: convert<std::int16_t>(*image, name, map.labels); break;
    case DT_UINT16: convert<std::uint16_t>(*image, name, map.labels); break;
    case DT_INT32: convert<std::int32_t>(*image, name, map.labels); break;
    case DT_UINT32: convert<std::uint32_t>(*image, name, map.labels); break;
    case DT_INT64: convert<std::int64_t>(*image, name, map.labels); break;
    case DT_UINT64: convert<std::uint64_t>(*image, name, map.labels); break;
    case DT_FLOAT32: convert<float>(*image, name, map.labels); break;
    case DT_FLOAT64: convert<double>(*image, name, map.labels); break;
    default:
      throw InputError(name + ": voxels of type " + type + ": expected integer labels (uint8, int16, int32, ...)");
  }

  // Voxel -> NIfTI world (RAS+, file units): sform when set, else qform (niftilib fills
  // qto_xyz with the pixdim scaling when qform_code is 0).
  const nifti_dmat44& m = image->sform_code > 0 ? image->sto_xyz : image->qto_xyz;
  map.transform_source = image->sform_code > 0 ? "sform" : image->qform_code > 0 ? "qform" : "pixdim";
  const double unit = metres_per_unit(XYZT_TO_SPACE(image->xyz_units));
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) map.ijk_to_lps(r, c) = m.m[r][c];
  }
  map.ijk_to_lps.row(3) << 0.0, 0.0, 0.0, 1.0;
  map.ijk_to_lps.topRows(3) *= unit;
  map.ijk_to_lps.row(0) *= -1.0;  // RAS -> LPS
  map.ijk_to_lps.row(1) *= -1.0;
  if (!map.ijk_to_lps.allFinite() || !(map.voxel_volume_m3() > 0.0)) {
    throw InputError(name + ": the " + map.transform_source +
                     " is singular or not finite: expected voxel axes of positive length");
  }
  return map;
}

}  // namespace pneuma::mesh
