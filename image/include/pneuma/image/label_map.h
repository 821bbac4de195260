#pragma once
// Label maps: segmented CT as labelled voxels with their geometry, in DICOM LPS metres (the frame
// of the rest of pneuma), overlaying the CT they were segmented from.
//
// Reading (read.cpp; ITK 5.2 in itk_read.cpp only), by the name's ending:
//   .nii, .nii.gz    NIfTI-1 or NIfTI-2. The voxel-to-world transform is pneuma's rule, read from
//                    the header's own bytes (ITK keeps no shear and chooses otherwise in some
//                    files): the sform when sform_code > 0, else the qform when qform_code > 0,
//                    else the pixdim scaling alone (NIfTI's "method 1"); NIfTI's world is RAS+,
//                    so LPS = (-x, -y, z). TotalSegmentator's label table (a CaretExtension in the
//                    header extension) names the segments.
//   .nrrd, .nhdr     NRRD (ITK turns a right-anterior space into LPS). 3D Slicer's .seg.nrrd
//                    names its segments (SegmentN_Name, _LabelValue, _Layer); several layers
//                    are flattened into one when they do not overlap.
//   .mha, .mhd       MetaImage (LPS by convention).
//   a DICOM folder   a CT series and one RT Structure Set on it (src/dicom_read.cpp, DCMTK): ROI n is
//                    label n, named by its ROIName, each CLOSED_PLANAR contour filled on its slice
//                    of the CT's grid; a voxel in several ROIs takes the smallest (docs/formats.md).
//   a folder         TotalSegmentator's masks (lung_upper_lobe_left.nii.gz, ...): the files
//                    named in LabelMapOptions::masks (the five lung lobes) on one grid, each a
//                    segment named by its file stem, label value its TotalSegmentator v2 class.
// Voxels may be of any integer type, or floating point holding integers. Sizes are checked
// against the file (also inside gzip and zlib streams) before anything is allocated.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace pneuma::image {

// A label value with its name ("lung_upper_lobe_left" = 10).
struct Segment {
  std::string name;
  std::int32_t label = 0;
};

// A label volume with its geometry. Voxel (i, j, k) is labels[i + nx * (j + ny * k)] and its
// centre is at ijk_to_lps * (i, j, k, 1), in metres, LPS.
struct LabelMap {
  std::array<std::size_t, 3> size{0, 0, 0};
  Eigen::Matrix4d ijk_to_lps = Eigen::Matrix4d::Identity();
  std::vector<std::int32_t> labels;
  // "sform", "qform" or "pixdim" (NIfTI), "space directions" (NRRD), "TransformMatrix" (MetaImage)
  std::string transform_source;
  // Named label values, in the file's order: a .seg.nrrd's segments, TotalSegmentator's label
  // table or class map, a mask folder's file stems. Empty when the file names none.
  std::vector<Segment> segments;

  std::size_t voxel_count() const { return size[0] * size[1] * size[2]; }
  // Lengths of the voxel edges along i, j, k (metres).
  Eigen::Vector3d spacing_m() const;
  double voxel_volume_m3() const;
};

// The label values and names TotalSegmentator gives its task "total": version 2 (117 classes;
// lungs 10-14) or 1 (104 classes; lungs 13-17), from class_map in its map_to_binary.py.
// Throws ValueError for another version.
std::vector<Segment> totalsegmentator_classes(int version = 2);
// {"lung_upper_lobe_left", "lung_lower_lobe_left", "lung_upper_lobe_right",
//  "lung_middle_lobe_right", "lung_lower_lobe_right"}
std::vector<std::string> totalsegmentator_lung_lobes();

enum class SegmentNames {
  from_file,            // what the file says (seg.nrrd header, NIfTI label table, mask file names)
  totalsegmentator,     // TotalSegmentator v2's class map, for a multilabel file without its table
  totalsegmentator_v1,  // the same, version 1's numbers
};

struct LabelMapOptions {
  SegmentNames names = SegmentNames::from_file;
  // The masks read from a folder (file stems, .nii.gz or .nii); other files there are ignored.
  std::vector<std::string> masks = totalsegmentator_lung_lobes();
};

// Throws IoError when the file cannot be opened and InputError ("<file>: <what was expected>")
// when it is not a label map of a known format, is truncated (also inside a gzip or zlib
// stream), has more than three dimensions with data, holds non-integral labels, has overlapping
// .seg.nrrd layers, or (a folder) masks on different grids, overlapping masks or none at all.
LabelMap read_label_map(const std::filesystem::path& path, const LabelMapOptions& options = {});

// What a label map at `path` is read from, in a fixed order: a detached header (.nhdr, .mhd)
// with its data files, else the file itself, or the folder (a mask folder, a DICOM series with
// its RTSTRUCT) whose files a digest must then cover by name and bytes (model's source_key). What
// a field cache's key covers: it is stale when any of them changes. Throws as read_label_map does
// for a header that names its data files wrongly.
std::vector<std::filesystem::path> label_map_files(const std::filesystem::path& path);

// How many label maps this process has read (read_label_map calls that returned a map; a mask
// folder counts once): a run reads its label map once, and the tests hold it to that.
std::size_t label_map_reads();

// The label values of a selection, in its order without repeats: each entry a segment name of
// `map` ("lung_upper_lobe_left") or a label number ("3"). Throws ValueError naming `name` (the
// file): `"x" is not a segment of lobes.seg.nrrd (segments: lung_upper_lobe_left = 1, ...)`,
// `label 7 is not in lobes.nii.gz (labels present: 0, 1, 2)`, or a segment without voxels.
std::vector<int> resolve_labels(const LabelMap& map, const std::string& name,
                                const std::vector<std::string>& selection);

}  // namespace pneuma::image
