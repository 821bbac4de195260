#pragma once
// The inside of a closed lung surface as tetrahedra (CGAL Mesh_3, Delaunay refinement of the
// polyhedral domain the surface bounds), for the interior field and the voxel outputs (#31).
#include <cstdint>
#include <vector>

#include "pneuma/mesh/geometry/tet_mesh.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh {

struct TetrahedralizeOptions {
  double edge_length_m = 3e-3;  // target size of cells and boundary facets (Mesh_3 cell_size, facet_size)
  double max_distance_m = 0.0;  // boundary facet to the surface; 0: edge_length_m / 10
  // Mesh_3's sliver exudation until every dihedral angle reaches this bound (degrees) or no
  // exchange improves it; 0: none. Flat tets make poorly conditioned gradients (the Jacobian of
  // a displacement is constant per tet, so a sliver shows at once). No time limit: deterministic.
  double sliver_bound_deg = 10.0;
};

struct VolumeMesh {
  TetMesh mesh;  // metres; tets positively oriented, nodes numbered by first use
  // The nodes on the boundary (vertices of Mesh_3's surface facets), ascending. They lie on the
  // input surface's triangles (to rounding), so a surface field carries over to them exactly
  // where it is linear on each triangle (transfer_vertex_field).
  std::vector<std::uint32_t> boundary_nodes;
  double volume_m3 = 0.0;         // sum of the tets' volumes
  double min_volume_m3 = 0.0;     // the smallest tet
  double min_dihedral_deg = 0.0;  // the smallest dihedral angle of any tet
};

// Throws ValueError for a surface that does not bound a volume (not closed, or a triangle
// soup Mesh_3 cannot take) or an edge length that is not positive. Sequential and seeded:
// the same surface and options give the same tets, bit for bit.
VolumeMesh tetrahedralize(const TriangleMesh& closed_surface, const TetrahedralizeOptions& options = {});

}  // namespace pneuma::mesh
