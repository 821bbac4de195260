// The phantom-only build's stand-in for voxels_itk.cpp (ITK's image writers: a run of the built-in
// phantom writes no voxel output; core/not_built.h).
#include "pneuma/core/not_built.h"
#include "pneuma/voxels/voxel_io.h"

namespace pneuma::voxels {

std::string dvf_description(DvfDirection /*direction*/, DvfConvention /*convention*/) {
  throw_not_built("DVF files (ITK)");
}

void write_dvf(const std::filesystem::path& /*path*/, const DisplacementField& /*field*/, DvfDirection /*direction*/,
               DvfConvention /*convention*/) {
  throw_not_built("DVF files (ITK)");
}

void write_label_map(const std::filesystem::path& /*path*/, const image::LabelMap& /*map*/) {
  throw_not_built("label map files (ITK)");
}

void write_image(const std::filesystem::path& /*path*/, const Image& /*image*/) {
  throw_not_built("image files (ITK)");
}

}  // namespace pneuma::voxels
