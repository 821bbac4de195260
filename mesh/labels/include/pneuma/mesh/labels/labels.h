#pragma once
// Lung surfaces from segmented CT: a label map in, one closed, manifold, genus-0, smooth
// triangle surface of the union of some labels out, in DICOM LPS metres (the frame of the rest
// of pneuma), overlaying the CT it was segmented from.
//
// Reading (labels_read.cpp; ITK 5.2 in labels_itk.cpp only), by the name's ending:
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
//   a folder         TotalSegmentator's masks (lung_upper_lobe_left.nii.gz, ...): the files
//                    named in LabelMapOptions::masks (the five lung lobes) on one grid, each a
//                    segment named by its file stem, label value its TotalSegmentator v2 class.
// Voxels may be of any integer type, or floating point holding integers. Sizes are checked
// against the file (also inside gzip and zlib streams) before anything is allocated.
// Extraction (labels.cpp, plain C++, then labels_cgal.cpp, CGAL Mesh_3), each step reported:
//   1. mask: the voxels whose label is one of `labels` (each must be present);
//   2. islands: only the largest 26-connected component is kept;
//   3. handles and gaps: morphological closing with a ball of `closing_radius_m` (exact
//      Euclidean distance transforms, anisotropic voxels), which closes the gaps between lobes
//      and the narrow tunnels of real segmentations;
//   4. cavities: background not connected to the outside (6-connected) is filled;
//   5. smoothing: the mask is blurred with a Gaussian of `smoothing_m` (sigma) and the surface
//      is the 0.5 level set of the trilinear interpolation of the blurred mask;
//   6. meshing: CGAL Mesh_3 (Delaunay refinement of the implicit surface, facet criteria:
//      angle >= 30 degrees, size `edge_length_m`, distance to the level set `max_distance_m`,
//      manifold topology), then the largest surface component, oriented outward;
//   7. genus: checked by the Euler characteristic; while it is above 0, steps 3-6 are redone,
//      first with tunnels filled (background enclosed within a slice across x, y or z, which is
//      how a tunnel shows), then with the closing radius doubled up to `max_closing_radius_m`.
//      A genus still above 0 is reported (LabelSurfaceReport::genus), not an error.
// Deterministic: the same file and options give the same triangles, bit for bit.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh {

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

// The label values of a selection, in its order without repeats: each entry a segment name of
// `map` ("lung_upper_lobe_left") or a label number ("3"). Throws ValueError naming `name` (the
// file): `"x" is not a segment of lobes.seg.nrrd (segments: lung_upper_lobe_left = 1, ...)`,
// `label 7 is not in lobes.nii.gz (labels present: 0, 1, 2)`, or a segment without voxels.
std::vector<int> resolve_labels(const LabelMap& map, const std::string& name,
                                const std::vector<std::string>& selection);

struct LabelSurfaceOptions {
  double edge_length_m = 2e-3;         // target facet size
  double max_distance_m = 0.0;         // facet to level set; 0: edge_length_m / 8
  double smoothing_m = 1.0e-3;         // Gaussian sigma of the mask; 0: none
  double closing_radius_m = 1.5e-3;    // morphological closing; 0: none
  double max_closing_radius_m = 6e-3;  // closing grows (doubling) up to this to reach genus 0
  bool keep_largest_component = true;
  bool fill_cavities = true;
  bool remove_handles = true;  // step 7; false: report the genus and keep the surface
};

// What was done, with the figures `pneuma mesh from-labels` prints and records.
struct LabelSurfaceReport {
  std::string source;  // the file name
  std::vector<int> labels;
  std::string transform_source;  // "qform", ...
  std::array<std::size_t, 3> size{0, 0, 0};
  Eigen::Vector3d spacing_m = Eigen::Vector3d::Zero();
  std::size_t label_voxels = 0;  // voxels of the union of the labels
  double voxel_volume_m3 = 0.0;
  std::size_t dropped_islands = 0, dropped_island_voxels = 0;
  double closing_radius_m = 0.0;  // the radius finally used
  std::size_t closing_added_voxels = 0;
  bool filled_slice_holes = false;  // tunnels filled slice by slice (second attempt on)
  std::size_t slice_hole_voxels = 0;
  std::size_t filled_cavities = 0, filled_cavity_voxels = 0;
  std::size_t mask_voxels = 0;  // after islands, closing and cavities
  double smoothing_m = 0.0, edge_length_m = 0.0, max_distance_m = 0.0;
  std::size_t dropped_surface_components = 0;
  int genus = 0;
  int attempts = 1;        // meshing runs (more when closing grew to reach genus 0)
  double volume_m3 = 0.0;  // enclosed by the surface
  double area_m2 = 0.0;

  double label_volume_m3() const { return static_cast<double>(label_voxels) * voxel_volume_m3; }
  // One line per step, in order ("islands: dropped 3 (120 voxels, 0.05 mL)").
  std::vector<std::string> steps() const;
  // A few "key: value" lines recording how the surface was made (the provenance file).
  std::string provenance() const;
};

struct LabelSurface {
  TriangleMesh mesh;  // metres, LPS, outward, vertices numbered by first use
  LabelSurfaceReport report;
};

// Refuses, before any work, an extraction that cannot finish: a smoothing or closing that reaches
// beyond the whole map (sigma 1e308 mm), or a facet size that would give the labels' surface over
// kMaxSurfaceVertices (its area estimated as 1.5 times a sphere's of their volume). Throws
// ValueError "<name>: smoothing|closing|edge: ..." with the numbers.
void check_label_surface_size(const LabelMap& map, const std::string& name, const std::vector<int>& labels,
                              const LabelSurfaceOptions& options);

// Throws InputError "<file>: ..." for a file that is not a label map, a label that is absent
// ("label 7 is not in the file (labels present: 0, 1, 2)"), and IoError as read_label_map().
LabelSurface surface_from_labels(const std::filesystem::path& path, const std::vector<int>& labels,
                                 const LabelSurfaceOptions& options = {});
// The same on a map already read; `name` starts every message.
LabelSurface surface_from_labels(const LabelMap& map, const std::string& name, const std::vector<int>& labels,
                                 const LabelSurfaceOptions& options = {});

// The file beside a mesh that records how it was made ("right.stl" -> "right.stl.provenance.txt").
std::filesystem::path provenance_path(const std::filesystem::path& mesh_path);

namespace detail {
// A float field on the crop of a label map, and the map from LPS metres to its index space.
struct ScalarGrid {
  std::array<std::size_t, 3> size{0, 0, 0};
  std::vector<float> values;  // i fastest
  Eigen::Matrix4d lps_to_index = Eigen::Matrix4d::Identity();
  Eigen::Matrix4d index_to_lps = Eigen::Matrix4d::Identity();
};
// The 0.5 level set of the trilinear field (values > 0.5 inside), meshed by CGAL Mesh_3 in
// labels_cgal.cpp. Returns a soup-free TriangleMesh (every component Mesh_3 found).
TriangleMesh mesh_level_set(const ScalarGrid& grid, double edge_length_m, double max_distance_m);
}  // namespace detail

}  // namespace pneuma::mesh
