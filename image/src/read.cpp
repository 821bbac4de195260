// read_label_map(): the format by the name's ending, what ITK does not check (measured with
// ITK 5.2: a NIfTI or MetaImage file cut short reads "successfully", the missing voxels left as
// they were), the NIfTI transform by pneuma's rule from the header's own bytes, .seg.nrrd
// segments and layers, and TotalSegmentator's mask folders. ITK itself is in itk_read.cpp.
#include <fmt/format.h>
#include <libdeflate.h>
#include <zlib.h>

#include <Eigen/LU>  // determinant()

#include <algorithm>
#include <atomic>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <span>
#include <sstream>
#include <string>

#include "dicom_series.h"
#include "itk_image.h"
#include "pneuma/core/error.h"
#include "pneuma/core/paths.h"
#include "pneuma/core/text.h"
#include "pneuma/image/label_map.h"
#include "pneuma/image/scalar_image.h"

namespace pneuma::image {
namespace fs = std::filesystem;
namespace {

constexpr const char* kFormats =
    "expected a label map: .nii, .nii.gz, .nrrd, .nhdr, .seg.nrrd, .mha, .mhd, or a folder of TotalSegmentator masks";

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

bool ends_with(const std::string& name, const char* suffix) {
  const std::size_t len = std::strlen(suffix);
  return name.size() > len && name.compare(name.size() - len, len, suffix) == 0;
}

std::string trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) return "";
  return s.substr(first, s.find_last_not_of(" \t\r\n") - first + 1);
}

double file_bytes(const fs::path& path) {
  std::error_code ec;
  const auto n = fs::file_size(path, ec);
  return ec ? 0.0 : static_cast<double>(n);
}

// What a zlib or gzip stream (gzip members one after another, as pigz writes, included)
// inflates to from byte `offset` of the file, counted without keeping it. The stream is read to
// its end, so that zlib checks its CRC-32 or Adler-32 (200 zeroed bytes in a gzip stream inflated
// to other labels without a word, #49), up to twice `enough` bytes. `complete` is false when
// fewer than `enough` bytes come out; a damaged stream throws "<name>: the gzip data is damaged".
// With `keep` (room for `enough` bytes), the first `enough` bytes are kept there: the one read
// of a .nii.gz (#50), whose voxels ITK then takes from memory instead of inflating the file again.
struct Inflated {
  double bytes = 0.0;
  bool complete = false;
};

Inflated inflated_bytes(const fs::path& path, std::uint64_t offset, double enough, const std::string& name,
                        std::span<unsigned char> keep = {}) {
  Inflated result;
  std::ifstream in(path, std::ios::binary);
  in.seekg(static_cast<std::streamoff>(offset));
  if (!in) return result;
  z_stream z{};
  if (inflateInit2(&z, 15 + 32) != Z_OK) return result;  // 32: zlib or gzip header, detected
  std::vector<unsigned char> input(1 << 16), output(1 << 18);
  bool more_input = true, gzip = false;
  std::string damage;
  auto refill = [&] {
    in.read(reinterpret_cast<char*>(input.data()), static_cast<std::streamsize>(input.size()));
    z.next_in = input.data();
    z.avail_in = static_cast<unsigned>(in.gcount());
    more_input = in.gcount() > 0;
  };
  const double cap = 2.0 * enough + 1e6;
  while (result.bytes < cap) {
    if (z.avail_in == 0 && more_input) refill();
    if (z.total_in == 0 && z.avail_in > 0) gzip = z.next_in[0] == 0x1f;
    // Into `keep` while it has room (at most 1 GiB a call: avail_out is 32 bits), then counted only.
    const auto produced = static_cast<std::size_t>(result.bytes);
    const bool keeping = produced < keep.size();
    const std::size_t room =
        keeping ? std::min<std::size_t>(keep.size() - produced, std::size_t{1} << 30) : output.size();
    z.next_out = keeping ? keep.data() + produced : output.data();
    z.avail_out = static_cast<unsigned>(room);
    const int status = inflate(&z, Z_NO_FLUSH);
    result.bytes += static_cast<double>(room - z.avail_out);
    if (status == Z_STREAM_END) {
      // Another gzip member may follow.
      if (z.avail_in == 0 && more_input) refill();
      if (z.avail_in < 2 || z.next_in[0] != 0x1f || z.next_in[1] != 0x8b) break;
      inflateReset(&z);
      continue;
    }
    if (status == Z_DATA_ERROR || status == Z_NEED_DICT || status == Z_STREAM_ERROR) {
      damage = z.msg != nullptr ? z.msg : "invalid data";
      break;
    }
    if (status != Z_OK && !(status == Z_BUF_ERROR && z.avail_in == 0 && more_input)) break;
    if (status == Z_BUF_ERROR && !more_input) break;
  }
  inflateEnd(&z);
  if (!damage.empty()) {
    throw InputError(fmt::format("{}: the {} data is damaged ({}): expected an intact compressed stream", name,
                                 gzip ? "gzip" : "zlib", damage));
  }
  result.complete = result.bytes >= enough;
  return result;
}

// A gzip file (members one after another, as pigz writes) inflated whole into `keep` by
// libdeflate (its CRC-32 and length checked; 0.02 CPU-s for case004's label map against zlib's
// 0.18, #50): true when the members fill `keep` exactly. Anything else (a damaged or short
// stream, more data than `keep` holds, a zlib stream) returns false and is left to
// inflated_bytes, whose zlib gives the message.
bool inflated_whole(const fs::path& path, std::span<unsigned char> keep) try {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) return false;
  std::vector<unsigned char> packed(static_cast<std::size_t>(std::max<std::streamoff>(in.tellg(), 0)));
  in.seekg(0);
  if (!in.read(reinterpret_cast<char*>(packed.data()), static_cast<std::streamsize>(packed.size()))) return false;
  const std::unique_ptr<libdeflate_decompressor, void (*)(libdeflate_decompressor*)> inflater(
      libdeflate_alloc_decompressor(), libdeflate_free_decompressor);
  if (!inflater) return false;
  std::size_t read = 0, written = 0;
  while (read + 2 <= packed.size() && packed[read] == 0x1f && packed[read + 1] == 0x8b) {
    std::size_t used = 0, made = 0;
    if (libdeflate_gzip_decompress_ex(inflater.get(), packed.data() + read, packed.size() - read, keep.data() + written,
                                      keep.size() - written, &used, &made) != LIBDEFLATE_SUCCESS)
      return false;
    read += used;
    written += made;
  }
  return written == keep.size();
} catch (const std::bad_alloc&) {
  return false;  // no room for the whole compressed file: zlib's pass streams it
}

// A file that a header or a folder brings in (NRRD's `data file`, MetaImage's ElementDataFile):
// there and a regular file, or a pipe would block the read for ever (#49).
fs::path data_file_path(const fs::path& header, const std::string& name, const std::string& file, const char* key) {
  fs::path path = header.parent_path() / file;
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(name + ": its data file '" + file + "' (" + key + ") is missing");
  require_readable_file(path);
  return path;
}

}  // namespace

