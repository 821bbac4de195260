// The one translation unit that includes ITK (5.2: ITKIONIFTI, ITKIONRRD, ITKIOMeta over
// ITKIOImageBase). The ImageIO classes are used directly, not through itk::Image and the IO
// factories: the file's own component type is read into a buffer of that type and converted to
// int32 here, and no image template is instantiated (compile time). ITK's messages (exception
// text with source locations, MetaIO's lines on std::cerr, warnings) never reach the user:
// each failure becomes one pneuma line.
// clang-format off
#include "itk_clang.h"  // first: Debian's ITK headers under clang
// clang-format on
#include <itkMetaDataObject.h>
#include <itkMetaImageIO.h>
#include <itkNiftiImageIO.h>
#include <itkNrrdImageIO.h>

#include "itk_quiet.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <type_traits>

#include "itk_image.h"
#include "pneuma/core/error.h"
#include "pneuma/core/fresh_pages.h"
#include "pneuma/core/tsan.h"

namespace pneuma::image::detail {
namespace {

using Component = itk::IOComponentEnum;

itk::ImageIOBase::Pointer make_io(ImageFormat format) {
  switch (format) {
    case ImageFormat::nifti: return itk::NiftiImageIO::New().GetPointer();
    case ImageFormat::nrrd: return itk::NrrdImageIO::New().GetPointer();
    case ImageFormat::meta: return itk::MetaImageIO::New().GetPointer();
  }
  return nullptr;
}

// NIfTI's names for the types (niftilib's nifti_datatype_string), whatever the format.
const char* type_name(Component c) {
  switch (c) {
    case Component::UCHAR: return "UINT8";
    case Component::CHAR: return "INT8";
    case Component::USHORT: return "UINT16";
    case Component::SHORT: return "INT16";
    case Component::UINT: return "UINT32";
    case Component::INT: return "INT32";
    case Component::ULONG: return sizeof(unsigned long) == 8 ? "UINT64" : "UINT32";
    case Component::LONG: return sizeof(long) == 8 ? "INT64" : "INT32";
    case Component::ULONGLONG: return "UINT64";
    case Component::LONGLONG: return "INT64";
    case Component::FLOAT: return "FLOAT32";
    case Component::DOUBLE: return "FLOAT64";
    case Component::LDOUBLE: return "FLOAT128";
    default: return "UNKNOWN";
  }
}

// Values converted a block at a time on every core (#50: the label map and the CT, 70.8M voxels
// each at case004's own grid, were converted on one core while the other waited, at the start of
// every run). A value depends on its voxel alone, so the result is the same at any thread count.
constexpr std::size_t kConvertBlock = std::size_t{1} << 18;

// body(lo, hi) for each block [lo, hi) of [0, count), in parallel.
template <typename Body>
void for_blocks(std::size_t count, const Body& body) {
  const std::size_t blocks = (count + kConvertBlock - 1) / kConvertBlock;
  const tsan::Region region;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks, 1),
                    region.wrap([&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t b = range.begin(); b != range.end(); ++b)
                        body(b * kConvertBlock, std::min(count, (b + 1) * kConvertBlock));
                    }));
  region.join();
}

// Whether every value of type T is a whole number that int32 holds (no check per voxel). int8
// labels (rare) take the checked way through double, as before: a signed char copied straight to
// int32 is what clang-tidy's bugprone-signed-char-misuse refuses.
template <typename T>
constexpr bool always_int32() {
  return std::is_integral_v<T> && !std::is_same_v<T, signed char> &&
         (sizeof(T) < sizeof(std::int32_t) || (sizeof(T) == sizeof(std::int32_t) && std::is_signed_v<T>));
}

// The voxels, value `at(v)` for v in [0, count), converted to int32 labels (refusing any that is
// not a whole number: the message names the first such voxel, whichever block finds one first)
// or to float. The buffers' pages are mapped on every core before they are written.
template <typename At>
void convert(const At& at, const std::string& name, ItkImage& image, VoxelKind kind) {
  using T = decltype(at(std::size_t{0}));
  const std::size_t count = image.voxel_count() * image.components;
  if (kind == VoxelKind::reals) {
    core::resize_mapped(image.reals, count);
    float* const out = image.reals.data();
    for_blocks(count, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t v = lo; v < hi; ++v) out[v] = static_cast<float>(at(v));
    });
    return;
  }
  core::resize_mapped(image.values, count);
  std::int32_t* const out = image.values.data();
  if constexpr (always_int32<T>()) {
    for_blocks(count, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t v = lo; v < hi; ++v) out[v] = static_cast<std::int32_t>(at(v));
    });
    return;
  }
  const auto whole = [](double value) { return value == std::floor(value) && std::abs(value) <= 2147483647.0; };
  std::atomic<std::size_t> first_refused{count};  // the lowest voxel found so far that is not a label
  for_blocks(count, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t v = lo; v < hi; ++v) {
      if (v >= first_refused.load(std::memory_order_relaxed)) return;  // a lower one is already refused
      const double value = static_cast<double>(at(v));
      if (!whole(value)) {
        std::size_t seen = first_refused.load(std::memory_order_relaxed);
        while (v < seen && !first_refused.compare_exchange_weak(seen, v, std::memory_order_relaxed)) {
        }
        return;
      }
      out[v] = static_cast<std::int32_t>(value);
    }
  });
  if (const std::size_t v = first_refused.load(); v < count) {
    std::ostringstream text;
    text << name << ": voxel " << v / image.components << " holds " << std::to_string(static_cast<double>(at(v)))
         << ": expected integer labels (a label map, not an image)";
    throw InputError(text.str());
  }
}

