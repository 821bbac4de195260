// The module's one translation unit that includes ITK's C++ (5.2: ITKIOMeta, ITKIONRRD over
// ITKIOImageBase): the MetaImage and NRRD writers (images are read by image/'s reader), as
// image/src/itk_read.cpp does: ImageIO classes used directly (no itk::Image, no IO factories),
// each call alone and silent (itk_quiet.h), ITK's exceptions turned into pneuma's one line.
// NRRD's key/values and measurement frame come from the metadata dictionary (NrrdImageIO::Write).
//
// NIfTI (.nii, .nii.gz) is written by nifti_write.h straight from the fields and images (#50):
// the header by the NIfTI library ITK's writer uses, the data converted a batch at a time and
// gzipped in parallel members (gzip.h). The layout is ITK 5.2's NiftiImageIO's for a vector image
// (tests/voxels/nifti_write_test.cpp compares the two writers' files): dim = (5, nx, ny, nz, 1, 3),
// intent_code 1007 (NIFTI_INTENT_VECTOR), the components in ITK's LPS (no flip to NIfTI's RAS+),
// components the slowest axis, the qform/sform carrying the geometry in RAS+ (x and y negated)
// as for any image: what ITK, plastimatch and ANTs read back. Unlike ITK's writer it also sets
// `descrip` (the DVF's direction) and, for the NIfTI standard's DISPVECT with RAS components,
// intent_code 1006.
// clang-format off
#include "itk_clang.h"  // first: Debian's ITK headers under clang
// clang-format on
#include <itkMetaDataObject.h>
#include <itkMetaImageIO.h>
#include <itkNrrdImageIO.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "itk_quiet.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <mutex>
#include <string>
#include <vector>

#include "nifti_write.h"
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

// The extension ITK chooses by (".nii.gz", ".nii", ".mha", ".nrrd"), or empty.
std::string written_extension(const fs::path& path) {
  const std::string n = lower(path.filename().string());
  for (const char* e : {".nii.gz", ".nii", ".mha", ".nrrd"}) {
    if (n.size() > std::strlen(e) && n.ends_with(e)) return e;
  }
  return {};
}

// What a file says about itself beyond the grid (DVFs).
struct FileNotes {
  std::vector<std::pair<std::string, std::string>> nrrd_fields;  // NRRD key:=value
  bool nrrd_measurement_frame = false;                           // the identity (components in LPS)
};

const char* format_name(const std::string& extension) {
  if (extension == ".mha") return "MetaImage";
  if (extension == ".nrrd") return "NRRD";
  return "NIfTI";
}