namespace detail {

void check_voxel_count(const std::string& name, const std::array<std::size_t, 3>& size, std::size_t components) {
  const double values = static_cast<double>(size[0]) * static_cast<double>(size[1]) * static_cast<double>(size[2]) *
                        static_cast<double>(components);
  if (values > kMaxVoxelValues) {
    throw InputError(fmt::format("{}: {} x {} x {} voxels{}: expected at most {:g} voxel values", name, size[0],
                                 size[1], size[2], components > 1 ? fmt::format(" in {} layers", components) : "",
                                 kMaxVoxelValues));
  }
}

void check_grid(const std::string& name, const std::string& source, const Eigen::Matrix4d& ijk_to_lps) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) {
      const double mm = ijk_to_lps(r, c) * 1e3;
      if (!(std::abs(mm) <= 1e6))
        throw InputError(fmt::format("{}: the {} holds {:g} mm: expected finite numbers of magnitude at most 1e6 mm",
                                     name, source, mm));
    }
  }
  Eigen::Matrix3d directions = ijk_to_lps.block<3, 3>(0, 0);
  for (int axis = 0; axis < 3; ++axis) {
    const double size_m = directions.col(axis).norm();
    if (!(size_m >= 1e-6))
      throw InputError(fmt::format("{}: the voxel size along axis {} ({}) is {:g} mm: expected at least 0.001 mm", name,
                                   axis + 1, source, size_m * 1e3));
    directions.col(axis) /= size_m;
  }
  // Axes (nearly) in one plane: a volume of nothing, and the inverse map meaningless.
  if (!(std::abs(directions.determinant()) >= 1e-6))
    throw InputError(
        fmt::format("{}: the {} gives voxel axes in one plane: expected three independent directions", name, source));
}

}  // namespace detail

namespace {

// ---- NIfTI: the header's own bytes (NIfTI-1: 348, NIfTI-2: 540, either byte order) ----

struct NiftiHeader {
  std::array<std::int64_t, 8> dim{};
  int datatype = 0;
  std::array<double, 8> pixdim{};
  double vox_offset = 0.0;
  int qform_code = 0, sform_code = 0;
  double quatern_b = 0, quatern_c = 0, quatern_d = 0, qoffset_x = 0, qoffset_y = 0, qoffset_z = 0;
  double srow[3][4]{};
  int xyz_units = 0;
  double scl_slope = 0.0, scl_inter = 0.0;
  std::size_t header_bytes = 0;  // 348 (NIfTI-1) or 540 (NIfTI-2)
  bool swapped = false;          // stored in the other byte order than this machine's
  std::string extensions;        // the text of every header extension, one after another
};

const char* nifti_type_name(int datatype) {
  switch (datatype) {
    case 2: return "UINT8";
    case 4: return "INT16";
    case 8: return "INT32";
    case 16: return "FLOAT32";
    case 32: return "COMPLEX64";
    case 64: return "FLOAT64";
    case 128: return "RGB24";
    case 256: return "INT8";
    case 512: return "UINT16";
    case 768: return "UINT32";
    case 1024: return "INT64";
    case 1280: return "UINT64";
    case 1536: return "FLOAT128";
    case 1792: return "COMPLEX128";
    case 2048: return "COMPLEX256";
    case 2304: return "RGBA32";
    default: return "UNKNOWN";
  }
}

int nifti_type_bytes(int datatype) {
  switch (datatype) {
    case 2:
    case 256: return 1;
    case 4:
    case 512: return 2;
    case 8:
    case 16:
    case 768: return 4;
    case 64:
    case 1024:
    case 1280: return 8;
    default: return 0;  // not a label type
  }
}

class Bytes {
 public:
  Bytes(const std::string& data, bool swap) : data_(data), swap_(swap) {}
  template <typename T>
  T get(std::size_t at) const {
    unsigned char raw[sizeof(T)];
    std::memcpy(raw, data_.data() + at, sizeof(T));
    if (swap_) std::reverse(raw, raw + sizeof(T));
    T value;
    std::memcpy(&value, raw, sizeof(T));
    return value;
  }

