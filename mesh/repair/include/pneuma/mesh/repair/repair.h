#pragma once
// Repair of what can be repaired safely, and a clear refusal of the rest.
//
// Repaired, in this order and each reported: vertices at identical positions (merged), faces
// with a repeated vertex (removed), duplicated faces (the first is kept), self-intersections
// (the faces of every intersecting pair and one ring of neighbours removed, the holes refilled
// below; a refill that still intersects is redone with a wider ring, up to
// `max_self_intersection_rounds`), small components (islands under `min_component_fraction` of
// the largest component's area: dropped), faces oriented against their neighbours (flipped),
// borders that coincide (stitched), zero-area faces (collapsed), holes of at most
// `max_hole_edges` boundary edges (CGAL triangulate_refine_and_fair_hole), closed components
// that enclose a negative volume (reversed), unused vertices (dropped).
// Rebuilt from the inside (rebuild_through_voxels): what no face-by-face repair mends, when
// the surface is closed: non-manifold edges and vertices and non-orientable surfaces (every
// component), and handles (genus > 0: only the components that have them; a lung has none).
// The inside is found on a voxel grid of half the surface's mean edge by ray parity and meshed
// again by the label-map pipeline (closing, tunnel filling, one-voxel smoothing, CGAL Mesh_3);
// the report gives the grid, the facet size and the volume before and after. A handle is
// removed only when that changes the enclosed volume by at most `max_handle_volume_change`
// (a narrow bridge or tunnel of a segmentation); wider ones are kept and reported.
// Refused (InputError "<name>: cannot repair: <problem and where> (<a command that works>)"):
// non-manifold or non-orientable surfaces that are also open, larger holes, and
// self-intersections that survive the rounds (repair_and_remesh() may still remove them);
// the indices refer to the input mesh.
#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "pneuma/mesh/geometry/triangle_mesh.h"
#include "pneuma/mesh/geometry/validate.h"
#include "pneuma/mesh/repair/remesh.h"

namespace pneuma::mesh {

struct RepairOptions {
  std::size_t max_hole_edges = 64;
  bool remove_self_intersections = true;
  int max_self_intersection_rounds = 3;
  double min_component_fraction = 0.01;  // 0: keep every component
  bool rebuild_through_voxels = true;    // false: refuse non-manifold/non-orientable, keep handles
  double max_handle_volume_change = 0.05;
};

struct RepairReport {
  std::size_t merged_vertices = 0;
  std::size_t removed_degenerate_faces = 0;
  std::size_t removed_duplicated_faces = 0;
  std::size_t flipped_faces = 0;
  std::size_t stitched_edges = 0;
  std::size_t filled_holes = 0;
  std::size_t added_faces = 0;
  std::size_t reversed_components = 0;
  std::size_t dropped_vertices = 0;
  std::size_t self_intersecting_pairs = 0;  // in the input
  std::array<std::size_t, 2> first_intersecting_faces{0, 0};
  std::size_t removed_intersecting_faces = 0;  // the pairs and the rings around them, all rounds
  int rounds = 0;
  std::size_t dropped_components = 0, dropped_component_faces = 0;
  double dropped_component_area_m2 = 0.0;
  double min_component_fraction = 0.0;
  std::size_t rebuilt_components = 0;  // rebuilt through a voxel grid, because of `rebuilt_for`
  std::string rebuilt_for;             // the validator's words ("non-manifold edge 0-1 ...", "2 handles")
  double rebuilt_voxel_m = 0.0, rebuilt_edge_m = 0.0;
  double rebuilt_volume_before_m3 = 0.0, rebuilt_volume_after_m3 = 0.0;
  int handles_removed = 0, handles_kept = 0;  // genus removed by the rebuild; left (too wide)
  std::string handles_kept_because;           // why they were left
  double remeshed_edge_m = 0.0;               // repair_and_remesh(): remeshing removed what repair left
  std::string left_for_remeshing;             // what that was (the validator's words)
  // One line per action taken ("flipped 1 face to match its neighbours"); empty: nothing to do.
  std::vector<std::string> actions() const;
};

struct RepairResult {
  TriangleMesh mesh;  // closed, manifold, outward oriented, vertices numbered by first use
  RepairReport report;
};

// `name` (usually the file name) starts every error message.
RepairResult repair(const TriangleMesh& mesh, const std::string& name, const RepairOptions& options = {});

// The repairs without the verdict: the result may still have problems, which `after` (when
// given) receives. Throws only for what it refuses to touch (non-manifold, non-orientable).
RepairResult repair_unchecked(const TriangleMesh& mesh, const std::string& name, const RepairOptions& options,
                              ValidationReport* after);

// Repair, then isotropic remeshing, then the verdict: what repair leaves (self-intersections of
// slivers that refilling did not cure) may be removed by the remeshing. This is the scenario
// runner's entry point for a file with a remeshing target (`mesh: {file, edge}`). Throws
// InputError "<name>: cannot repair: ..." when the remeshed surface is still not valid.
struct RepairRemeshResult {
  RepairReport repair;  // remeshed_edge_m > 0 when the remeshing removed a remaining defect
  RemeshResult remesh;  // remesh.mesh: the valid result
};
RepairRemeshResult repair_and_remesh(const TriangleMesh& mesh, const std::string& name,
                                     const RepairOptions& repair_options, const RemeshOptions& remesh_options);

// The repaired mesh alone (the runner's entry point); throws as repair() does.
inline TriangleMesh repair_or_throw(const TriangleMesh& mesh, const std::string& name,
                                    const RepairOptions& options = {}) {
  return repair(mesh, name, options).mesh;
}

}  // namespace pneuma::mesh
