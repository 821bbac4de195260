// The messages the readers of image/ share, on either side of ITK (read.cpp's own readers and
// itk_read.cpp), apart from ITK so that a build without ITK (the phantom-only demo) has them.
#include <cstdint>
#include <limits>
#include <sstream>

#include "itk_image.h"

namespace pneuma::image::detail {

const char* format_expectation(ImageFormat format) {
  switch (format) {
    case ImageFormat::nifti:
      return "not a NIfTI file: expected a NIfTI-1 or NIfTI-2 header (348 or 540 bytes, magic 'n+1' or 'n+2'), "
             "gzip-compressed for .nii.gz";
    case ImageFormat::nrrd:
      return "not a NRRD file: expected the magic line 'NRRD0001'..'NRRD0005' and a header with type, dimension, "
             "sizes and encoding";
    case ImageFormat::meta:
      return "not a MetaImage file: expected 'Key = Value' header lines with NDims, DimSize, ElementType and "
             "ElementDataFile";
  }
  return "";
}

std::string truncated_message(const std::string& name, const std::array<std::size_t, 3>& size, std::size_t components,
                              const std::string& type_name, double data_bytes, bool compressed) {
  std::ostringstream text;
  text.precision(std::numeric_limits<double>::max_digits10);
  text << name << ": truncated or corrupt: expected " << size[0] << " x " << size[1] << " x " << size[2]
       << " voxels of " << type_name;
  if (components > 1) text << " in " << components << " layers";
  text << " (" << static_cast<std::uint64_t>(data_bytes) << " bytes of data"
       << (compressed ? " after decompression" : "") << ")";
  return text.str();
}

}  // namespace pneuma::image::detail
