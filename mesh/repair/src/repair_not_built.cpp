// The phantom-only build's stand-in for repair.cpp, remesh.cpp and voxel_rebuild.cpp (CGAL's
// polygon mesh processing; core/not_built.h). A run of the built-in phantom neither repairs nor
// remeshes: the phantom is made at its edge length.
#include "pneuma/core/not_built.h"
#include "pneuma/mesh/repair/remesh.h"
#include "pneuma/mesh/repair/repair.h"

namespace pneuma::mesh {

RepairResult repair(const TriangleMesh& /*mesh*/, const std::string& name, const RepairOptions& /*options*/) {
  throw_not_built(name + ": mesh repair");
}

RepairResult repair_unchecked(const TriangleMesh& /*mesh*/, const std::string& name, const RepairOptions& /*options*/,
                              ValidationReport* /*after*/) {
  throw_not_built(name + ": mesh repair");
}

RepairRemeshResult repair_and_remesh(const TriangleMesh& /*mesh*/, const std::string& name,
                                     const RepairOptions& /*repair_options*/, const RemeshOptions& /*remesh_options*/) {
  throw_not_built(name + ": mesh repair and remeshing");
}

RemeshResult remesh_isotropic(const TriangleMesh& /*mesh*/, const RemeshOptions& /*options*/) {
  throw_not_built("isotropic remeshing");
}

}  // namespace pneuma::mesh
