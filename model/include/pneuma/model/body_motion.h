#pragma once
// How the body outside the lungs moves (#31; docs/voxels.md, "Around the lungs").
//
// The lungs slide along the chest wall: the tissue beside them (ribs, muscle, mediastinum) stays
// where it is, and the displacement is discontinuous at the pleura. Below the diaphragm the
// abdomen moves with it (the liver dome descends with the diaphragm in 4D-CT). pneuma models that
// as a decaying extension of the diaphragm's motion along the body's long axis:
//
//   u(x) = sum over lungs of  s_lung * a_lung(p) * exp(-|h - z_lung(p)| / L) * up
//
// with p the point's position across the body (the plane perpendicular to `up`), h its height
// along `up`, z_lung(p) the height of the lung's lowest surface point above or below p (its
// diaphragm) and a_lung(p) that point's unit displacement along `up` (negative: it descends).
// Outside the lung's footprint, a and z are extended by normalised Gaussian averaging (sigma
// `lateral_sigma_m`) and faded out by the Gaussian's reach, so the field is continuous everywhere
// off the lungs and matches the diaphragm's descent just below it. The motion is along `up` only,
// so its Jacobian determinant is 1 + du/dh >= 1 - max|s a| / L: with L = 120 mm and a 25 mm
// descent, at least 0.79; it cannot fold.
#include <Eigen/Core>
#include <span>
#include <vector>

namespace pneuma::model {

struct Model;

struct BodyMotionOptions {
  // L: how fast the motion fades with distance from the diaphragm along the body. The liver dome
  // follows the diaphragm; kidneys about 10 cm below it move about half as far (hence ~120 mm).
  double decay_length_m = 0.12;
  double lateral_sigma_m = 0.02;  // fade beyond the lung's footprint
  double cell_m = 2e-3;           // the maps' resolution across the body
};

class BodyMotion {
 public:
  BodyMotion() = default;  // no lungs: nothing moves
  // The maps of every lung of `model` (its rest surface, unit displacement and body axes).
  BodyMotion(const Model& model, const BodyMotionOptions& options = {});

  // The displacement (metres, LPS) of body tissue at `x` (outside the lungs) for the lungs'
  // scales (one per model lung).
  Eigen::Vector3d displacement(const Eigen::Vector3d& x, std::span<const double> scales) const;
  const BodyMotionOptions& options() const { return options_; }

 private:
  struct LungMap {
    Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // corner of cell (0, 0)
    std::size_t nx = 0, ny = 0;
    std::vector<double> amplitude;  // a * fade, per cell (m per unit s)
    std::vector<double> height;     // z, per cell (m along up)
  };
  BodyMotionOptions options_;
  Eigen::Vector3d up_ = Eigen::Vector3d::UnitZ(), across1_ = Eigen::Vector3d::UnitX(),
                  across2_ = Eigen::Vector3d::UnitY();
  std::vector<LungMap> lungs_;
};

}  // namespace pneuma::model
