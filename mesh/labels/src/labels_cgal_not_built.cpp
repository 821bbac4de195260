// The phantom-only build's stand-in for labels_cgal.cpp (CGAL Mesh_3: the slowest unit to
// compile; core/not_built.h).
#include "pneuma/core/not_built.h"
#include "pneuma/mesh/labels/labels.h"

namespace pneuma::mesh::detail {

TriangleMesh mesh_level_set(const ScalarGrid& /*grid*/, double /*edge_length_m*/, double /*max_distance_m*/) {
  throw_not_built("a label map's surface (CGAL Mesh_3)");
}

}  // namespace pneuma::mesh::detail
