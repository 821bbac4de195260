#pragma once
// One lung at one time point, as the voxel outputs take it: the tetrahedral mesh of its inside
// at rest (metres, LPS, positively oriented tets), a unit displacement per node and the frame's
// scale s. Node n moves to nodes[n] + s * unit_displacement_m[n]; inside a tet the motion is the
// linear (P1) interpolation of the nodes' motion.
#include <Eigen/Core>
#include <span>

#include "pneuma/mesh/geometry/tet_mesh.h"

namespace pneuma::voxels {

struct LungMotion {
  const mesh::TetMesh& mesh;
  std::span<const Eigen::Vector3d> unit_displacement_m;  // one per node
  double scale = 1.0;
};

// Throws ValueError unless there is one displacement per node, every tet names existing nodes
// and every value is finite.
void check_lung_motion(const LungMotion& lung);

}  // namespace pneuma::voxels
