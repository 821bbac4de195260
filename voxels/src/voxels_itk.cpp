// The module's one translation unit that includes ITK (5.2: ITKIONIFTI, ITKIOMeta over
// ITKIOImageBase), the writers (images are read by mesh/labels' reader), as
// image/src/itk_read.cpp does: ImageIO classes used directly (no
// itk::Image, no IO factories), each call alone and silent (itk_quiet.h), ITK's exceptions turned
// into pneuma's one line.
//
// What ITK 5.2's NiftiImageIO does with a vector image (measured: tests/voxels/voxel_io_test.cpp
// reads the file back with nibabel): dim = (5, nx, ny, nz, 1, 3), intent_code 1007
// (NIFTI_INTENT_VECTOR), and the components stored as given, in ITK's LPS (no flip to NIfTI's
// RAS+), while the qform/sform carry the geometry in RAS+ (x and y negated) as for any image.
// This is what ITK itself, plastimatch and ANTs read back.
// clang-format off
#include "itk_clang.h"  // first: Debian's ITK headers under clang
// clang-format on
#include <itkMetaImageIO.h>
#include <itkNiftiImageIO.h>

#include "itk_quiet.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <string>
#include <vector>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/voxels/voxel_io.h"

namespace pneuma::voxels {
namespace fs = std::filesystem;
namespace {

using Component = itk::IOComponentEnum;

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// The extension ITK chooses by (".nii.gz", ".nii", ".mha"), or empty.
std::string written_extension(const fs::path& path) {
  const std::string n = lower(path.filename().string());
  for (const char* e : {".nii.gz", ".nii", ".mha"}) {
    if (n.size() > std::strlen(e) && n.ends_with(e)) return e;
  }
  return {};
}

// Writes `components` values of `component` per voxel (`buffer`, component fastest, then i, j,
// k) on `grid` to `path`, atomically: ITK writes a temporary name with the file's extension (it
// chooses compression by it), which is renamed into place.
void write_itk(const fs::path& path, const Grid& grid, itk::IOPixelEnum pixel, Component component, unsigned components,
               const void* buffer) {
  const std::string extension = written_extension(path);
  if (extension.empty()) {
    throw ValueError(path.string() + ": expected a voxel file name ending in .nii.gz, .nii or .mha");
  }
  const Eigen::Vector3d spacing_m = grid.spacing_m();
  write_atomically(path, [&](const fs::path& tmp) {
    const fs::path itk_path = tmp.string() + extension;
    const std::lock_guard<std::mutex> lock(itk_quiet::mutex());
    itk::Object::SetGlobalWarningDisplay(false);
    const itk_quiet::SilenceStdErr silence;
    try {
      itk::ImageIOBase::Pointer io;
      if (extension == ".mha") {
        io = itk::MetaImageIO::New().GetPointer();
      } else {
        io = itk::NiftiImageIO::New().GetPointer();
      }
      io->SetNumberOfDimensions(3);
      itk::ImageIORegion region(3);
      for (unsigned a = 0; a < 3; ++a) {
        const auto ai = static_cast<Eigen::Index>(a);
        io->SetDimensions(a, static_cast<unsigned>(grid.size[a]));
        io->SetSpacing(a, spacing_m[ai] * 1e3);
        io->SetOrigin(a, grid.ijk_to_lps(ai, 3) * 1e3);
        std::vector<double> axis(3);
        for (unsigned r = 0; r < 3; ++r) axis[r] = grid.ijk_to_lps(static_cast<Eigen::Index>(r), ai) / spacing_m[ai];
        io->SetDirection(a, axis);
        region.SetIndex(a, 0);
        region.SetSize(a, grid.size[a]);
      }
      io->SetIORegion(region);
      io->SetPixelType(pixel);
      io->SetComponentType(component);
      io->SetNumberOfComponents(components);
      io->SetUseCompression(extension != ".nii");
      io->SetFileName(itk_path.string());
      io->WriteImageInformation();
      io->Write(buffer);
    } catch (const itk::ExceptionObject&) {
      std::error_code ec;
      fs::remove(itk_path, ec);
      throw IoError(path.string() + ": cannot write (ITK's " + (extension == ".mha" ? "MetaImage" : "NIfTI") +
                    " writer failed: is the folder writable, the disk full?)");
    }
    std::error_code ec;
    fs::rename(itk_path, tmp, ec);
    if (ec) {
      fs::remove(itk_path, ec);
      throw IoError(path.string() + ": cannot write: " + ec.message());
    }
  });
}

}  // namespace

void write_dvf(const fs::path& path, const DisplacementField& field) {
  std::vector<float> mm(3 * field.displacement_m.size());
  for (std::size_t v = 0; v < field.displacement_m.size(); ++v)
    for (std::size_t c = 0; c < 3; ++c)
      mm[3 * v + c] = static_cast<float>(field.displacement_m[v][static_cast<Eigen::Index>(c)] * 1e3);
  write_itk(path, field.grid, itk::IOPixelEnum::VECTOR, Component::FLOAT, 3, mm.data());
}

void write_label_map(const fs::path& path, const image::LabelMap& map) {
  const Grid grid = grid_of(map);
  const auto [lo, hi] = std::minmax_element(map.labels.begin(), map.labels.end());
  const std::int32_t min = lo == map.labels.end() ? 0 : *lo, max = hi == map.labels.end() ? 0 : *hi;
  if (min >= 0 && max <= 255) {
    const std::vector<std::uint8_t> values(map.labels.begin(), map.labels.end());
    write_itk(path, grid, itk::IOPixelEnum::SCALAR, Component::UCHAR, 1, values.data());
  } else if (min >= -32768 && max <= 32767) {
    const std::vector<std::int16_t> values(map.labels.begin(), map.labels.end());
    write_itk(path, grid, itk::IOPixelEnum::SCALAR, Component::SHORT, 1, values.data());
  } else {
    write_itk(path, grid, itk::IOPixelEnum::SCALAR, Component::INT, 1, map.labels.data());
  }
}

void write_image(const fs::path& path, const Image& image) {
  write_itk(path, image.grid, itk::IOPixelEnum::SCALAR, Component::FLOAT, 1, image.values.data());
}

}  // namespace pneuma::voxels
