#pragma once
// A breath below the rest shape (a scan taken above FRC, docs/voxels.md "The scan's place on the
// breath"): the surface field u is the inflation's, and rest + s u with s < 0 is its mirror. Where
// a thin part of the lung (the costophrenic recess, the sharp medial rim of the base) has a face
// that moves much more than the face beside it, the mirror closes that part by more than its
// thickness and the two faces pass through each other (on the shared CT lungs the diaphragm rises
// 9-13 mm under a mediastinal or costal face 6 mm above it that stands still). A displacement
// v(x) whose spatial gradient stays below 1 maps space one to one; the field smoothed in space
// (not along the surface: the two faces of a thin wedge are close in space, far along the
// surface) at a length sigma has a gradient of at most its range over sigma, so faces closer than
// about sigma move together and a wedge rises as a whole instead of closing.
#include <Eigen/Core>
#include <vector>

#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::field {

// `u` (per vertex of `rest`) smoothed in space at `sigma_m`: each vertex takes the area-weighted
// Gaussian mean of the vertices within 4 sigma (Nadaraya-Watson), then the whole field is scaled
// so that its first-order area rate (mesh::area_gradient . u) is u's: s still counts the same area
// units. sigma_m <= 0: u as it is. The same bits at any thread count (each vertex's sum in a fixed
// order). Throws ValueError when the sizes do not match or the smoothed field does not enlarge
// the surface.
std::vector<Eigen::Vector3d> smooth_field_in_space(const mesh::TriangleMesh& rest,
                                                   const std::vector<Eigen::Vector3d>& u, double sigma_m);

}  // namespace pneuma::field
