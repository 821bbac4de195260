#include "pneuma/image/scalar_image.h"
#include "pneuma/voxels/voxel_io.h"

namespace pneuma::voxels {

Image read_image(const std::filesystem::path& path) {
  image::ScalarImage read = image::read_scalar_image(path);
  Image image;
  image.grid = Grid{read.size, read.ijk_to_lps};
  image.values = std::move(read.values);
  return image;
}

}  // namespace pneuma::voxels
