#pragma once
// NIfTI-1 files written and read byte by byte, independently of niftilib: the oracle for the
// label-map reader (header layout and qform formula from the NIfTI-1 standard, nifti1.h).
#include <zlib.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace pneuma::mesh::test {

struct Qform {
  double b = 0.0, c = 0.0, d = 0.0;                  // quaternion (a = sqrt(1 - b^2 - c^2 - d^2))
  double qfac = 1.0;                                 // pixdim[0]: -1 flips k
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();  // mm, RAS
  Eigen::Vector3d spacing{1.0, 1.0, 1.0};            // mm
};

// Voxel (i, j, k) -> LPS metres, by the standard's method 2 and RAS -> LPS.
inline Eigen::Matrix4d qform_ijk_to_lps(const Qform& q) {
  const double a = std::sqrt(std::max(0.0, 1.0 - q.b * q.b - q.c * q.c - q.d * q.d));
  const double b = q.b, c = q.c, d = q.d;
  Eigen::Matrix3d R;
  R << a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c),  //
      2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b),   //
      2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - c * c - b * b;
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.block<3, 3>(0, 0) = R * Eigen::Vector3d(q.spacing.x(), q.spacing.y(), q.qfac * q.spacing.z()).asDiagonal();
  m.block<3, 1>(0, 3) = q.offset;
  m.topRows(3) *= 1e-3;
  m.row(0) *= -1.0;
  m.row(1) *= -1.0;
  return m;
}

// What a NIfTI-1 file may carry besides the qform.
struct NiftiExtras {
  bool has_sform = false;
  std::array<std::array<float, 4>, 3> srow{};  // sform rows, mm RAS (sform_code 1 when has_sform)
  std::string extension{};                     // one header extension of code 0 (TotalSegmentator's label table)
};

// A single-file NIfTI-1 (.nii, or gzip-compressed when the name ends in .gz) of int16 labels.
inline void write_nifti(const std::filesystem::path& path, const std::array<int, 3>& size,
                        const std::vector<std::int16_t>& labels, const Qform& q, const NiftiExtras& extras = {}) {
  std::string bytes(352, '\0');
  auto put = [&](std::size_t at, auto value) { std::memcpy(bytes.data() + at, &value, sizeof value); };
  put(0, std::int32_t{348});
  const std::int16_t dim[8] = {3,
                               static_cast<std::int16_t>(size[0]),
                               static_cast<std::int16_t>(size[1]),
                               static_cast<std::int16_t>(size[2]),
                               1,
                               1,
                               1,
                               1};
  for (int i = 0; i < 8; ++i) put(40 + 2 * static_cast<std::size_t>(i), dim[i]);
  put(70, std::int16_t{4});   // DT_INT16
  put(72, std::int16_t{16});  // bitpix
  const float pixdim[8] = {static_cast<float>(q.qfac),
                           static_cast<float>(q.spacing.x()),
                           static_cast<float>(q.spacing.y()),
                           static_cast<float>(q.spacing.z()),
                           1,
                           1,
                           1,
                           1};
  for (int i = 0; i < 8; ++i) put(76 + 4 * static_cast<std::size_t>(i), pixdim[i]);
  put(108, 352.0f);           // vox_offset
  put(112, 1.0f);             // scl_slope
  bytes[123] = 2;             // xyzt_units: mm
  put(252, std::int16_t{1});  // qform_code: scanner
  put(254, std::int16_t{0});  // sform_code: none
  put(256, static_cast<float>(q.b));
  put(260, static_cast<float>(q.c));
  put(264, static_cast<float>(q.d));
  put(268, static_cast<float>(q.offset.x()));
  put(272, static_cast<float>(q.offset.y()));
  put(276, static_cast<float>(q.offset.z()));
  if (extras.has_sform) {
    put(254, std::int16_t{1});
    for (std::size_t r = 0; r < 3; ++r)
      for (std::size_t c = 0; c < 4; ++c) put(280 + 16 * r + 4 * c, extras.srow[r][c]);
  }
  std::memcpy(bytes.data() + 344, "n+1\0", 4);
  if (!extras.extension.empty()) {
    const std::size_t esize = (extras.extension.size() + 8 + 15) / 16 * 16;
    bytes[348] = 1;  // extender: extensions follow
    std::string ext(esize, '\0');
    const auto size32 = static_cast<std::int32_t>(esize);
    std::memcpy(ext.data(), &size32, 4);  // esize; ecode 0 follows
    std::memcpy(ext.data() + 8, extras.extension.data(), extras.extension.size());
    bytes += ext;
    put(108, static_cast<float>(bytes.size()));  // vox_offset
  }
  bytes.append(reinterpret_cast<const char*>(labels.data()), labels.size() * sizeof(std::int16_t));
  if (path.extension() == ".gz") {
    gzFile f = gzopen(path.c_str(), "wb1");  // fastest: the tests write large crops
    if (f == nullptr) throw std::runtime_error("cannot write " + path.string());
    gzwrite(f, bytes.data(), static_cast<unsigned>(bytes.size()));
    gzclose(f);
  } else {
    std::ofstream(path, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
}

// The qform of a NIfTI-1 file (.nii or .nii.gz), read from the raw header bytes.
inline Qform read_raw_qform(const std::filesystem::path& path) {
  gzFile f = gzopen(path.c_str(), "rb");  // reads uncompressed files too
  if (f == nullptr) throw std::runtime_error("cannot read " + path.string());
  char h[348];
  const int got = gzread(f, h, sizeof h);
  gzclose(f);
  if (got != 348) throw std::runtime_error("short header in " + path.string());
  auto get = [&](std::size_t at) {
    float v;
    std::memcpy(&v, h + at, 4);
    return static_cast<double>(v);
  };
  Qform q;
  q.qfac = get(76) < 0 ? -1.0 : 1.0;
  q.spacing = {get(80), get(84), get(88)};
  q.b = get(256), q.c = get(260), q.d = get(264);
  q.offset = {get(268), get(272), get(276)};
  return q;
}

}  // namespace pneuma::mesh::test