 private:
  const std::string& data_;
  bool swap_;
};

// The first `limit` bytes of the file, through zlib (which reads an uncompressed file as is).
std::string read_prefix(const fs::path& path, std::size_t limit) {
  std::string out;
  gzFile f = gzopen(path.c_str(), "rb");
  if (f == nullptr) return out;
  out.resize(limit);
  const int got = gzread(f, out.data(), static_cast<unsigned>(limit));
  gzclose(f);
  out.resize(got > 0 ? static_cast<std::size_t>(got) : 0);
  return out;
}

NiftiHeader read_nifti_header(const fs::path& path, const std::string& name) {
  const std::string not_nifti = name +
                                ": not a NIfTI file: expected a NIfTI-1 or NIfTI-2 header (348 or 540 bytes, magic "
                                "'n+1' or 'n+2'), gzip-compressed for .nii.gz";
  std::string h = read_prefix(path, 540);
  if (h.size() < 348) throw InputError(not_nifti);
  std::int32_t sizeof_hdr;
  std::memcpy(&sizeof_hdr, h.data(), 4);
  const bool swap = sizeof_hdr != 348 && sizeof_hdr != 540;
  const Bytes b(h, swap);
  sizeof_hdr = b.get<std::int32_t>(0);
  NiftiHeader n;
  std::size_t header_bytes = 0;
  if (sizeof_hdr == 348) {
    const std::string magic = h.substr(344, 4);
    if (magic == std::string("ni1\0", 4)) {
      throw InputError(name + ": a NIfTI header without its image (.hdr/.img pair): expected a single-file NIfTI "
                              "(.nii or .nii.gz)");
    }
    if (magic != std::string("n+1\0", 4)) {
      throw InputError(name + ": an ANALYZE 7.5 file, not NIfTI: expected a NIfTI-1 or NIfTI-2 header (it carries "
                              "the orientation)");
    }
    header_bytes = 348;
    for (std::size_t i = 0; i < 8; ++i) n.dim[i] = b.get<std::int16_t>(40 + 2 * i);
    n.datatype = b.get<std::int16_t>(70);
    for (std::size_t i = 0; i < 8; ++i) n.pixdim[i] = b.get<float>(76 + 4 * i);
    n.vox_offset = b.get<float>(108);
    n.scl_slope = b.get<float>(112), n.scl_inter = b.get<float>(116);
    n.xyz_units = static_cast<unsigned char>(h[123]) & 0x07;
    n.qform_code = b.get<std::int16_t>(252);
    n.sform_code = b.get<std::int16_t>(254);
    n.quatern_b = b.get<float>(256), n.quatern_c = b.get<float>(260), n.quatern_d = b.get<float>(264);
    n.qoffset_x = b.get<float>(268), n.qoffset_y = b.get<float>(272), n.qoffset_z = b.get<float>(276);
    for (std::size_t r = 0; r < 3; ++r)
      for (std::size_t c = 0; c < 4; ++c) n.srow[r][c] = b.get<float>(280 + 16 * r + 4 * c);
  } else if (sizeof_hdr == 540 && h.size() >= 540 && h.compare(4, 3, "n+2") == 0) {
    header_bytes = 540;
    n.datatype = b.get<std::int16_t>(12);
    for (std::size_t i = 0; i < 8; ++i) n.dim[i] = b.get<std::int64_t>(16 + 8 * i);
    for (std::size_t i = 0; i < 8; ++i) n.pixdim[i] = b.get<double>(104 + 8 * i);
    n.vox_offset = static_cast<double>(b.get<std::int64_t>(168));
    n.scl_slope = b.get<double>(176), n.scl_inter = b.get<double>(184);
    n.qform_code = b.get<std::int32_t>(344);
    n.sform_code = b.get<std::int32_t>(348);
    n.quatern_b = b.get<double>(352), n.quatern_c = b.get<double>(360), n.quatern_d = b.get<double>(368);
    n.qoffset_x = b.get<double>(376), n.qoffset_y = b.get<double>(384), n.qoffset_z = b.get<double>(392);
    for (std::size_t r = 0; r < 3; ++r)
      for (std::size_t c = 0; c < 4; ++c) n.srow[r][c] = b.get<double>(400 + 32 * r + 8 * c);
    n.xyz_units = b.get<std::int32_t>(500) & 0x07;
  } else {
    throw InputError(not_nifti);
  }
  n.header_bytes = header_bytes;
  n.swapped = swap;
  // Header extensions (between the header and vox_offset): TotalSegmentator's label table.
  const double extension_bytes = n.vox_offset - static_cast<double>(header_bytes) - 4.0;
  if (extension_bytes >= 16.0 && extension_bytes <= 64.0 * 1024 * 1024) {
    h = read_prefix(path, static_cast<std::size_t>(n.vox_offset));
    if (h.size() > header_bytes + 4 && h[header_bytes] != 0) {
      const Bytes e(h, swap);
      for (std::size_t at = header_bytes + 4; at + 8 <= h.size();) {
        const auto esize = e.get<std::int32_t>(at);
        if (esize < 16 || esize % 16 != 0 || at + static_cast<std::size_t>(esize) > h.size()) break;
        n.extensions.append(h, at + 8, static_cast<std::size_t>(esize) - 8);
        at += static_cast<std::size_t>(esize);
      }
    }
  }
  return n;
}

// Voxel -> LPS metres by pneuma's rule (niftilib's formulas: nifti_quatern_to_mat44).
Eigen::Matrix4d nifti_ijk_to_lps(const NiftiHeader& n, std::string& source) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  if (n.sform_code > 0) {
    source = "sform";
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) m(r, c) = n.srow[r][c];
  } else {
    const double dx = n.pixdim[1] > 0 ? n.pixdim[1] : 1.0, dy = n.pixdim[2] > 0 ? n.pixdim[2] : 1.0;
    double dz = n.pixdim[3] > 0 ? n.pixdim[3] : 1.0;
    if (n.qform_code > 0) {
      source = "qform";
      double b = n.quatern_b, c = n.quatern_c, d = n.quatern_d;
      double a = 1.0 - (b * b + c * c + d * d);
      if (a < 1.e-7) {  // a quaternion of length > 1: normalised, a = 0
        a = 1.0 / std::sqrt(b * b + c * c + d * d);
        b *= a, c *= a, d *= a;
        a = 0.0;
      } else {
        a = std::sqrt(a);
      }
      if (n.pixdim[0] < 0) dz = -dz;  // qfac
      m(0, 0) = (a * a + b * b - c * c - d * d) * dx;
      m(0, 1) = 2.0 * (b * c - a * d) * dy;
      m(0, 2) = 2.0 * (b * d + a * c) * dz;
      m(1, 0) = 2.0 * (b * c + a * d) * dx;
      m(1, 1) = (a * a + c * c - b * b - d * d) * dy;
      m(1, 2) = 2.0 * (c * d - a * b) * dz;
      m(2, 0) = 2.0 * (b * d - a * c) * dx;
      m(2, 1) = 2.0 * (c * d + a * b) * dy;
      m(2, 2) = (a * a + d * d - c * c - b * b) * dz;
      m(0, 3) = n.qoffset_x, m(1, 3) = n.qoffset_y, m(2, 3) = n.qoffset_z;
    } else {
      source = "pixdim";
      m(0, 0) = dx, m(1, 1) = dy, m(2, 2) = dz;
    }
  }
  // Metres per unit of xyzt_units; unknown units are millimetres, as nearly every writer means.
  const double unit = n.xyz_units == 1 ? 1.0 : n.xyz_units == 3 ? 1e-6 : 1e-3;
  m.topRows(3) *= unit;
  m.row(0) *= -1.0;  // RAS -> LPS
  m.row(1) *= -1.0;
  return m;
}

struct NiftiVoxels {
  NiftiHeader header;
  detail::ItkImage image;
};

