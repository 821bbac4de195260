#pragma once
// NRRD (.nrrd, .seg.nrrd) and MetaImage (.mha) label maps written byte by byte from the formats'
// specifications (teem's NRRD format page, 3D Slicer's segmentation header keys, MetaIO's
// MetaImage keys), independently of ITK: the test's files for the label-map reader.
#include <zlib.h>

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace pneuma::mesh::test {

inline std::string zlib_bytes(const std::string& raw, bool gzip_wrapper) {
  z_stream z{};
  if (deflateInit2(&z, 6, Z_DEFLATED, gzip_wrapper ? 15 + 16 : 15, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
    throw std::runtime_error("deflateInit2");
  }
  std::string out(deflateBound(&z, static_cast<uLong>(raw.size())) + 64, '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(raw.data()));
  z.avail_in = static_cast<uInt>(raw.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(out.size());
  if (deflate(&z, Z_FINISH) != Z_STREAM_END) throw std::runtime_error("deflate");
  out.resize(z.total_out);
  deflateEnd(&z);
  return out;
}

inline std::string number(double v) {
  char text[40];
  std::snprintf(text, sizeof text, "%.17g", v);
  return text;
}

template <typename T>
std::string raw_bytes(const std::vector<T>& values) {
  return std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
}

inline void write_bytes(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// NRRD header lines for a 3D grid (LPS millimetres from an ijk -> LPS metres matrix).
inline std::string nrrd_geometry(const Eigen::Matrix4d& ijk_to_lps, bool list_axis) {
  std::string h = "space: left-posterior-superior\nspace directions:";
  if (list_axis) h += " none";
  for (int c = 0; c < 3; ++c) {
    h += " (" + number(ijk_to_lps(0, c) * 1e3) + "," + number(ijk_to_lps(1, c) * 1e3) + "," +
         number(ijk_to_lps(2, c) * 1e3) + ")";
  }
  h += "\nspace origin: (" + number(ijk_to_lps(0, 3) * 1e3) + "," + number(ijk_to_lps(1, 3) * 1e3) + "," +
       number(ijk_to_lps(2, 3) * 1e3) + ")\n";
  return h;
}

struct NrrdOptions {
  bool gzip = false;
  std::size_t layers = 1;     // > 1: a 4D .seg.nrrd, the layer axis first (kind "list")
  std::string extra_lines{};  // "key:=value" lines (Slicer's segments)
};

// int16 labels, i fastest (layer fastest of all when layers > 1).
inline void write_nrrd(const std::filesystem::path& path, const std::array<std::size_t, 3>& size,
                       const std::vector<std::int16_t>& labels, const Eigen::Matrix4d& ijk_to_lps,
                       const NrrdOptions& options = {}) {
  const bool list = options.layers > 1;
  std::string h = "NRRD0004\n# written by pneuma's tests\ntype: short\n";
  h += list ? "dimension: 4\nsizes: " + std::to_string(options.layers) + " " : "dimension: 3\nsizes: ";
  h += std::to_string(size[0]) + " " + std::to_string(size[1]) + " " + std::to_string(size[2]) + "\n";
  h += nrrd_geometry(ijk_to_lps, list);
  h += list ? "kinds: list domain domain domain\n" : "kinds: domain domain domain\n";
  h += "endian: little\nencoding: " + std::string(options.gzip ? "gzip" : "raw") + "\n";
  h += options.extra_lines + "\n";
  const std::string data = raw_bytes(labels);
  write_bytes(path, h + (options.gzip ? zlib_bytes(data, true) : data));
}

// A MetaImage (.mha, data after the header) of `element_type` values (MET_SHORT, MET_FLOAT, ...).
inline void write_mha(const std::filesystem::path& path, const std::array<std::size_t, 3>& size,
                      const std::string& data, const std::string& element_type, const Eigen::Matrix4d& ijk_to_lps,
                      bool compressed = false) {
  Eigen::Vector3d spacing;
  for (int c = 0; c < 3; ++c) spacing[c] = ijk_to_lps.block<3, 1>(0, c).norm();
  std::string h = "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n";
  const std::string stored = compressed ? zlib_bytes(data, false) : data;
  // Appended piece by piece (GCC 12 warns, wrongly, on `"text" + std::string&&` here).
  auto line = [&h](const std::string& key, const std::vector<double>& values) {
    h.append(key).append(" =");
    for (double v : values) h.append(" ").append(number(v));
    h.append("\n");
  };
  h.append("CompressedData = ").append(compressed ? "True" : "False").append("\n");
  if (compressed) line("CompressedDataSize", {static_cast<double>(stored.size())});
  std::vector<double> matrix;  // MetaIO's matrix: row c holds the direction of axis c
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) matrix.push_back(ijk_to_lps(r, c) / spacing[c]);
  line("TransformMatrix", matrix);
  line("Offset", {ijk_to_lps(0, 3) * 1e3, ijk_to_lps(1, 3) * 1e3, ijk_to_lps(2, 3) * 1e3});
  h.append("AnatomicalOrientation = RAI\n");
  line("ElementSpacing", {spacing[0] * 1e3, spacing[1] * 1e3, spacing[2] * 1e3});
  h += "DimSize = " + std::to_string(size[0]) + " " + std::to_string(size[1]) + " " + std::to_string(size[2]) + "\n";
  h += "ElementType = " + element_type + "\nElementDataFile = LOCAL\n";
  write_bytes(path, h + stored);
}

}  // namespace pneuma::mesh::test
