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
//
// The diaphragm is one sheet: where the lung reaches under its slope (a recess below the dome's
// rim or under the heart), the face of the lung that looks up lies under the same sheet that
// the lung's diaphragmatic face below it lies on, a recess's thickness away, and moves with it.
// Without that, such a face kept the costal region's motion (2 mm at 500 mL) while the
// diaphragmatic face under it descended 10-12 mm: case009's left lung has such a recess, 8-12 mm
// thick, stretched to a forward Jacobian of 2-3.2 (#45, docs/voxels.md "The stretched recess").
// A face under the diaphragm therefore takes the motion of the surface around it in space (the
// field blurred at 10 mm, which holds both faces of the recess), as far as it lies under it.
// Adding the heart's descent to that face instead stretched it less but self-intersected the
// surfaces of case007-009 at a 1.5 L breath: its own descent overtook the face below it.
//
// The costophrenic margin is such a place too: below the dome's top the lung ends in an edge
// between its costal face, on the chest wall, and its diaphragmatic face, on the diaphragm where
// it curves down to meet the chest wall (the costophrenic recess), and the lung's edge slides
// down into the recess as the diaphragm descends. Without it, upright, the dome's piston moved
// the diaphragmatic face of case009's right lung 16-19.5 mm down beside an anterior costal face
// 10-15 mm away that moved 1-4 mm: the edge between them was stretched to a forward Jacobian of
// 2.1 (2-3 voxels above the base; #45, docs/voxels.md "The costophrenic margin"). So both faces
// of the margin (where the costal and diaphragmatic weights, blurred at 10 mm, meet) also move
// with the surface around them, as far as the edge is thin (its two faces' normals cancel in
// space): a border however thick moved as well raised the phantom's dome top past 21 mm (the
// breath's volume taken from the diaphragm's rim), and moving the costal face alone
// self-intersected case008's left lung at a 1.5 L breath. Not where the tissue has a slide
// (healthy-supine): there the costal face at the base already descends with the diaphragm
// (mesh/sliding.h), and moving the margin as well made the body under case009's posterior recess
// leave [0.5, 2] (J 2.006, 3 voxels) with the scan at end-inspiration.
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
// The same with N given: `smoothed_normal` is mesh::smoothed_normals(mesh, sigma), computed once
// by a caller that needs it for other rules too (compute_field). Not read when the heart stands
// still; else one per vertex (ValueError).
std::vector<Eigen::Vector3d> heart_descent_field(const mesh::TriangleMesh& mesh, const mesh::SurfaceRegions& regions,
                                                 const HeartDescent& heart,
                                                 const std::vector<Eigen::Vector3d>& smoothed_normal);

// The sigma of the normals by which a face under the diaphragm is told (under_diaphragm) and
// along which the thin lung's rays are cast (thin_lung.h): 3 mm, so that a thin recess's two
// faces (8-12 mm apart on case009) keep their own; at 10 mm (the regions') or 20 mm they cancel.
inline constexpr double kFaceNormalSigma = 3e-3;

// Per vertex: how far the face lies under the diaphragm or (Margin::moved) on a thin
// costophrenic margin, in [0, 1]: b(h) max(max(0, up.n), min(1, 4 c d) t) (Margin::kept:
// b(h) max(0, up.n)), n the outward normal smoothed in space at 3 mm (a thin recess's two faces
// keep their own), c and d the costal and diaphragmatic region weights blurred in space at 10 mm
// (4 c d is 1 on their border, where c = d = 1/2, and falls off over about the blur's width),
// t = 1 - |the vertex normals blurred in space at 10 mm| (0 on a flat face, 0.3 at a right-angled
// edge, about 0.7 at an edge of 30 degrees, 1 between opposite faces: how thin the lung is
// there), b a smooth step of the height from 1 below the dome's top (mesh::dome_top_vertices)
// less 0.05 of the lung's height to 0 at it. 0 everywhere on a surface without a dome. Throws
// ValueError for regions of another surface.
enum class Margin {
  kept,   // the costophrenic margin keeps its own motion (the tissue slides: it moves already)
  moved,  // the margin moves with the surface around it too
};
std::vector<double> under_diaphragm(const mesh::TriangleMesh& mesh, const mesh::SurfaceRegions& regions,
                                    Margin margin = Margin::moved);
// The same with n given: `face_normal` is mesh::smoothed_normals(mesh, kFaceNormalSigma), one
// per vertex (ValueError), computed once for this rule and the thin lung's rays (compute_field).
std::vector<double> under_diaphragm(const mesh::TriangleMesh& mesh, const mesh::SurfaceRegions& regions, Margin margin,
                                    const std::vector<Eigen::Vector3d>& face_normal);

// A face under the diaphragm moves with the surface around it: u_i += w_i (ubar_i - u_i), w
// from under_diaphragm(), ubar the field blurred in space at 10 mm (mesh::blurred_in_space). In
// place; the caller scales the field back to its area unit.
void follow_the_diaphragm_over(const mesh::TriangleMesh& mesh, const mesh::SurfaceRegions& regions,
                               std::vector<Eigen::Vector3d>& u, Margin margin = Margin::moved);
// The same with the 3 mm normals given (under_diaphragm's `face_normal`).
void follow_the_diaphragm_over(const mesh::TriangleMesh& mesh, const mesh::SurfaceRegions& regions,
                               std::vector<Eigen::Vector3d>& u, Margin margin,
                               const std::vector<Eigen::Vector3d>& face_normal);

}  // namespace pneuma::field
