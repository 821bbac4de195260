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

// Whether the displacement `d` (per point of `points`) is a contraction on them:
// |d_i - d_j| < |x_i - x_j| for every pair of distinct points. A displacement whose Lipschitz
// constant is below 1 maps the points one to one (x + d(x) is then bi-Lipschitz), and by
// Kirszbraun's theorem it extends into the space between them with the same constant, so the
// lung's inside can follow it with no two neighbours more than their distance apart. Only pairs
// closer than 2 max |d| can fail (|d_i - d_j| <= 2 max |d|), so only those are visited, through a
// grid of that size: about a lung's neighbourhood instead of all pairs. Exact, in parallel, the
// same answer at any thread count. Throws ValueError when the sizes do not match or a point or
// its displacement is not finite.
bool is_contraction(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& d);

// The largest |d_i - d_j| / |x_i - x_j| over the pairs of distinct points closer than `radius_m`
// (0 when there is none): the displacement's Lipschitz constant on them where radius_m reaches
// every pair. is_contraction's measure, for tests and probes; the same errors.
double steepest_pair_slope(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& d,
                           double radius_m);

}  // namespace pneuma::field
