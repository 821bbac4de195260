#pragma once
// The volume -> scale map (METHOD.md section 6).
//
// The enclosed volume of x + s*u is an exact cubic in s (a sum of signed tetrahedra whose
// vertices move linearly in s): V(s) = c0 + c1 s + c2 s^2 + c3 s^3. Its coefficients are
// computed once per model; each frame inverts it for the target volume with a safeguarded
// Newton iteration (bisection whenever a Newton step leaves the bracket), warm-started from
// the previous frame's scale, so a frame costs a few multiply-adds and allocates nothing.
#include <Eigen/Core>
#include <array>
#include <vector>

#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::model {

class VolumeScaleMap {
 public:
  VolumeScaleMap(const std::vector<Eigen::Vector3d>& rest, const std::vector<Eigen::Vector3d>& field,
                 const std::vector<mesh::Triangle>& triangles);
  // From known coefficients {c0, c1, c2, c3} (e.g. read back from a file).
  explicit VolumeScaleMap(const std::array<double, 4>& coefficients);

  // {c0, c1, c2, c3}; c0 is the rest volume (m^3).
  const std::array<double, 4>& coefficients() const { return c_; }
  double volume(double s) const { return c_[0] + s * (c_[1] + s * (c_[2] + s * c_[3])); }
  double slope(double s) const { return c_[1] + s * (2.0 * c_[2] + s * 3.0 * c_[3]); }

  // The interval around s = 0 on which V(s) increases (V' > 0): beyond it a larger scale no
  // longer means a larger volume. Infinite ends where V' never vanishes.
  double min_scale() const { return s_min_; }
  double max_scale() const { return s_max_; }
  double min_volume() const { return volume(s_min_); }
  double max_volume() const { return volume(s_max_); }
  bool reachable(double volume_m3) const;

  // The scale whose volume is `volume_m3`, to `relative_tolerance` of the rest volume.
  // Throws UnsupportedError when the volume lies outside [min_volume, max_volume].
  double scale_for(double volume_m3, double initial_guess = 0.0, double relative_tolerance = 1e-13) const;

 private:
  void find_monotone_range();
  std::array<double, 4> c_{};
  double s_min_ = 0.0;
  double s_max_ = 0.0;
};

}  // namespace pneuma::model