// The header by pneuma's reading, its data checked against the file, then the voxels through ITK.
NiftiVoxels read_nifti_voxels(const fs::path& path, const std::string& name, detail::VoxelKind kind) {
  const NiftiHeader n = read_nifti_header(path, name);
  const std::int64_t rank = n.dim[0];
  if (rank < 1 || rank > 7) throw InputError(name + ": dim[0] is " + std::to_string(rank) + ": expected 1 to 7");
  for (std::int64_t d = 4; d <= 7; ++d) {
    const auto du = static_cast<std::size_t>(d);
    if (rank >= d && n.dim[du] > 1) {
      throw InputError(name + ": " + std::to_string(rank) +
                       "-dimensional data: expected one 3D label volume (dimension " + std::to_string(d) + " has " +
                       std::to_string(n.dim[du]) + " entries)");
    }
  }
  std::array<std::size_t, 3> size{1, 1, 1};
  for (std::size_t a = 0; a < 3; ++a) {
    const std::int64_t v = static_cast<std::int64_t>(a) + 1 <= rank ? n.dim[a + 1] : 1;
    if (v < 1) throw InputError(name + ": expected a non-empty 3D volume");
    size[a] = static_cast<std::size_t>(v);
  }
  // Without an sform, the voxel size is pixdim's: 0 or NaN there used to become 1 mm in silence
  // (niftilib's rule), a wrong volume with no word (2,628 mL for 2,275 mL).
  if (n.sform_code <= 0) {
    for (std::size_t d = 1; d <= 3; ++d) {
      if (static_cast<std::int64_t>(d) <= rank && !(n.pixdim[d] > 0.0 && std::isfinite(n.pixdim[d]))) {
        throw InputError(fmt::format("{}: pixdim[{}] is {}: expected a positive voxel size (the file has no sform "
                                     "to give it instead)",
                                     name, d, n.pixdim[d]));
      }
    }
  }
  // The orientation's numbers, before ITK sees them: a NaN in srow aborted inside ITK's SVD of
  // the direction matrix (vnl's assert_finite), and -1.7e38 made that SVD run for ever (found by
  // scripts/mutate). A kilometre (1e6 mm) is far beyond any scanner.
  auto require_finite = [&](const char* field, double value) {
    if (!(std::abs(value) <= 1e6))
      throw InputError(fmt::format("{}: {} is {:g}: expected a finite number of magnitude at most 1e6 (the voxel -> "
                                   "world orientation)",
                                   name, field, value));
  };
  // niftilib warns on stderr about a fractional data offset, and no NIfTI writer makes one.
  if (n.vox_offset != std::floor(n.vox_offset) || n.vox_offset > 1e12)
    throw InputError(fmt::format("{}: vox_offset is {:g}: expected a whole number of bytes", name, n.vox_offset));
  if (n.sform_code > 0) {
    static constexpr std::array<const char*, 3> kRows{"srow_x", "srow_y", "srow_z"};
    for (std::size_t r = 0; r < 3; ++r)
      for (std::size_t c = 0; c < 4; ++c) require_finite(kRows[r], n.srow[r][c]);
  }
  if (n.qform_code > 0) {
    require_finite("quatern_b", n.quatern_b), require_finite("quatern_c", n.quatern_c);
    require_finite("quatern_d", n.quatern_d), require_finite("qoffset_x", n.qoffset_x);
    require_finite("qoffset_y", n.qoffset_y), require_finite("qoffset_z", n.qoffset_z);
  }
  for (std::size_t d = 0; d <= 3; ++d) require_finite(fmt::format("pixdim[{}]", d).c_str(), n.pixdim[d]);
  // A voxel thinner than a micrometre is a damaged header (srow_z 4e-19 made the smoothing kernel
  // 1e18 voxels wide; found by scripts/mutate): the rule of every format.
  {
    std::string source;
    const Eigen::Matrix4d m = nifti_ijk_to_lps(n, source);
    detail::check_grid(name, source, m);
  }
  const char* type = nifti_type_name(n.datatype);
  const int type_bytes = nifti_type_bytes(n.datatype);
  if (type_bytes == 0) {
    throw InputError(name + ": voxels of type " + type + ": " +
                     (kind == detail::VoxelKind::labels ? "expected integer labels (uint8, int16, int32, ...)"
                                                        : "expected numbers (int16, float32, ...)"));
  }
  // The data the header promises, against the file (a damaged header claimed 37 GB, found by
  // fuzz_nifti): counted through the gzip stream without keeping it, before ITK allocates.
  const bool gzipped = ends_with(lower(name), ".gz");
  const double data_bytes = static_cast<double>(size[0]) * static_cast<double>(size[1]) * static_cast<double>(size[2]) *
                            static_cast<double>(type_bytes);
  const double needed = std::max(n.vox_offset, 0.0) + data_bytes;
  const std::string truncated = detail::truncated_message(name, size, 1, type, data_bytes, gzipped);
  if (!((gzipped ? 1032.0 * file_bytes(path) + 4096.0 : file_bytes(path)) >= needed)) throw InputError(truncated);
  detail::check_voxel_count(name, size, 1);  // before the stream is inflated to count it
  // A .nii.gz is inflated once (#50): the stream checked whole here, its bytes kept, and ITK reads
  // only the header and takes the voxels from them. Kept only where ITK's own read would give the
  // stored values (no scl_slope rescale; the data after the header and its extension flag, where
  // niftilib looks for it too), and where the room is to be had: the pages are touched only as
  // the stream fills them, so a header claiming more than the stream holds costs no memory.
  // niftilib's rule (FIXED_FLOAT): a slope or intercept that is not a number is 0 (a slope of 0:
  // no rescale).
  const auto fixed = [](double f) { return std::isfinite(f) ? f : 0.0; };
  const double slope = fixed(n.scl_slope), intercept = fixed(n.scl_inter);
  const bool as_stored = slope == 0.0 || (slope == 1.0 && intercept == 0.0);
  std::unique_ptr<unsigned char[]> kept;
  if (gzipped && as_stored && n.vox_offset >= static_cast<double>(n.header_bytes + 4)) {
    try {
      kept = std::make_unique_for_overwrite<unsigned char[]>(static_cast<std::size_t>(needed));
    } catch (const std::bad_alloc&) {
      kept.reset();  // counted without keeping; ITK reads the file again
    }
  }
  const std::span<unsigned char> keep =
      kept ? std::span<unsigned char>(kept.get(), static_cast<std::size_t>(needed)) : std::span<unsigned char>();
  if (gzipped && !(kept && inflated_whole(path, keep)) && !inflated_bytes(path, 0, needed, name, keep).complete)
    throw InputError(truncated);
  std::optional<detail::VoxelBytes> in_memory;
  if (kept) {
    in_memory = detail::VoxelBytes{
        .bytes = keep.subspan(static_cast<std::size_t>(n.vox_offset)), .swap = n.swapped, .type_name = type};
  }

  // Checked above: what ITK finds in the header is there.
  NiftiVoxels read{n, detail::read_itk_image(
                          path, detail::ImageFormat::nifti,
                          [&](const detail::ItkImage& header) {
                            return detail::StoredData{
                                .compressed = gzipped, .exact = true, .bytes = header.data_bytes()};
                          },
                          kind, in_memory ? &*in_memory : nullptr)};
  const detail::ItkImage& image = read.image;
  if (image.size != size || image.components != 1) {
    throw InputError(name + ": the voxels do not match the header (" + std::to_string(image.size[0]) + " x " +
                     std::to_string(image.size[1]) + " x " + std::to_string(image.size[2]) + " read)");
  }
  return read;
}

LabelMap read_nifti(const fs::path& path, const std::string& name, const LabelMapOptions& options) {
  NiftiVoxels read = read_nifti_voxels(path, name, detail::VoxelKind::labels);
  LabelMap map;
  map.size = read.image.size;
  map.labels = std::move(read.image.values);
  map.ijk_to_lps = nifti_ijk_to_lps(read.header, map.transform_source);
  if (options.names == SegmentNames::from_file) {
    map.segments = detail::caret_label_table(read.header.extensions);
  }
  return map;
}

// ---- MetaImage: where the data is, from the header's own lines ----

// A MetaImage header's own lines up to ElementDataFile: where its data is.
struct MetaHeader {
  bool compressed = false;
  double header_size = 0.0;
  std::uint64_t offset = 0;  // where local data starts, or the data file's HeaderSize
  fs::path data;             // the file holding the data (the file itself when LOCAL)
};

MetaHeader read_meta_header(const fs::path& path, const std::string& name) {
  std::ifstream in(path, std::ios::binary);
  std::string line, data_file;
  MetaHeader h;
  while (std::getline(in, line) && h.offset < (1u << 20)) {
    h.offset += line.size() + 1;
    const auto eq = line.find('=');
    if (eq == std::string::npos) continue;
    const std::string key = trim(line.substr(0, eq)), value = trim(line.substr(eq + 1));
    if (key == "CompressedData") h.compressed = lower(value) == "true";
    if (key == "HeaderSize") h.header_size = std::atof(value.c_str());
    if (key == "ElementDataFile") {
      data_file = value;
      break;
    }
  }
  h.data = path;
  if (data_file != "LOCAL" && data_file != "Local" && data_file != "local") {
    if (data_file.empty() || data_file == "LIST" || data_file.find('%') != std::string::npos) {
      throw InputError(name + ": ElementDataFile '" + data_file + "': expected LOCAL or one data file");
    }
    h.data = data_file_path(path, name, data_file, "ElementDataFile");
    h.offset = h.header_size > 0 ? static_cast<std::uint64_t>(h.header_size) : 0;
  }
  return h;
}

