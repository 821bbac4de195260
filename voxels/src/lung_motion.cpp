#include "pneuma/voxels/lung_motion.h"

#include <cmath>
#include <string>

#include "pneuma/core/error.h"

namespace pneuma::voxels {

void check_lung_motion(const LungMotion& lung) {
  const std::size_t nodes = lung.mesh.node_count();
  if (lung.unit_displacement_m.size() != nodes) {
    throw ValueError("a lung's tet mesh has " + std::to_string(nodes) + " nodes and " +
                     std::to_string(lung.unit_displacement_m.size()) + " displacements: expected one per node");
  }
  if (!std::isfinite(lung.scale)) throw ValueError("a lung's displacement scale is not finite");
  for (std::size_t t = 0; t < lung.mesh.tet_count(); ++t) {
    for (const std::uint32_t n : lung.mesh.tets[t]) {
      if (n >= nodes) {
        throw ValueError("tet " + std::to_string(t) + " names node " + std::to_string(n) + " of " +
                         std::to_string(nodes));
      }
    }
  }
  for (std::size_t n = 0; n < nodes; ++n) {
    if (!lung.mesh.nodes[n].allFinite() || !lung.unit_displacement_m[n].allFinite()) {
      throw ValueError("node " + std::to_string(n) +
                       " of a lung's tet mesh: expected a finite position and displacement");
    }
  }
}

}  // namespace pneuma::voxels
