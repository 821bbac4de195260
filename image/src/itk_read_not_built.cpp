// The phantom-only build's stand-in for itk_read.cpp (ITK's image readers: a run of the built-in
// phantom reads no image; core/not_built.h).
#include "itk_image.h"
#include "pneuma/core/not_built.h"

namespace pneuma::image::detail {

ItkImage read_itk_image(const std::filesystem::path& /*path*/, ImageFormat /*format*/,
                        const std::function<StoredData(const ItkImage&)>& /*stored*/, VoxelKind /*kind*/,
                        const VoxelBytes* /*in_memory*/) {
  throw_not_built("NIfTI, NRRD and MetaImage images (ITK)");
}

}  // namespace pneuma::image::detail