// ITK reads the file's voxels (its second pass over a compressed file), then they are converted.
template <typename T>
void read_and_convert(itk::ImageIOBase& io, const std::string& name, ItkImage& image, VoxelKind kind) {
  std::vector<T> buffer(image.voxel_count() * image.components);
  io.Read(buffer.data());
  convert([&buffer](std::size_t v) { return buffer[v]; }, name, image, kind);
}

// niftilib sets a stored NaN or infinity to 0 as it reads (nifti_read_buffer: "bad floats were set
// to 0"), so the bytes read here do the same: a .nii.gz reads as the same .nii read by ITK.
template <typename T>
T as_niftilib_reads(T value) {
  if constexpr (std::is_floating_point_v<T>) {
    if (!std::isfinite(value)) return T(0);
  }
  return value;
}

// The same values from the file's bytes already in memory: what ITK's read gives (niftilib copies
// the stored bytes, swaps them to this machine's order and zeroes bad floats), without reading the
// file again.
template <typename T>
void convert_bytes(const VoxelBytes& stored, const std::string& name, ItkImage& image, VoxelKind kind) {
  const unsigned char* bytes = stored.bytes.data();
  if (stored.swap) {
    convert(
        [bytes](std::size_t v) {
          unsigned char raw[sizeof(T)];
          std::memcpy(raw, bytes + v * sizeof(T), sizeof(T));
          std::reverse(raw, raw + sizeof(T));
          T value;
          std::memcpy(&value, raw, sizeof(T));
          return as_niftilib_reads(value);
        },
        name, image, kind);
  } else {
    convert(
        [bytes](std::size_t v) {
          T value;
          std::memcpy(&value, bytes + v * sizeof(T), sizeof(T));
          return as_niftilib_reads(value);
        },
        name, image, kind);
  }
}

// The voxels of component type T: from `in_memory` when it holds them, else by ITK.
template <typename T>
void voxels_of(itk::ImageIOBase& io, const VoxelBytes* in_memory, const std::string& name, ItkImage& image,
               VoxelKind kind) {
  if (in_memory) {
    convert_bytes<T>(*in_memory, name, image, kind);
  } else {
    read_and_convert<T>(io, name, image, kind);
  }
}

}  // namespace

namespace {

// The header as ITK reads it; ITK's exceptions pass (the caller turns them into one line).
ItkImage read_header(itk::ImageIOBase& io, const std::string& name, ImageFormat format, VoxelKind kind) {
  const std::string expected = kind == VoxelKind::labels ? "expected integer labels (uint8, int16, int32, ...)"
                                                         : "expected numbers (int16, float32, ...)";
  if (!io.CanReadFile(name.c_str())) throw InputError(name + ": " + format_expectation(format));
  io.ReadImageInformation();
  ItkImage image;
  const unsigned dims = io.GetNumberOfDimensions();
  for (unsigned d = 3; d < dims; ++d) {
    if (io.GetDimensions(d) > 1) {
      throw InputError(name + ": " + std::to_string(dims) +
                       "-dimensional data: expected one 3D label volume (dimension " + std::to_string(d + 1) + " has " +
                       std::to_string(io.GetDimensions(d)) + " entries)");
    }
  }
  if (dims < 2) throw InputError(name + ": " + std::to_string(dims) + "-dimensional data: expected a 3D label volume");
  // ITK's spacing and origin are millimetres in LPS (NRRD in a right-anterior space and
  // MetaImage are turned into LPS by ITK); a 2D image is one slice of unit thickness.
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();
  Eigen::Vector3d spacing_mm = Eigen::Vector3d::Ones(), origin_mm = Eigen::Vector3d::Zero();
  const unsigned shown = std::min(dims, 3u);
  for (unsigned d = 0; d < shown; ++d) {
    image.size[d] = io.GetDimensions(d);
    spacing_mm[d] = io.GetSpacing(d);
    origin_mm[d] = io.GetOrigin(d);
    const std::vector<double> column = io.GetDirection(d);
    for (unsigned r = 0; r < shown && r < column.size(); ++r) direction(r, d) = column[r];
  }
  for (unsigned d = shown; d < 3; ++d) image.size[d] = 1;
  image.ijk_to_lps.block<3, 3>(0, 0) = direction * spacing_mm.asDiagonal() * 1e-3;
  image.ijk_to_lps.block<3, 1>(0, 3) = origin_mm * 1e-3;
  if (image.voxel_count() == 0) throw InputError(name + ": expected a non-empty 3D volume");
  image.components = io.GetNumberOfComponents();
  const Component component = io.GetComponentType();
  image.type_name = type_name(component);
  const itk::IOPixelEnum pixel = io.GetPixelType();
  const bool integral_or_real = component != Component::UNKNOWNCOMPONENTTYPE && component != Component::LDOUBLE;
  if (!integral_or_real) {
    throw InputError(name + ": voxels of an unknown type: " + expected);
  }
  if (pixel == itk::IOPixelEnum::COMPLEX || pixel == itk::IOPixelEnum::RGB || pixel == itk::IOPixelEnum::RGBA ||
      image.components == 0) {
    throw InputError(name + ": voxels of type " + itk::ImageIOBase::GetPixelTypeAsString(pixel) + " " +
                     image.type_name + ": " + expected);
  }
  image.component_bytes = io.GetComponentSize();

  const itk::MetaDataDictionary& dictionary = io.GetMetaDataDictionary();
  for (const std::string& key : dictionary.GetKeys()) {
    std::string value;
    if (itk::ExposeMetaData<std::string>(dictionary, key, value)) image.metadata.emplace(key, value);
  }
  return image;
}

}  // namespace

