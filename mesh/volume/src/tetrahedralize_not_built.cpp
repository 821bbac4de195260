// The phantom-only build's stand-in for tetrahedralize_cgal.cpp (CGAL Mesh_3) and the lattice
// mesher (core/not_built.h): a run without voxel outputs or an interior field has no inside.
#include "pneuma/core/not_built.h"
#include "pneuma/mesh/volume/tetrahedralize.h"

namespace pneuma::mesh {

const char* tet_mesher_name(TetMesher mesher) { return mesher == TetMesher::lattice ? "lattice" : "delaunay"; }

VolumeMesh tetrahedralize(const TriangleMesh& /*closed_surface*/, const TetrahedralizeOptions& options) {
  throw_not_built(std::string("the inside of a surface as tetrahedra (the ") + tet_mesher_name(options.mesher) +
                  " mesher)");
}

}  // namespace pneuma::mesh
