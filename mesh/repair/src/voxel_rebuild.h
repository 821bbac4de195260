#pragma once
// The last resort of repair(): a closed surface whose topology cannot be mended face by face
// (non-manifold edges or vertices, non-orientable, handles) is rebuilt from its inside. The
// inside is found on a voxel grid by even-odd ray parity along x, which needs neither
// manifoldness nor orientation, only that every ray crosses the surface an even number of times
// (a closed surface); then the label-map pipeline (labels.h: closing, tunnel filling, smoothing,
// CGAL Mesh_3, genus check) makes a closed, manifold, genus-0 surface of it.
#include <cstddef>
#include <string>

#include "pneuma/mesh/geometry/triangle_mesh.h"
#include "pneuma/mesh/labels/labels.h"

namespace pneuma::mesh::detail {

struct VoxelRebuild {
  TriangleMesh mesh;          // empty when the inside could not be found (see odd_rows)
  LabelSurfaceReport report;  // how the surface was made from the voxels
  double voxel_m = 0.0;
  double edge_m = 0.0;       // facet size of the rebuilt surface
  std::size_t rows = 0;      // grid rows along x that meet the surface
  std::size_t odd_rows = 0;  // of those, rows crossing it an odd number of times (a hole)
};

// The grid: `edge_m` / 2 voxels (coarsened to at most ~40 M voxels), rows offset by a small
// irrational fraction of a voxel so no ray runs exactly through a vertex or an edge of a surface
// aligned with the grid. Deterministic. Rows with an odd number of crossings are left empty;
// more than 1 % of them leave `mesh` empty (the surface is open: not rebuilt).
VoxelRebuild rebuild_through_voxels(const TriangleMesh& mesh, const std::string& name, double edge_m);

// rebuild_through_voxels() for each vertex-connected component on its own (the pipeline keeps
// one component, and a file may hold two lungs), all of them or only those with handles
// (genus > 0 by the Euler characteristic); the others are kept as they are.
struct ComponentsRebuild {
  TriangleMesh mesh;  // every component, rebuilt or kept, in input order
  std::size_t components = 0, rebuilt = 0;
  int genus_before = 0, genus_after = 0;                 // summed over the rebuilt components
  double voxel_m = 0.0, edge_m = 0.0;                    // of the last rebuild
  double volume_before_m3 = 0.0, volume_after_m3 = 0.0;  // of the rebuilt components (|signed|)
  bool open = false;                                     // a component to rebuild is not closed: nothing was rebuilt
};
ComponentsRebuild rebuild_components(const TriangleMesh& mesh, const std::string& name, double edge_m,
                                     bool only_with_handles);

// The facet size a rebuild uses when the caller has none: the mean edge of the surface, at most
// 1/32 of its bounding-box diagonal (so a small surface still spans many voxels).
double rebuild_edge_for(const TriangleMesh& mesh);

}  // namespace pneuma::mesh::detail