ItkImage read_itk_image(const std::filesystem::path& path, ImageFormat format,
                        const std::function<StoredData(const ItkImage&)>& stored, VoxelKind kind,
                        const VoxelBytes* in_memory) {
  const std::string name = path.string();
  // One ITK call at a time: std::cerr's buffer and ITK's warning switch are process-wide.
  const std::lock_guard<std::mutex> lock(itk_quiet::mutex());
  itk::Object::SetGlobalWarningDisplay(false);
  const itk_quiet::SilenceStdErr silence;
  itk::ImageIOBase::Pointer io = make_io(format);
  io->SetFileName(name);
  ItkImage image;
  try {
    image = read_header(*io, name, format, kind);
  } catch (const itk::ExceptionObject&) {
    throw InputError(name + ": " + format_expectation(format));
  } catch (const std::bad_alloc&) {
    throw InputError(name + ": " + format_expectation(format));
  } catch (const std::length_error&) {
    throw InputError(name + ": " + format_expectation(format));
  }

  const StoredData data = stored(image);
  const double claimed = image.data_bytes();
  const double room = data.exact || !data.compressed ? data.bytes : 1032.0 * data.bytes + 4096.0;
  const std::string truncated =
      truncated_message(name, image.size, image.components, image.type_name, claimed, data.compressed);
  if (claimed > room) throw InputError(truncated);
  // The bytes in memory only where ITK's header says what they hold: the same type, all of them.
  if (in_memory &&
      (in_memory->type_name != image.type_name || static_cast<double>(in_memory->bytes.size()) != image.data_bytes())) {
    in_memory = nullptr;
  }
  try {
    // The whole image (an ImageIO reads only its IO region, empty unless set).
    const unsigned dims = io->GetNumberOfDimensions();
    itk::ImageIORegion region(dims);
    for (unsigned d = 0; d < dims; ++d) {
      region.SetIndex(d, 0);
      region.SetSize(d, io->GetDimensions(d));
    }
    io->SetIORegion(region);
    switch (io->GetComponentType()) {
      case Component::UCHAR: voxels_of<unsigned char>(*io, in_memory, name, image, kind); break;
      case Component::CHAR: voxels_of<signed char>(*io, in_memory, name, image, kind); break;
      case Component::USHORT: voxels_of<unsigned short>(*io, in_memory, name, image, kind); break;
      case Component::SHORT: voxels_of<short>(*io, in_memory, name, image, kind); break;
      case Component::UINT: voxels_of<unsigned int>(*io, in_memory, name, image, kind); break;
      case Component::INT: voxels_of<int>(*io, in_memory, name, image, kind); break;
      case Component::ULONG: voxels_of<unsigned long>(*io, in_memory, name, image, kind); break;
      case Component::LONG: voxels_of<long>(*io, in_memory, name, image, kind); break;
      case Component::ULONGLONG: voxels_of<unsigned long long>(*io, in_memory, name, image, kind); break;
      case Component::LONGLONG: voxels_of<long long>(*io, in_memory, name, image, kind); break;
      case Component::FLOAT: voxels_of<float>(*io, in_memory, name, image, kind); break;
      case Component::DOUBLE: voxels_of<double>(*io, in_memory, name, image, kind); break;
      default: throw InputError(truncated);  // excluded with the header
    }
  } catch (const itk::ExceptionObject&) {
    throw InputError(truncated);
  } catch (const std::bad_alloc&) {
    throw InputError(truncated);
  }
  return image;
}

}  // namespace pneuma::image::detail
