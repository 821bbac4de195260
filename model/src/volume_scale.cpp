#include "pneuma/model/volume_scale.h"

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <string>

#include "pneuma/core/error.h"

namespace pneuma::model {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

std::string litres(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.4g L", v * 1e3);
  return buffer;
}

}  // namespace

VolumeScaleMap::VolumeScaleMap(const std::vector<Eigen::Vector3d>& x, const std::vector<Eigen::Vector3d>& u,
                               const std::vector<mesh::Triangle>& triangles) {
  // 6 V(s) = sum (a + s ua) . ((b + s ub) x (c + s uc)), expanded by powers of s.
  double k0 = 0, k1 = 0, k2 = 0, k3 = 0;
  for (const mesh::Triangle& t : triangles) {
    const Eigen::Vector3d &a = x[t[0]], &b = x[t[1]], &c = x[t[2]];
    const Eigen::Vector3d &ua = u[t[0]], &ub = u[t[1]], &uc = u[t[2]];
    const Eigen::Vector3d bc = b.cross(c), ubc = ub.cross(c), buc = b.cross(uc), ubuc = ub.cross(uc);
    k0 += a.dot(bc);
    k1 += ua.dot(bc) + a.dot(ubc) + a.dot(buc);
    k2 += a.dot(ubuc) + ua.dot(ubc) + ua.dot(buc);
    k3 += ua.dot(ubuc);
  }
  c_ = {k0 / 6.0, k1 / 6.0, k2 / 6.0, k3 / 6.0};
  find_monotone_range();
}

VolumeScaleMap::VolumeScaleMap(const std::array<double, 4>& coefficients) : c_(coefficients) { find_monotone_range(); }

void VolumeScaleMap::find_monotone_range() {
  // Roots of V'(s) = c1 + 2 c2 s + 3 c3 s^2 nearest to 0 on each side bound the monotone range.
  s_min_ = -kInfinity;
  s_max_ = kInfinity;
  const double qa = 3.0 * c_[3], qb = 2.0 * c_[2], qc = c_[1];
  std::array<double, 2> roots{kInfinity, kInfinity};
  int count = 0;
  if (std::abs(qa) < 1e-300) {
    if (qb != 0.0) roots[count++] = -qc / qb;
  } else {
    const double disc = qb * qb - 4.0 * qa * qc;
    if (disc >= 0.0) {
      // Numerically stable quadratic roots.
      const double q = -0.5 * (qb + std::copysign(std::sqrt(disc), qb));
      roots[count++] = q / qa;
      if (q != 0.0) roots[count++] = qc / q;
    }
  }
  for (int i = 0; i < count; ++i) {
    if (roots[i] > 0.0) s_max_ = std::min(s_max_, roots[i]);
    if (roots[i] < 0.0) s_min_ = std::max(s_min_, roots[i]);
  }
  if (!(c_[1] > 0.0)) {
    throw UnsupportedError("the displacement field does not enlarge the mesh (dV/ds = " + std::to_string(c_[1]) +
                           " m^3 per unit scale); check that the mesh is outward-oriented");
  }
}

bool VolumeScaleMap::reachable(double v) const { return v >= min_volume() && v <= max_volume(); }

double VolumeScaleMap::scale_for(double target, double guess, double relative_tolerance) const {
  if (!reachable(target)) {
    throw UnsupportedError("a mesh volume of " + litres(target) + " is outside what the field can reach (" +
                           litres(min_volume()) + " to " + litres(max_volume()) + ")");
  }
  // Bracket [lo, hi] with V(lo) <= target <= V(hi), within the monotone range.
  double lo = s_min_, hi = s_max_;
  if (!std::isfinite(lo) || !std::isfinite(hi)) {
    // Expand a finite bracket from the guess until it holds the target.
    double step = std::max(1.0, std::abs(guess));
    if (!std::isfinite(lo)) {
      lo = guess - step;
      while (volume(lo) > target) lo -= (step *= 2.0);
    }
    step = std::max(1.0, std::abs(guess));
    if (!std::isfinite(hi)) {
      hi = guess + step;
      while (volume(hi) < target) hi += (step *= 2.0);
    }
  }
  double s = std::clamp(guess, lo, hi);
  const double tolerance = relative_tolerance * std::abs(c_[0]);
  for (int iteration = 0; iteration < 200; ++iteration) {
    const double f = volume(s) - target;
    if (std::abs(f) <= tolerance) return s;
    if (f < 0.0) lo = s;
    else hi = s;
    const double d = slope(s);
    double next = d > 0.0 ? s - f / d : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);  // the safeguard
    if (next == s) return s;
    s = next;
  }
  return s;
}

}  // namespace pneuma::model
