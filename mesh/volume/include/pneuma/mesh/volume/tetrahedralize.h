#pragma once
// The inside of a closed lung surface as tetrahedra, for the interior field and the voxel outputs
// (#31), by one of two meshers:
//   delaunay  CGAL Mesh_3: Delaunay refinement of the polyhedral domain the surface bounds, with
//             sliver exudation. Graded, well-shaped tets; about 17 us per tet (2 cores).
//   lattice   the Kuhn triangulation of a cubic lattice of the edge, cut at the surface after
//             nodes near it were moved onto it (isosurface stuffing's warping; see
//             tetrahedralize_lattice.cpp). Uniform tets, far fewer shapes; linear time and about
//             50x faster, for the fine (1M-tet) insides.
// Both put the boundary nodes on the surface's triangles.
#include <cstdint>
#include <vector>

#include "pneuma/mesh/geometry/tet_mesh.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh {

enum class TetMesher { delaunay, lattice };

// "delaunay", "lattice"
const char* tet_mesher_name(TetMesher mesher);

struct TetrahedralizeOptions {
  TetMesher mesher = TetMesher::delaunay;
  // delaunay: target size of cells and boundary facets (Mesh_3 cell_size, facet_size);
  // lattice: the lattice's spacing (the tets' short edges; about as many tets as Mesh_3's).
  double edge_length_m = 3e-3;
  double max_distance_m = 0.0;  // delaunay: boundary facet to the surface; 0: edge_length_m / 10
  // delaunay: Mesh_3's sliver exudation until every dihedral angle reaches this bound (degrees) or no
  // exchange improves it; 0: none. Flat tets make poorly conditioned gradients (the Jacobian of
  // a displacement is constant per tet, so a sliver shows at once). No time limit: deterministic.
  double sliver_bound_deg = 10.0;
};

struct VolumeMesh {
  TetMesh mesh;  // metres; tets positively oriented, nodes numbered by first use
  // The nodes on the boundary (vertices of Mesh_3's surface facets; the lattice's crossings and
  // moved nodes), ascending. They lie on the
  // input surface's triangles (to rounding), so a surface field carries over to them exactly
  // where it is linear on each triangle (transfer_vertex_field).
  std::vector<std::uint32_t> boundary_nodes;
  double volume_m3 = 0.0;         // sum of the tets' volumes
  double min_volume_m3 = 0.0;     // the smallest tet
  double min_dihedral_deg = 0.0;  // the smallest dihedral angle of any tet
};

// Throws ValueError for a surface that does not bound a volume (not closed, or a triangle
// soup Mesh_3 cannot take) or an edge length that is not positive. Deterministic (Mesh_3
// sequential and seeded; the lattice's parallel loops write their own slots): the same surface and
// options give the same tets, bit for bit, at any thread count.
VolumeMesh tetrahedralize(const TriangleMesh& closed_surface, const TetrahedralizeOptions& options = {});

}  // namespace pneuma::mesh