detail::StoredData meta_stored_data(const fs::path& path, const std::string& name, const detail::ItkImage& image) {
  const MetaHeader h = read_meta_header(path, name);
  const bool compressed = h.compressed;
  const double header_size = h.header_size;
  const std::uint64_t offset = h.offset;
  const fs::path& data_path = h.data;
  const double claimed = image.data_bytes();
  if (compressed) {
    return {.compressed = true, .exact = true, .bytes = inflated_bytes(data_path, offset, claimed, name).bytes};
  }
  const double available =
      header_size < 0 ? file_bytes(data_path) : file_bytes(data_path) - static_cast<double>(offset);
  return {.compressed = false, .exact = true, .bytes = available};
}

// ---- NRRD: where the data is (NrrdIO checks its length itself), and .seg.nrrd segments ----

std::optional<long long> parse_integer(const std::string& text) {
  const std::string t = trim(text);
  if (t.empty()) return std::nullopt;
  char* end = nullptr;
  const long long v = std::strtoll(t.c_str(), &end, 10);
  if (end != t.c_str() + t.size()) return std::nullopt;
  return v;
}

// The files of NRRD's `data file: LIST` (the header's remaining lines) or `data file: <pattern>
// <min> <max> <step> [<subdim>]` (one %d, possibly zero-padded: "slice%03d.raw").
std::vector<std::string> nrrd_data_files(const std::string& value, std::istream& rest, const std::string& name) {
  constexpr std::size_t kMaxFiles = 100000;
  std::vector<std::string> files;
  if (value.starts_with("LIST")) {
    std::string line;
    while (std::getline(rest, line) && files.size() <= kMaxFiles) {
      if (!trim(line).empty()) files.push_back(trim(line));
    }
  } else if (value.find('%') != std::string::npos) {
    std::istringstream words(value);
    std::string pattern;
    long long min = 0, max = 0, step = 0;
    words >> pattern >> min >> max >> step;
    const std::size_t at = pattern.find('%');
    std::size_t end = at + 1;
    while (end < pattern.size() && std::isdigit(static_cast<unsigned char>(pattern[end]))) ++end;
    const bool one_integer = words && step != 0 && end < pattern.size() && std::strchr("diu", pattern[end]) &&
                             pattern.find('%', end) == std::string::npos && end - at <= 4;
    const long long count = one_integer ? (max - min) / step + 1 : 0;
    if (!one_integer || count < 1 || count > static_cast<long long>(kMaxFiles)) {
      throw InputError(fmt::format("{}: data file '{}': expected a file name, LIST, or a pattern with one %d and its "
                                   "first, last and step (at most {} files)",
                                   name, value, kMaxFiles));
    }
    const bool zeros = end > at + 1 && pattern[at + 1] == '0';
    const int width = end > at + 1 ? std::atoi(pattern.substr(at + 1, end - at - 1).c_str()) : 0;
    for (long long i = 0; i < count; ++i) {
      const std::string number = fmt::format(fmt::runtime(zeros ? "{:0{}d}" : "{:{}d}"), min + i * step, width);
      files.push_back(pattern.substr(0, at) + number + pattern.substr(end + 1));
    }
  } else {
    files.push_back(value);
  }
  if (files.empty() || files.size() > kMaxFiles) {
    throw InputError(fmt::format("{}: data file '{}': expected from 1 to {} files", name, value, kMaxFiles));
  }
  return files;
}

// A NRRD header's own lines, read before ITK: teem opens a detached data file while it reads the
// header (a pipe there never returned, #49) and turns a NaN, negative or 1e308 spacing into
// another one without a word, so those are refused here.
struct NrrdHeader {
  std::string encoding = "raw";
  bool skips = false;          // line skip or byte skip: the data's start is not the header's end
  std::uint64_t offset = 0;    // where attached data starts
  std::vector<fs::path> data;  // the files holding the data (the file itself when attached)
};

NrrdHeader read_nrrd_header(const fs::path& path, const std::string& name) {
  std::ifstream in(path, std::ios::binary);
  NrrdHeader h;
  std::string line, data_file;
  long long dimension = 3;
  for (int number = 1; std::getline(in, line) && number < 10000; ++number) {
    h.offset += line.size() + 1;
    if (trim(line).empty()) break;
    const auto colon = line.find(':');
    if (colon == std::string::npos || line.compare(colon, 2, ":=") == 0 || line[0] == '#') continue;
    const std::string key = lower(trim(line.substr(0, colon))), value = trim(line.substr(colon + 1));
    const std::string where = fmt::format("{}:{}:{}: {}: ", name, number, colon + 3, key);
    // Finite numbers of magnitude at most 1e6 (positive for spacings), "none" or "nan" (a
    // non-spatial axis) where the axis may have none.
    auto check_numbers = [&](bool positive) {
      std::string numbers = value;
      std::replace_if(
          numbers.begin(), numbers.end(), [](char c) { return c == '(' || c == ')' || c == ','; }, ' ');
      std::istringstream words(numbers);
      std::string word;
      int missing = 0;
      while (words >> word) {
        if (lower(word) == "none" || lower(word) == "nan") {
          ++missing;
          continue;
        }
        char* end = nullptr;
        const double v = std::strtod(word.c_str(), &end);
        if (end != word.c_str() + word.size() || !(std::abs(v) <= 1e6) || (positive && !(v > 0.0))) {
          throw InputError(where + (positive ? "expected positive" : "expected finite") +
                           " numbers of magnitude at most 1e6 (millimetres), got " + quote_input(word));
        }
      }
      if (missing > dimension - 3)
        throw InputError(where + "expected a number for each of the three spatial axes, got " + quote_input(value));
    };
    if (key == "dimension") {
      if (const auto d = parse_integer(value)) dimension = *d;
    } else if (key == "encoding") {
      h.encoding = lower(value);
    } else if (key == "line skip" || key == "lineskip" || key == "byte skip" || key == "byteskip") {
      h.skips = true;
    } else if (key == "spacings") {
      check_numbers(true);
    } else if (key == "space directions" || key == "space origin") {
      check_numbers(false);
    } else if (key == "data file" || key == "datafile") {
      data_file = value;
      break;  // LIST: the file names follow
    }
  }
  if (data_file.empty()) {
    h.data.push_back(path);
  } else {
    for (const std::string& file : nrrd_data_files(data_file, in, name))
      h.data.push_back(data_file_path(path, name, file, "data file:"));
    h.offset = 0;
  }
  return h;
}

detail::StoredData nrrd_stored_data(const NrrdHeader& h, const std::string& name, const detail::ItkImage& image) {
  const bool gzip = h.encoding == "gzip" || h.encoding == "gz";
  double bytes = 0.0;
  for (const fs::path& data_path : h.data) {
    // Inflated whole to check its CRC, where the skips do not make the data's start uncertain.
    if (gzip && !h.skips) {
      bytes += inflated_bytes(data_path, h.offset, image.data_bytes(), name).bytes;
    } else {
      bytes += file_bytes(data_path) - static_cast<double>(h.offset);
    }
  }
  if (gzip && !h.skips) return {.compressed = true, .exact = true, .bytes = bytes};
  if (gzip || h.encoding == "bzip2" || h.encoding == "bz2") return {.compressed = true, .exact = false, .bytes = bytes};
  // Text: each voxel takes at least one character, and a voxel at most 8 bytes.
  const bool text = h.encoding == "ascii" || h.encoding == "text" || h.encoding == "txt" || h.encoding == "hex";
  return {.compressed = false, .exact = false, .bytes = text ? 8.0 * bytes : bytes};
}