// Writes `components` values of `component` per voxel (`buffer`, component fastest, then i, j,
// k) on `grid` to `path` (.mha or .nrrd), atomically: ITK writes a temporary name with the file's
// extension (it chooses the format by it), which is renamed into place.
void write_itk(const fs::path& path, const Grid& grid, itk::IOPixelEnum pixel, Component component, unsigned components,
               const void* buffer, const FileNotes& notes = {}) {
  const std::string extension = written_extension(path);
  const Eigen::Vector3d spacing_m = grid.spacing_m();
  write_atomically(path, [&](const fs::path& tmp) {
    const fs::path itk_path = tmp.string() + extension;
    try {
      const std::lock_guard<std::mutex> lock(itk_quiet::mutex());
      itk::Object::SetGlobalWarningDisplay(false);
      const itk_quiet::SilenceStdErr silence;
      itk::ImageIOBase::Pointer io;
      if (extension == ".mha") {
        io = itk::MetaImageIO::New().GetPointer();
      } else {
        io = itk::NrrdImageIO::New().GetPointer();
      }
      itk::MetaDataDictionary& dictionary = io->GetMetaDataDictionary();
      if (extension == ".nrrd") {
        for (const auto& [key, value] : notes.nrrd_fields)
          itk::EncapsulateMetaData<std::string>(dictionary, key, value);
        if (notes.nrrd_measurement_frame) {
          const std::vector<std::vector<double>> identity{{1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {0.0, 0.0, 1.0}};
          itk::EncapsulateMetaData<std::vector<std::vector<double>>>(dictionary, "NRRD_measurement frame", identity);
        }
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
      io->SetUseCompression(true);
      io->SetFileName(itk_path.string());
      io->WriteImageInformation();
      io->Write(buffer);
    } catch (const itk::ExceptionObject&) {
      std::error_code ec;
      fs::remove(itk_path, ec);
      throw IoError(path.string() + ": cannot write (ITK's " + format_name(extension) +
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

// The extension, checked: ValueError for another one.
std::string checked_extension(const fs::path& path) {
  std::string extension = written_extension(path);
  if (extension.empty()) {
    throw ValueError(path.string() + ": expected a voxel file name ending in .nii.gz, .nii, .mha or .nrrd");
  }
  return extension;
}

bool is_nifti(const std::string& extension) { return extension == ".nii.gz" || extension == ".nii"; }

// `values` converted to T, from value `first` on, in parallel (a batch of write_nifti's).
template <typename T, typename From>
void fill_as(const From* values, std::size_t first, std::size_t count, void* out) {
  T* to = static_cast<T*>(out);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, std::size_t{1} << 16),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t q = r.begin(); q != r.end(); ++q) to[q] = static_cast<T>(values[first + q]);
                    });
}

}  // namespace

std::string dvf_description(DvfDirection direction, DvfConvention convention) {
  // "jumps at pleura": the lungs slide, so the field is discontinuous there (docs/voxels.md).
  return std::string(direction == DvfDirection::pullback ? "pneuma pull-back DVF out(x)=in(x+v)"
                                                         : "pneuma forward DVF x->x+u(x)") +
         (convention == DvfConvention::itk ? ", LPS mm, ITK<=5.2 layout" : ", RAS mm, NIfTI DISPVECT") +
         ", jumps at pleura";
}

void write_dvf(const fs::path& path, const DisplacementField& field, DvfDirection direction, DvfConvention convention) {
  const std::string extension = checked_extension(path);
  if (convention == DvfConvention::nifti && !is_nifti(extension)) {
    throw ValueError(path.string() + ": the NIfTI standard's DVF convention needs a .nii.gz or .nii name");
  }
  // RAS components: x and y negated (the NIfTI standard's vectors live in the file's RAS world).
  const std::array<double, 3> sign = convention == DvfConvention::nifti ? std::array<double, 3>{-1e3, -1e3, 1e3}
                                                                        : std::array<double, 3>{1e3, 1e3, 1e3};
  const std::size_t n = field.displacement_m.size();
  if (is_nifti(extension)) {
    // Component by component (NIfTI's slowest axis), a batch at a time: no copy of the field.
    NiftiSpec spec{field.grid, NiftiType::float32, 3,
                   convention == DvfConvention::nifti ? std::int16_t{1006} : std::int16_t{0},  // NIFTI_INTENT_DISPVECT
                   dvf_description(direction, convention)};
    write_nifti(path, spec, [&](std::size_t first, std::size_t count, void* out) {
      float* to = static_cast<float*>(out);
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, std::size_t{1} << 16),
                        [&](const tbb::blocked_range<std::size_t>& r) {
                          // The component and voxel of the range's first value, then stepped: no
                          // division per value (it cost more than the conversion, #50).
                          std::size_t c = (first + r.begin()) / n, v = first + r.begin() - c * n;
                          for (std::size_t q = r.begin(); q != r.end(); ++q) {
                            to[q] = static_cast<float>(field.displacement_m[v][static_cast<Eigen::Index>(c)] * sign[c]);
                            if (++v == n) v = 0, ++c;
                          }
                        });
    });
    return;
  }
  std::vector<float> mm(3 * n);
  for (std::size_t v = 0; v < n; ++v)
    for (std::size_t c = 0; c < 3; ++c)
      mm[3 * v + c] = static_cast<float>(field.displacement_m[v][static_cast<Eigen::Index>(c)] * sign[c]);
  FileNotes notes;
  // Slicer's displacement-field NRRD (its Transforms docs): the direction, and intent_code 1006 so
  // that ITK-based readers see a displacement field.
  notes.nrrd_fields = {{"displacement field type", direction == DvfDirection::pullback ? "resampling" : "modeling"},
                       {"intent_code", "1006"}};
  notes.nrrd_measurement_frame = true;
  write_itk(path, field.grid, itk::IOPixelEnum::VECTOR, Component::FLOAT, 3, mm.data(), notes);
}

void write_label_map(const fs::path& path, const image::LabelMap& map) {
  const std::string extension = checked_extension(path);
  const Grid grid = grid_of(map);
  const auto [lo, hi] = std::minmax_element(map.labels.begin(), map.labels.end());
  const std::int32_t min = lo == map.labels.end() ? 0 : *lo, max = hi == map.labels.end() ? 0 : *hi;
  const NiftiType type = min >= 0 && max <= 255          ? NiftiType::uint8
                         : min >= -32768 && max <= 32767 ? NiftiType::int16
                                                         : NiftiType::int32;
  if (is_nifti(extension)) {
    const std::int32_t* labels = map.labels.data();
    write_nifti(path, {grid, type, 1, 0, {}}, [&](std::size_t first, std::size_t count, void* out) {
      if (type == NiftiType::uint8) fill_as<std::uint8_t>(labels, first, count, out);
      else if (type == NiftiType::int16) fill_as<std::int16_t>(labels, first, count, out);
      else fill_as<std::int32_t>(labels, first, count, out);
    });
  } else if (type == NiftiType::uint8) {
    const std::vector<std::uint8_t> values(map.labels.begin(), map.labels.end());
    write_itk(path, grid, itk::IOPixelEnum::SCALAR, Component::UCHAR, 1, values.data());
  } else if (type == NiftiType::int16) {
    const std::vector<std::int16_t> values(map.labels.begin(), map.labels.end());
    write_itk(path, grid, itk::IOPixelEnum::SCALAR, Component::SHORT, 1, values.data());
  } else {
    write_itk(path, grid, itk::IOPixelEnum::SCALAR, Component::INT, 1, map.labels.data());
  }
}

void write_image(const fs::path& path, const Image& image) {
  if (is_nifti(checked_extension(path))) {
    write_nifti(path, {image.grid, NiftiType::float32, 1, 0, {}}, [&](std::size_t first, std::size_t count, void* out) {
      fill_as<float>(image.values.data(), first, count, out);
    });
    return;
  }
  write_itk(path, image.grid, itk::IOPixelEnum::SCALAR, Component::FLOAT, 1, image.values.data());
}

}  // namespace pneuma::voxels
