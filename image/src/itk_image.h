#pragma once
// Private to image/: the one door to ITK (itk_read.cpp, the only translation unit that
// includes ITK's headers; they are slow to compile). read.cpp decides the format, checks
// what ITK does not (the NIfTI header's transform rule, data that stops short in NIfTI and
// MetaImage files) and turns the result into a LabelMap.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "pneuma/image/label_map.h"

namespace pneuma::image::detail {

enum class ImageFormat { nifti, nrrd, meta };

// What the voxels must be: integer labels (converted to int32, anything else refused) or any
// numbers (an image such as a CT, converted to float).
enum class VoxelKind { labels, reals };

struct ItkImage {
  std::array<std::size_t, 3> size{0, 0, 0};
  std::size_t components = 1;  // values per voxel (the layers of a .seg.nrrd)
  std::size_t component_bytes = 0;
  std::string type_name;  // NIfTI's spelling: "UINT8", "INT16", "FLOAT32", ...
  // ITK's origin, spacing and direction (LPS millimetres) as one matrix in LPS metres.
  Eigen::Matrix4d ijk_to_lps = Eigen::Matrix4d::Identity();
  std::vector<std::int32_t> values;             // VoxelKind::labels: component fastest, then i, j, k
  std::vector<float> reals;                     // VoxelKind::reals: the same order
  std::map<std::string, std::string> metadata;  // the text entries of ITK's dictionary

  std::size_t voxel_count() const { return size[0] * size[1] * size[2]; }
  double data_bytes() const {
    return static_cast<double>(voxel_count()) * static_cast<double>(components * component_bytes);
  }
};

// Where the voxels are stored, as the caller found out from the file (ITK does not say).
struct StoredData {
  bool compressed = false;  // gzip or zlib: the bytes after decompression are compared
  bool exact = false;       // `bytes` counts the stored data exactly (else: the file holding it)
  double bytes = 0.0;
};

// The voxels' bytes as the file stores them, already in memory (a .nii.gz that read.cpp inflated
// once, its stream checked whole: #50), `swap` when their byte order is not this machine's, and
// `type_name` the file's own type (NIfTI's spelling). read_itk_image takes them in place of ITK's
// second read of the file when ITK's header gives that type and exactly that many bytes; the
// caller passes none when ITK would change the values as it reads them (a rescale).
struct VoxelBytes {
  std::span<const unsigned char> bytes;
  bool swap = false;
  std::string type_name;
};

// Reads the header, asks `stored` where the data is (with the header filled in, values empty),
// refuses sizes the file cannot hold before anything is allocated ("<file>: truncated or
// corrupt: expected 48 x 40 x 32 voxels of INT16 (122880 bytes of data)"), then reads the voxels
// and converts them to int32 ("<file>: voxel 7 holds 0.5: expected integer labels ...") or, for
// VoxelKind::reals, to float. Every ITK exception becomes one InputError line; nothing of ITK's
// text is passed on. Calls from several threads are safe (they take turns). With `in_memory`
// (above) the voxels are converted from those bytes, by the same rules and messages.
ItkImage read_itk_image(const std::filesystem::path& path, ImageFormat format,
                        const std::function<StoredData(const ItkImage&)>& stored, VoxelKind kind = VoxelKind::labels,
                        const VoxelBytes* in_memory = nullptr);

// "not a NRRD file: expected ...": what a file of `format` must begin with.
const char* format_expectation(ImageFormat format);

// "truncated or corrupt: expected 48 x 40 x 32 voxels of INT16 (122880 bytes of data after
// decompression)", shared by the checks on either side of ITK.
std::string truncated_message(const std::string& name, const std::array<std::size_t, 3>& size, std::size_t components,
                              const std::string& type_name, double data_bytes, bool compressed);

// read.cpp: the rules every format's header passes before its voxels are allocated. At most
// kMaxVoxelValues values (8 GiB as int32; a header alone claimed 7.5e9 voxels, #49):
// "<file>: 50000 x 50000 x 3 voxels: expected at most 2.14748e+09 voxel values".
constexpr double kMaxVoxelValues = 2147483648.0;
void check_voxel_count(const std::string& name, const std::array<std::size_t, 3>& size, std::size_t components);
// The voxel -> LPS transform (`source`: "sform", "space directions", "TransformMatrix", ...):
// finite numbers of magnitude at most 1e6 mm, voxels of at least 1 um along each axis, axes
// not in one plane. Each failure is one InputError line naming the file and `source`.
void check_grid(const std::string& name, const std::string& source, const Eigen::Matrix4d& ijk_to_lps);

// segments.cpp: the entries of `classes` whose label value occurs in `labels`; the
// label table of TotalSegmentator's NIfTI header extension (empty when the text holds none).
std::vector<Segment> segments_of_present_labels(const std::vector<Segment>& classes,
                                                const std::vector<std::int32_t>& labels);
std::vector<Segment> caret_label_table(const std::string& xml);

}  // namespace pneuma::image::detail