struct SegNrrdSegment {
  std::string name;
  long long label = 0;
  std::size_t layer = 0;
};

std::vector<SegNrrdSegment> seg_nrrd_segments(const detail::ItkImage& image, const std::string& name) {
  std::vector<SegNrrdSegment> out;
  for (int i = 0;; ++i) {
    const std::string prefix = "Segment" + std::to_string(i) + "_";
    const auto found = image.metadata.find(prefix + "Name");
    if (found == image.metadata.end()) break;
    SegNrrdSegment s;
    s.name = trim(found->second);
    const auto label = image.metadata.find(prefix + "LabelValue");
    const auto layer = image.metadata.find(prefix + "Layer");
    const std::optional<long long> l = label == image.metadata.end() ? 1LL : parse_integer(label->second);
    const std::optional<long long> y = layer == image.metadata.end() ? 0LL : parse_integer(layer->second);
    if (!l || *l < 1 || *l > 2147483647LL) {
      throw InputError(
          fmt::format("{}: {}LabelValue is '{}': expected a positive integer", name, prefix, label->second));
    }
    if (!y || *y < 0 || static_cast<std::size_t>(*y) >= image.components) {
      throw InputError(fmt::format("{}: {}Layer is '{}': expected a layer from 0 to {}", name, prefix,
                                   layer == image.metadata.end() ? std::string() : layer->second,
                                   image.components - 1));
    }
    s.label = *l;
    s.layer = static_cast<std::size_t>(*y);
    for (const SegNrrdSegment& other : out) {
      if (other.name == s.name) throw InputError(name + ": two segments are named \"" + s.name + "\"");
      if (other.layer == s.layer && other.label == s.label) {
        throw InputError(name + ": segments \"" + other.name + "\" and \"" + s.name + "\" have the same label value " +
                         std::to_string(s.label) + " in layer " + std::to_string(s.layer));
      }
    }
    out.push_back(std::move(s));
  }
  return out;
}

// One label volume from the layers of a .seg.nrrd (3D Slicer keeps overlapping segments in
// separate layers): refused when two layers overlap; a label value met in more than one layer
// is renumbered (above every value in the file), and its segment follows it.
LabelMap flatten_layers(detail::ItkImage& image, const std::vector<SegNrrdSegment>& segments, const std::string& name) {
  LabelMap map;
  map.size = image.size;
  map.ijk_to_lps = image.ijk_to_lps;
  map.transform_source = "space directions";
  const std::size_t layers = image.components, voxels = image.voxel_count();
  if (layers == 1) {
    map.labels = std::move(image.values);
    for (const SegNrrdSegment& s : segments) map.segments.push_back({s.name, static_cast<std::int32_t>(s.label)});
    return map;
  }
  // Which (layer, value) pairs occur, and where layers overlap.
  std::set<std::pair<std::size_t, std::int32_t>> pairs;
  std::map<std::pair<std::size_t, std::size_t>, std::size_t> overlaps;
  for (std::size_t v = 0; v < voxels; ++v) {
    std::size_t first = layers;
    for (std::size_t l = 0; l < layers; ++l) {
      const std::int32_t value = image.values[v * layers + l];
      if (value == 0) continue;
      pairs.emplace(l, value);
      if (first == layers) {
        first = l;
      } else {
        ++overlaps[{first, l}];
      }
    }
  }
  if (!overlaps.empty()) {
    const auto& [which, count] = *overlaps.begin();
    auto segment_in = [&](std::size_t layer) {
      for (const SegNrrdSegment& s : segments)
        if (s.layer == layer) return " \"" + s.name + "\"";
      return std::string();
    };
    throw InputError(name + ": layers " + std::to_string(which.first) + " and " + std::to_string(which.second) +
                     " overlap in " + std::to_string(count) + " voxels (segments" + segment_in(which.first) + " and" +
                     segment_in(which.second) +
                     "): expected segments that do not overlap (in 3D Slicer, export them to a labelmap volume)");
  }
  for (const SegNrrdSegment& s : segments) pairs.emplace(s.layer, static_cast<std::int32_t>(s.label));
  std::map<std::int32_t, int> layers_of_value;
  std::int32_t top = 0;
  for (const auto& [layer, value] : pairs) ++layers_of_value[value], top = std::max(top, value);
  std::map<std::pair<std::size_t, std::int32_t>, std::int32_t> flat;
  std::set<std::int32_t> used;
  for (const auto& [layer, value] : pairs) {
    const bool keep = layers_of_value[value] == 1 || !used.count(value);
    const std::int32_t to = keep ? value : ++top;
    flat[{layer, value}] = to;
    used.insert(to);
  }
  map.labels.assign(voxels, 0);
  for (std::size_t v = 0; v < voxels; ++v) {
    for (std::size_t l = 0; l < layers; ++l) {
      const std::int32_t value = image.values[v * layers + l];
      if (value != 0) map.labels[v] = flat[{l, value}];
    }
  }
  for (const SegNrrdSegment& s : segments) {
    map.segments.push_back({s.name, flat[{s.layer, static_cast<std::int32_t>(s.label)}]});
  }
  return map;
}

