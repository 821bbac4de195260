// The module's one translation unit that includes ITK (5.2: ITKIONIFTI, ITKIOMeta, ITKIONRRD
// over ITKIOImageBase), the writers (images are read by mesh/labels' reader), as
// image/src/itk_read.cpp does: ImageIO classes used directly (no
// itk::Image, no IO factories), each call alone and silent (itk_quiet.h), ITK's exceptions turned
// into pneuma's one line.
//
// What ITK 5.2's NiftiImageIO does with a vector image (measured: tests/voxels/voxel_io_test.cpp
// reads the file back with nibabel): dim = (5, nx, ny, nz, 1, 3), intent_code 1007
// (NIFTI_INTENT_VECTOR), and the components stored as given, in ITK's LPS (no flip to NIfTI's
// RAS+), while the qform/sform carry the geometry in RAS+ (x and y negated) as for any image.
// This is what ITK itself, plastimatch and ANTs read back. ITK 5.2's NIfTI writer sets neither
// `descrip` (it ignores ITK_FileNotes; measured) nor another intent than 1007, so a DVF is written
// by ITK uncompressed, its header's descrip (and, for the NIfTI standard's DISPVECT with RAS
// components, intent_code 1006) patched, and then gzipped by pneuma (gzip.h: parallel members cut
// at fixed offsets, no time stamp: the same bytes each run and at any thread count); label maps
// and images too, so that every .nii.gz is compressed alike. NRRD's key/values and measurement frame come from the
// metadata dictionary (NrrdImageIO::Write).
// clang-format off
#include "itk_clang.h"  // first: Debian's ITK headers under clang
// clang-format on
#include <itkMetaDataObject.h>
#include <itkMetaImageIO.h>
#include <itkNiftiImageIO.h>
#include <itkNrrdImageIO.h>

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

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/voxels/gzip.h"
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
  std::string nifti_description;                                 // NIfTI's descrip
  std::int16_t nifti_intent = 0;                                 // 0: ITK's own intent_code
  std::vector<std::pair<std::string, std::string>> nrrd_fields;  // NRRD key:=value
  bool nrrd_measurement_frame = false;                           // the identity (components in LPS)
};

const char* format_name(const std::string& extension) {
  if (extension == ".mha") return "MetaImage";
  if (extension == ".nrrd") return "NRRD";
  return "NIfTI";
}

// NIfTI-1's header: intent_code a little-endian int16 at byte 68 (ITK writes the host's order,
// little-endian on every platform pneuma builds for), descrip 80 bytes at 148 (NUL-terminated).
void patch_nifti_header(const fs::path& nii, const FileNotes& notes) {
  std::fstream file(nii, std::ios::in | std::ios::out | std::ios::binary);
  if (notes.nifti_intent != 0) {
    const std::array<char, 2> bytes{static_cast<char>(notes.nifti_intent & 0xff),
                                    static_cast<char>((notes.nifti_intent >> 8) & 0xff)};
    file.seekp(68);
    file.write(bytes.data(), 2);
  }
  std::array<char, 80> descrip{};
  std::copy_n(notes.nifti_description.begin(), std::min<std::size_t>(notes.nifti_description.size(), 79),
              descrip.begin());
  file.seekp(148);
  file.write(descrip.data(), descrip.size());
  if (!file) throw IoError(nii.string() + ": cannot patch the NIfTI header");
}

// Writes `components` values of `component` per voxel (`buffer`, component fastest, then i, j,
// k) on `grid` to `path`, atomically: ITK writes a temporary name with the file's extension (it
// chooses compression by it), which is renamed into place.
void write_itk(const fs::path& path, const Grid& grid, itk::IOPixelEnum pixel, Component component, unsigned components,
               const void* buffer, const FileNotes& notes = {}) {
  const std::string extension = written_extension(path);
  if (extension.empty()) {
    throw ValueError(path.string() + ": expected a voxel file name ending in .nii.gz, .nii, .mha or .nrrd");
  }
  const bool nifti = extension == ".nii.gz" || extension == ".nii";
  // NIfTI: ITK writes the plain .nii, pneuma patches its header (DVFs) and gzips it in parallel
  // members (gzip.h; ITK's znzlib would compress in one thread).
  const bool patch = nifti && (notes.nifti_intent != 0 || !notes.nifti_description.empty());
  const Eigen::Vector3d spacing_m = grid.spacing_m();
  write_atomically(path, [&](const fs::path& tmp) {
    const fs::path itk_path = tmp.string() + (nifti ? ".nii" : extension);
    // ITK alone under the lock: the gzip after it runs TBB tasks, which must not wait on a lock
    // another task of the same thread may hold.
    try {
      const std::lock_guard<std::mutex> lock(itk_quiet::mutex());
      itk::Object::SetGlobalWarningDisplay(false);
      const itk_quiet::SilenceStdErr silence;
      itk::ImageIOBase::Pointer io;
      if (extension == ".mha") {
        io = itk::MetaImageIO::New().GetPointer();
      } else if (extension == ".nrrd") {
        io = itk::NrrdImageIO::New().GetPointer();
      } else {
        io = itk::NiftiImageIO::New().GetPointer();
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
      io->SetUseCompression(!nifti);
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
    if (nifti) {
      try {
        if (patch) patch_nifti_header(itk_path, notes);
        if (extension == ".nii.gz") {
          gzip_file(itk_path, tmp);
          fs::remove(itk_path, ec);
          return;
        }
      } catch (const Error&) {
        fs::remove(itk_path, ec);
        throw;
      }
    }
    fs::rename(itk_path, tmp, ec);
    if (ec) {
      fs::remove(itk_path, ec);
      throw IoError(path.string() + ": cannot write: " + ec.message());
    }
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
  const std::string extension = written_extension(path);
  const bool nifti = extension == ".nii.gz" || extension == ".nii";
  if (convention == DvfConvention::nifti && !nifti) {
    throw ValueError(path.string() + ": the NIfTI standard's DVF convention needs a .nii.gz or .nii name");
  }
  // RAS components: x and y negated (the NIfTI standard's vectors live in the file's RAS world).
  const std::array<double, 3> sign = convention == DvfConvention::nifti ? std::array<double, 3>{-1e3, -1e3, 1e3}
                                                                        : std::array<double, 3>{1e3, 1e3, 1e3};
  std::vector<float> mm(3 * field.displacement_m.size());
  for (std::size_t v = 0; v < field.displacement_m.size(); ++v)
    for (std::size_t c = 0; c < 3; ++c)
      mm[3 * v + c] = static_cast<float>(field.displacement_m[v][static_cast<Eigen::Index>(c)] * sign[c]);
  FileNotes notes;
  notes.nifti_description = dvf_description(direction, convention);
  notes.nifti_intent =
      convention == DvfConvention::nifti ? std::int16_t{1006} : std::int16_t{0};  // NIFTI_INTENT_DISPVECT
  // Slicer's displacement-field NRRD (its Transforms docs): the direction, and intent_code 1006 so
  // that ITK-based readers see a displacement field.
  notes.nrrd_fields = {{"displacement field type", direction == DvfDirection::pullback ? "resampling" : "modeling"},
                       {"intent_code", "1006"}};
  notes.nrrd_measurement_frame = true;
  write_itk(path, field.grid, itk::IOPixelEnum::VECTOR, Component::FLOAT, 3, mm.data(), notes);
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
