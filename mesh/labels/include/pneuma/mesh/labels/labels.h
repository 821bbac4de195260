#pragma once
// Lung surfaces from segmented CT: a label map (pneuma/image/label_map.h) in, one closed, manifold, genus-0, smooth
// triangle surface of the union of some labels out, in DICOM LPS metres (the frame of the rest
// of pneuma), overlaying the CT it was segmented from.
//
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
//   7. genus: checked by the Euler characteristic, first on the blurred mask's samples (a handle
//      seen there skips the meshing: it would be thrown away), then on the surface; while it is
//      above 0, steps 3-6 are redone,
//      first with tunnels filled (background enclosed within a slice across x, y or z, which is
//      how a tunnel shows) but the dents from below left open (the holes of the axial slices,
//      taken as 3D regions, that open towards the feet and are closed above: the underside of
//      the diaphragm's dome, which the body fills, not the lung; one spanning fewer slices than
//      twice `smoothing_m` is filled, the blur all but closes it), then with those filled too where
//      a handle remains, then the same with the closing radius doubled up to
//      `max_closing_radius_m`.
//      A genus still above 0 is reported (LabelSurfaceReport::genus), not an error.
// Deterministic: the same file and options give the same triangles, bit for bit.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "pneuma/mesh/geometry/triangle_mesh.h"

#include "pneuma/image/label_map.h"

namespace pneuma::mesh {

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
  // Holes of the slices across the axis nearest LPS z whose 3D region opens downwards and is
  // closed above (the dome's underside): left to the body, not filled, and not in the mask.
  std::size_t dents_left = 0, dent_voxels_left = 0;
  std::size_t filled_cavities = 0, filled_cavity_voxels = 0;
  std::size_t mask_voxels = 0;  // after islands, closing and cavities
  double smoothing_m = 0.0, edge_length_m = 0.0, max_distance_m = 0.0;
  std::size_t dropped_surface_components = 0;
  int genus = 0;
  int attempts = 1;        // masks made (more when closing grew to reach genus 0)
  int meshings = 1;        // Mesh_3 runs: attempts less those whose mask showed a handle on its samples
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
void check_label_surface_size(const image::LabelMap& map, const std::string& name, const std::vector<int>& labels,
                              const LabelSurfaceOptions& options);

// Throws InputError "<file>: ..." for a file that is not a label map, a label that is absent
// ("label 7 is not in the file (labels present: 0, 1, 2)"), and IoError as image::read_label_map().
LabelSurface surface_from_labels(const std::filesystem::path& path, const std::vector<int>& labels,
                                 const LabelSurfaceOptions& options = {});
// The same on a map already read; `name` starts every message.
LabelSurface surface_from_labels(const image::LabelMap& map, const std::string& name, const std::vector<int>& labels,
                                 const LabelSurfaceOptions& options = {});

// The facet size a lung is meshed at from a label map before it is remeshed to `target_edge_m`
// (a run's `mesh.edge`): the target itself up to 4 mm; 2 mm for a coarser target or none. Mesh_3's
// cost falls with the square of the facet size, and at 4 mm the remeshed surface lies within the
// remeshing's own deviation of the one meshed at 2 mm (BENCHMARKS.md, "The shipped 4D scenario").
double extraction_edge_m(double target_edge_m);

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
// The Euler characteristic (V - E + F - C) of the samples above 0.5, the last sample of each
// axis and all outside the grid read as background (as mesh_level_set() reads them), in the two
// cubical models between which the trilinear level set lies: `thin`, the grid cells whose
// corners are all inside (6-connected); `thick`, the union of the inside samples' voxel cubes
// (26-connected). For one solid without cavities either is 1 - its handles; islands and
// cavities add 1 each. Where the two differ, a sample pair touching only diagonally decides.
struct LevelSetEuler {
  long long thin = 0, thick = 0;
};
LevelSetEuler level_set_euler_characteristics(const ScalarGrid& grid);  // level_set_topology.cpp
// The mask steps of surface_from_labels on a 0/1 mask of `size` voxels (i fastest), for their
// tests. The closing with a ball of `radius_m` in voxels of `spacing_m` (only voxels of the grid
// count); returns the voxels added.
std::size_t close_mask(const std::array<std::size_t, 3>& size, std::vector<std::uint8_t>& mask,
                       const Eigen::Vector3d& spacing_m, double radius_m);
// The largest 26-connected component kept (on a tie the one with the lowest first voxel);
// returns {components dropped, voxels dropped}.
std::pair<std::size_t, std::size_t> keep_largest_component(const std::array<std::size_t, 3>& size,
                                                           std::vector<std::uint8_t>& mask);
// Background not 6-connected to the grid's border filled; returns {cavities, voxels filled}.
std::pair<std::size_t, std::size_t> fill_cavities(const std::array<std::size_t, 3>& size,
                                                  std::vector<std::uint8_t>& mask);
}  // namespace detail

}  // namespace pneuma::mesh