// MetaIO reads its header with >>: a value it cannot read leaves the stream failed, and its next
// read of a key then never ends (a 115-byte header with NDims and no value hung, found by
// fuzz_labels_mha); NDims = 99997 sized matrices for minutes. So every line MetaIO parses is
// checked here first, up to ElementDataFile: "<file>:<line>:1: <Key>: expected ..., got '...'".
void check_meta_header(const fs::path& path, const std::string& name) {
  constexpr std::size_t kMaxMetaKey = 64;
  constexpr std::size_t kMaxMetaText = 254;
  static const std::set<std::string> kTypes{
      "MET_CHAR", "MET_UCHAR", "MET_SHORT",     "MET_USHORT",     "MET_INT",   "MET_UINT",
      "MET_LONG", "MET_ULONG", "MET_LONG_LONG", "MET_ULONG_LONG", "MET_FLOAT", "MET_DOUBLE",
  };
  std::ifstream in(path, std::ios::binary);
  std::string line;
  std::size_t ndims = 0;
  bool dim_size = false, element_type = false, binary = false;
  int compressed_line = 0;  // CompressedData = True's line, if any
  std::uint64_t read = 0;
  for (int number = 1; std::getline(in, line) && read < (1u << 20); ++number) {
    read += line.size() + 1;
    if (trim(line).empty()) continue;
    const auto eq = line.find('=');
    if (eq == std::string::npos && read == line.size() + 1) break;  // not a MetaImage at all
    const std::string where = fmt::format("{}:{}:1: ", name, number);
    if (eq == std::string::npos)
      throw InputError(where + "expected 'Key = Value' (a MetaImage header line), got " + quote_input(line));
    const std::string key = trim(line.substr(0, eq)), value = trim(line.substr(eq + 1));
    // MetaIO copies an unknown key into a 255-byte name with strcpy (a 250-byte key overflowed it,
    // found by fuzz_labels_mha): a key is a word, as every MetaIO key is.
    if (key.empty() || key.size() > kMaxMetaKey ||
        !std::all_of(key.begin(), key.end(), [](unsigned char c) { return std::isalnum(c) || c == '_'; })) {
      throw InputError(fmt::format("{}expected a key of letters, digits and '_' (at most {} characters), got {}", where,
                                   kMaxMetaKey, quote_input(key)));
    }
    // Control characters in a text value: pneuma and MetaIO would read different values (tabs and
    // carriage returns before LOCAL made MetaIO look for a data file, and leak its stream, where
    // pneuma saw LOCAL: fuzz_labels_mha). A line's final '\r' (CRLF files) is whitespace.
    auto printable = [&] {
      const std::string_view text(line.data(), line.ends_with('\r') ? line.size() - 1 : line.size());
      // MetaIO strcpy's a text value into a 255-byte field (a 300-byte ObjectType overflowed it).
      if (value.size() > kMaxMetaText ||
          std::any_of(text.begin(), text.end(), [](unsigned char c) { return c < 0x20 || c == 0x7f; })) {
        std::string_view raw = text.substr(eq + 1);
        raw.remove_prefix(std::min(raw.find_first_not_of(' '), raw.size()));
        throw InputError(fmt::format("{}{}: expected printable text of at most {} bytes, got {}", where, key,
                                     kMaxMetaText, quote_input(raw)));
      }
    };
    auto numbers = [&](std::size_t count, bool whole, double low, double high) {
      std::istringstream words(value);
      std::string word;
      std::size_t n = 0;
      for (; words >> word; ++n) {
        char* end = nullptr;
        const double v = std::strtod(word.c_str(), &end);
        if (end != word.c_str() + word.size() || !(v >= low && v <= high) || (whole && v != std::floor(v))) break;
      }
      if (n != count || words >> word) {
        throw InputError(fmt::format("{}{}: expected {} {} from {:g} to {:g}, got {}", where, key, count,
                                     whole ? "whole numbers" : "numbers", low, high, quote_input(value)));
      }
    };
    const bool array = key == "DimSize" || key == "ElementSpacing" || key == "ElementSize" || key == "Position" ||
                       key == "Origin" || key == "Offset" || key == "CenterOfRotation" || key == "TransformMatrix" ||
                       key == "Rotation" || key == "Orientation";
    if (array && ndims == 0) throw InputError(where + key + ": expected after NDims (its length)");
    if (key == "NDims") {
      numbers(1, true, 2, 4);
      ndims = static_cast<std::size_t>(std::stoi(value));
    } else if (key == "DimSize") {
      numbers(ndims, true, 1, 1e9);
      dim_size = true;
    } else if (key == "ElementSpacing" || key == "ElementSize") {
      // A negative spacing mirrored the lung left-right without a word (#49).
      numbers(ndims, false, 1e-3, 1e6);
    } else if (key == "Position" || key == "Origin" || key == "Offset" || key == "CenterOfRotation") {
      numbers(ndims, false, -1e6, 1e6);
    } else if (key == "TransformMatrix" || key == "Rotation" || key == "Orientation") {
      numbers(ndims * ndims, false, -1e6, 1e6);
    } else if (key == "ID" || key == "ParentID" || key == "HeaderSize") {
      numbers(1, true, -1, 1e15);
    } else if (key == "ElementNumberOfChannels") {
      numbers(1, true, 1, 1e6);
    } else if (key == "CompressedDataSize" || key == "ElementMin" || key == "ElementMax") {
      numbers(1, false, -1e300, 1e300);
    } else if (key == "Color" || key == "SequenceID") {
      numbers(4, false, -1e300, 1e300);
    } else if (key == "CompressedData" || key == "BinaryData" || key == "BinaryDataByteOrderMSB" ||
               key == "ElementByteOrderMSB") {
      if (lower(value) != "true" && lower(value) != "false")
        throw InputError(where + key + ": expected True or False, got " + quote_input(value));
      if (key == "CompressedData") compressed_line = lower(value) == "true" ? number : 0;
      if (key == "BinaryData") binary = lower(value) == "true";
    } else if (key == "ElementType") {
      std::string base = value;
      if (base.ends_with("_ARRAY")) base.resize(base.size() - 6);
      if (!kTypes.count(base))
        throw InputError(where + key +
                         ": expected MET_UCHAR, MET_SHORT, MET_INT, MET_FLOAT, ... (a MetaIO type), got " +
                         quote_input(value));
      element_type = true;
    } else if (key == "ElementDataFile") {
      printable();
      if (!dim_size || !element_type)
        throw InputError(where + key + ": expected NDims, DimSize and ElementType before it");
      // Compressed text data: MetaIO then inflates the file from its first byte, header and all;
      // the read goes on with voxels that are not the file's, or (a header that begins like a zlib stream) the
      // read never ends (fuzz_labels_mha). MetaIO writes compressed data only as binary.
      if (compressed_line > 0 && !binary) {
        throw InputError(fmt::format("{}:{}:1: CompressedData: expected BinaryData = True in the header (compressed "
                                     "data is binary)",
                                     name, compressed_line));
      }
      return;
    } else {
      printable();
    }
  }
  throw InputError(name + ": " + detail::format_expectation(detail::ImageFormat::meta));
}

// A NRRD or MetaImage file through ITK, its data checked against the file first.
detail::ItkImage read_itk_voxels(const fs::path& path, const std::string& name, detail::ImageFormat format,
                                 detail::VoxelKind kind) {
  NrrdHeader nrrd;
  if (format == detail::ImageFormat::meta) check_meta_header(path, name);
  if (format == detail::ImageFormat::nrrd) nrrd = read_nrrd_header(path, name);
  return detail::read_itk_image(
      path, format,
      [&](const detail::ItkImage& header) {
        // Before the voxels are allocated: the rules of every format.
        detail::check_grid(name, format == detail::ImageFormat::meta ? "TransformMatrix" : "space directions",
                           header.ijk_to_lps);
        detail::check_voxel_count(name, header.size, header.components);
        return format == detail::ImageFormat::meta ? meta_stored_data(path, name, header)
                                                   : nrrd_stored_data(nrrd, name, header);
      },
      kind);
}

LabelMap read_itk_map(const fs::path& path, const std::string& name, detail::ImageFormat format) {
  detail::ItkImage image = read_itk_voxels(path, name, format, detail::VoxelKind::labels);
  if (format == detail::ImageFormat::nrrd) return flatten_layers(image, seg_nrrd_segments(image, name), name);
  if (image.components != 1) {
    throw InputError(name + ": " + std::to_string(image.components) +
                     " values per voxel: expected one label per voxel");
  }
  LabelMap map;
  map.size = image.size;
  map.ijk_to_lps = image.ijk_to_lps;
  map.transform_source = "TransformMatrix";
  map.labels = std::move(image.values);
  return map;
}

// ---- TotalSegmentator's mask folder ----

LabelMap read_map(const fs::path& path, const LabelMapOptions& options);  // a file or a folder, uncounted

