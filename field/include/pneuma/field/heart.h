#pragma once
// The heart descends with the diaphragm (docs/voxels.md, "The lung on the heart"): its inferior
// surface rests on the diaphragm's central tendon, and in breathing it moves caudally by about
// 0.6 of the diaphragm's descent (Wang et al., Magn Reson Med 33:713, 1995: the correction
// factor of MRI's diaphragm navigator for the coronary arteries). The lung's face on the heart
// (the cardiac impression: the mediastinal face below the hilum that looks down onto the heart)
// descends with it, as far as it looks down: fully where it lies flat on the heart, not at all
// where it stands beside it (there the heart slides past). One direction (-up) for the whole
// face: moving the concave face along its own normals (the normal part of the descent) made
// them converge, and the surface of case008's and case009's left lungs self-intersected at a
// 1.5 L breath. Without it that face stands still while the lung above it descends, and the
// lingula between them shrinks (#45).
#include <Eigen/Core>
#include <vector>

#include "pneuma/mesh/anatomy/regions.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::field {

// The heart's descent in units of the lung's own diaphragm descent (mesh::diaphragm_descent), so
// it follows whatever load drives the diaphragm. descent 0: the heart stands still.
struct HeartDescent {
  double descent = 0.0;  // the heart's caudal motion per unit of the diaphragm's mean descent
  double top = 0.5;      // the heart's top, a height of the lung (0 base, 1 apex): full below
                         // top - 0.1, none above top + 0.1 (a smooth step)
  bool active() const { return descent != 0.0; }
};

// Per vertex: the lung's motion per unit of diaphragm descent where it lies on the heart,
//   descent w_mediastinal g(h) max(0, -up.N) (-up),
// N the outward normal smoothed in space at `sigma` (mesh::smoothed_normals), w the mediastinal
// region weight, g the smooth step of the height h at `top`: 0 off the mediastinal face, above
// the heart and where the face does not look down. Smooth in space (every factor is).
// Throws ValueError for a descent outside [0, 1], a top outside (0.1, 0.9), or regions of
// another surface.
std::vector<Eigen::Vector3d> heart_descent_field(const mesh::TriangleMesh& mesh, const mesh::SurfaceRegions& regions,
                                                 const HeartDescent& heart, double sigma);

}  // namespace pneuma::field
