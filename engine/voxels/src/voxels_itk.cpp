// The module's one translation unit that includes ITK (5.2: ITKIONIFTI, ITKIONRRD, ITKIOMeta over
// ITKIOImageBase), as mesh/labels/src/labels_itk.cpp does: ImageIO classes used directly (no
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
#include <itkNrrdImageIO.h>

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
#include "pneuma/mesh/io/readable_file.h"
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

template <typename T>
std::vector<float> read_as_float(itk::ImageIOBase& io, std::size_t count) {
  std::vector<T> buffer(count);
  io.Read(buffer.data());
  std::vector<float> out(count);
  for (std::size_t v = 0; v < count; ++v) out[v] = static_cast<float>(buffer[v]);
  return out;
}

const char* format_expectation(const std::string& format) {
  if (format == "nifti") {
    return "not a NIfTI image: expected a NIfTI-1 or NIfTI-2 header (magic 'n+1' or 'n+2'), gzip-compressed for "
           ".nii.gz";
  }
  if (format == "nrrd") return "not a NRRD image: expected the magic line 'NRRD0001'..'NRRD0005' and its header";
  return "not a MetaImage: expected 'Key = Value' header lines with NDims, DimSize, ElementType and ElementDataFile";
}

}  // namespace

void write_dvf(const fs::path& path, const DisplacementField& field) {
  std::vector<float> mm(3 * field.displacement_m.size());
  for (std::size_t v = 0; v < field.displacement_m.size(); ++v)
    for (std::size_t c = 0; c < 3; ++c)
      mm[3 * v + c] = static_cast<float>(field.displacement_m[v][static_cast<Eigen::Index>(c)] * 1e3);
  write_itk(path, field.grid, itk::IOPixelEnum::VECTOR, Component::FLOAT, 3, mm.data());
}

void write_label_map(const fs::path& path, const mesh::LabelMap& map) {
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

Image read_image(const fs::path& path) {
  const std::string name = path.string();
  mesh::detail::require_readable_file(path);
  const std::string n = lower(path.filename().string());
  const auto ends = [&](const std::string& e) { return n.size() > e.size() && n.ends_with(e); };
  std::string format;
  if (ends(".nii") || ends(".nii.gz")) format = "nifti";
  if (ends(".nrrd") || ends(".nhdr")) format = "nrrd";
  if (ends(".mha") || ends(".mhd")) format = "meta";
  if (format.empty()) throw InputError(name + ": expected an image: .nii, .nii.gz, .nrrd, .nhdr, .mha or .mhd");

  const std::lock_guard<std::mutex> lock(itk_quiet::mutex());
  itk::Object::SetGlobalWarningDisplay(false);
  const itk_quiet::SilenceStdErr silence;
  itk::ImageIOBase::Pointer io;
  if (format == "nifti") io = itk::NiftiImageIO::New().GetPointer();
  if (format == "nrrd") io = itk::NrrdImageIO::New().GetPointer();
  if (format == "meta") io = itk::MetaImageIO::New().GetPointer();
  io->SetFileName(name);
  Image image;
  std::size_t count = 0;
  try {
    if (!io->CanReadFile(name.c_str())) throw InputError(name + ": " + format_expectation(format));
    io->ReadImageInformation();
    const unsigned dims = io->GetNumberOfDimensions();
    if (dims < 2 || dims > 4 || (dims == 4 && io->GetDimensions(3) > 1)) {
      throw InputError(name + ": " + std::to_string(dims) + "-dimensional data: expected one 3D image");
    }
    if (io->GetNumberOfComponents() != 1) {
      throw InputError(name + ": " + std::to_string(io->GetNumberOfComponents()) +
                       " values per voxel: expected a scalar image (a CT)");
    }
    Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();
    Eigen::Vector3d spacing_mm = Eigen::Vector3d::Ones(), origin_mm = Eigen::Vector3d::Zero();
    double voxels = 1.0;
    for (unsigned d = 0; d < 3; ++d) {
      const auto di = static_cast<Eigen::Index>(d);
      image.grid.size[d] = d < dims ? io->GetDimensions(d) : 1;
      voxels *= static_cast<double>(image.grid.size[d]);
      if (d >= dims) continue;
      spacing_mm[di] = io->GetSpacing(d);
      origin_mm[di] = io->GetOrigin(d);
      const std::vector<double> column = io->GetDirection(d);
      for (unsigned r = 0; r < 3 && r < column.size(); ++r) direction(static_cast<Eigen::Index>(r), di) = column[r];
    }
    if (!(voxels >= 1.0 && voxels <= 2147483648.0)) {
      throw InputError(name + ": " + std::to_string(voxels) + " voxels: expected a non-empty 3D image of at most 2^31");
    }
    image.grid.ijk_to_lps.block<3, 3>(0, 0) = direction * spacing_mm.asDiagonal() * 1e-3;
    image.grid.ijk_to_lps.block<3, 1>(0, 3) = origin_mm * 1e-3;
    if (!image.grid.ijk_to_lps.allFinite() || !(image.grid.voxel_volume_m3() > 0.0)) {
      throw InputError(name + ": a singular or non-finite voxel-to-world transform: expected voxel axes of positive "
                              "length");
    }
    count = image.grid.voxel_count();
    itk::ImageIORegion region(dims);
    for (unsigned d = 0; d < dims; ++d) {
      region.SetIndex(d, 0);
      region.SetSize(d, io->GetDimensions(d));
    }
    io->SetIORegion(region);
    switch (io->GetComponentType()) {
      case Component::UCHAR: image.values = read_as_float<unsigned char>(*io, count); break;
      case Component::CHAR: image.values = read_as_float<signed char>(*io, count); break;
      case Component::USHORT: image.values = read_as_float<unsigned short>(*io, count); break;
      case Component::SHORT: image.values = read_as_float<short>(*io, count); break;
      case Component::UINT: image.values = read_as_float<unsigned int>(*io, count); break;
      case Component::INT: image.values = read_as_float<int>(*io, count); break;
      case Component::ULONG: image.values = read_as_float<unsigned long>(*io, count); break;
      case Component::LONG: image.values = read_as_float<long>(*io, count); break;
      case Component::ULONGLONG: image.values = read_as_float<unsigned long long>(*io, count); break;
      case Component::LONGLONG: image.values = read_as_float<long long>(*io, count); break;
      case Component::FLOAT: image.values = read_as_float<float>(*io, count); break;
      case Component::DOUBLE: image.values = read_as_float<double>(*io, count); break;
      default: throw InputError(name + ": voxels of an unknown type: expected numbers (int16, float32, ...)");
    }
  } catch (const itk::ExceptionObject&) {
    throw InputError(name + ": " + format_expectation(format));
  } catch (const std::bad_alloc&) {
    throw InputError(name + ": " + format_expectation(format));
  } catch (const std::length_error&) {
    throw InputError(name + ": " + format_expectation(format));
  }
  return image;
}

}  // namespace pneuma::voxels