LabelMap read_mask_folder(const fs::path& dir, const std::string& name, const LabelMapOptions& options) {
  const std::vector<Segment> classes = totalsegmentator_classes(2);
  LabelMap map;
  std::string first_file;
  std::int32_t next_free = 1000;  // masks that are not TotalSegmentator classes
  std::vector<std::string> owner_of_label;
  for (const std::string& stem : options.masks) {
    fs::path file = dir / (stem + ".nii.gz");
    if (!fs::exists(file)) file = dir / (stem + ".nii");
    if (!fs::exists(file)) continue;
    LabelMapOptions plain;
    plain.masks.clear();
    const LabelMap mask = read_map(file, plain);
    const auto known = std::find_if(classes.begin(), classes.end(), [&](const Segment& s) { return s.name == stem; });
    const std::int32_t label = known != classes.end() ? known->label : next_free++;
    if (first_file.empty()) {
      first_file = file.filename().string();
      map.size = mask.size;
      map.ijk_to_lps = mask.ijk_to_lps;
      map.transform_source = mask.transform_source;
      map.labels.assign(mask.voxel_count(), 0);
    } else {
      const double offset_m = (mask.ijk_to_lps - map.ijk_to_lps).cwiseAbs().maxCoeff();
      if (mask.size != map.size || !(offset_m <= 1e-3 * map.spacing_m().minCoeff())) {
        const std::string transform =
            mask.size == map.size ? ", voxel-to-LPS transform differs by " + std::to_string(offset_m * 1e3) + " mm"
                                  : std::string();
        throw InputError(fmt::format("{}: {} is on another grid than {} ({} x {} x {} voxels against {} x {} x {}{}): "
                                     "expected every mask on the grid of the CT",
                                     name, file.filename().string(), first_file, mask.size[0], mask.size[1],
                                     mask.size[2], map.size[0], map.size[1], map.size[2], transform));
      }
    }
    std::size_t overlap = 0;
    std::int32_t other = 0;
    for (std::size_t v = 0; v < map.labels.size(); ++v) {
      if (mask.labels[v] == 0) continue;
      if (map.labels[v] != 0) {
        ++overlap, other = map.labels[v];
        continue;
      }
      map.labels[v] = label;
    }
    if (overlap > 0) {
      const auto o =
          std::find_if(map.segments.begin(), map.segments.end(), [&](const Segment& s) { return s.label == other; });
      throw InputError(name + ": " + file.filename().string() + " and " + o->name + " overlap in " +
                       std::to_string(overlap) + " voxels: expected masks that do not overlap");
    }
    map.segments.push_back({stem, label});
  }
  if (first_file.empty()) {
    std::string wanted;
    for (const std::string& stem : options.masks) wanted += (wanted.empty() ? "" : ", ") + stem + ".nii.gz";
    throw InputError(name + ": a folder without TotalSegmentator masks: expected " +
                     (wanted.empty() ? std::string("mask files") : wanted));
  }
  return map;
}

}  // namespace

std::vector<fs::path> label_map_files(const fs::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  // A folder (TotalSegmentator masks, a DICOM series with its RTSTRUCT): the folder itself.
  if (fs::is_directory(path, ec)) return {path};
  std::vector<fs::path> files{path};
  const std::string n = lower(name);
  if (n.ends_with(".nhdr") || n.ends_with(".nrrd")) {
    for (const fs::path& data : read_nrrd_header(path, name).data)
      if (data != path) files.push_back(data);
  } else if (n.ends_with(".mhd") || n.ends_with(".mha")) {
    const MetaHeader h = read_meta_header(path, name);
    if (h.data != path) files.push_back(h.data);
  }
  return files;
}

Eigen::Vector3d LabelMap::spacing_m() const {
  return {ijk_to_lps.block<3, 1>(0, 0).norm(), ijk_to_lps.block<3, 1>(0, 1).norm(),
          ijk_to_lps.block<3, 1>(0, 2).norm()};
}

double LabelMap::voxel_volume_m3() const { return std::abs(ijk_to_lps.block<3, 3>(0, 0).determinant()); }

namespace {

std::atomic<std::size_t> reads{0};

LabelMap read_map(const fs::path& path, const LabelMapOptions& options) {
  const std::string name = path.string();
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    if (detail::holds_dicom(path)) return detail::read_dicom_structures(path);
    return read_mask_folder(path, name, options);
  }
  require_readable_file(path);
  const std::string n = lower(name);
  LabelMap map;
  if (ends_with(n, ".nii") || ends_with(n, ".nii.gz")) {
    map = read_nifti(path, name, options);
  } else if (ends_with(n, ".nrrd") || ends_with(n, ".nhdr")) {
    map = read_itk_map(path, name, detail::ImageFormat::nrrd);
  } else if (ends_with(n, ".mha") || ends_with(n, ".mhd")) {
    map = read_itk_map(path, name, detail::ImageFormat::meta);
  } else {
    throw InputError(name + ": " + kFormats);
  }
  if (!map.ijk_to_lps.allFinite() || !(map.voxel_volume_m3() > 0.0)) {
    throw InputError(name + ": the " + map.transform_source +
                     " is singular or not finite: expected voxel axes of positive length");
  }
  if (options.names == SegmentNames::totalsegmentator || options.names == SegmentNames::totalsegmentator_v1) {
    const int version = options.names == SegmentNames::totalsegmentator ? 2 : 1;
    map.segments = detail::segments_of_present_labels(totalsegmentator_classes(version), map.labels);
  }
  return map;
}

}  // namespace

std::size_t label_map_reads() { return reads.load(); }

LabelMap read_label_map(const fs::path& path, const LabelMapOptions& options) {
  LabelMap map = read_map(path, options);
  ++reads;
  return map;
}

ScalarImage read_scalar_image(const fs::path& path, const ScalarImageOptions& options) {
  const std::string name = path.string();
  std::error_code ec;
  if (fs::is_directory(path, ec)) return detail::read_dicom_series(path, options.series_instance_uid);
  require_readable_file(path);
  const std::string n = lower(name);
  ScalarImage out;
  if (ends_with(n, ".nii") || ends_with(n, ".nii.gz")) {
    NiftiVoxels read = read_nifti_voxels(path, name, detail::VoxelKind::reals);
    out.size = read.image.size;
    out.values = std::move(read.image.reals);
    out.ijk_to_lps = nifti_ijk_to_lps(read.header, out.transform_source);
  } else if (ends_with(n, ".nrrd") || ends_with(n, ".nhdr") || ends_with(n, ".mha") || ends_with(n, ".mhd")) {
    const bool nrrd = ends_with(n, ".nrrd") || ends_with(n, ".nhdr");
    detail::ItkImage image = read_itk_voxels(path, name, nrrd ? detail::ImageFormat::nrrd : detail::ImageFormat::meta,
                                             detail::VoxelKind::reals);
    if (image.components != 1) {
      throw InputError(name + ": " + std::to_string(image.components) +
                       " values per voxel: expected a scalar image (one number per voxel)");
    }
    out.size = image.size;
    out.values = std::move(image.reals);
    out.ijk_to_lps = image.ijk_to_lps;
    out.transform_source = nrrd ? "space directions" : "TransformMatrix";
  } else {
    throw InputError(name + ": expected an image: .nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd or a DICOM series folder");
  }
  if (!out.ijk_to_lps.allFinite() || !(std::abs(out.ijk_to_lps.block<3, 3>(0, 0).determinant()) > 0.0)) {
    throw InputError(name + ": the " + out.transform_source +
                     " is singular or not finite: expected voxel axes of positive length");
  }
  return out;
}

}  // namespace pneuma::image
