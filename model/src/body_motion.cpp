// The diaphragm's height map per lung, extended and faded beyond the footprint (body_motion.h).
#include "pneuma/model/body_motion.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

#include "pneuma/model/model.h"

namespace pneuma::model {
namespace {

// A separable Gaussian blur of a nx x ny map (i fastest), truncated at 4 sigma, zero outside.
std::vector<double> blur(const std::vector<double>& in, std::size_t nx, std::size_t ny, double sigma_cells) {
  const auto radius = static_cast<std::ptrdiff_t>(std::ceil(4.0 * sigma_cells));
  std::vector<double> kernel;
  for (std::ptrdiff_t k = -radius; k <= radius; ++k) {
    kernel.push_back(std::exp(-0.5 * static_cast<double>(k * k) / (sigma_cells * sigma_cells)));
  }
  double total = 0.0;
  for (const double w : kernel) total += w;
  for (double& w : kernel) w /= total;
  auto pass = [&](const std::vector<double>& src, bool along_x) {
    std::vector<double> dst(src.size(), 0.0);
    const auto sx = static_cast<std::ptrdiff_t>(nx), sy = static_cast<std::ptrdiff_t>(ny);
    for (std::ptrdiff_t j = 0; j < sy; ++j) {
      for (std::ptrdiff_t i = 0; i < sx; ++i) {
        double sum = 0.0;
        for (std::ptrdiff_t k = -radius; k <= radius; ++k) {
          const std::ptrdiff_t ii = along_x ? i + k : i, jj = along_x ? j : j + k;
          if (ii < 0 || jj < 0 || ii >= sx || jj >= sy) continue;
          sum += kernel[static_cast<std::size_t>(k + radius)] * src[static_cast<std::size_t>(ii + sx * jj)];
        }
        dst[static_cast<std::size_t>(i + sx * j)] = sum;
      }
    }
    return dst;
  };
  return pass(pass(in, true), false);
}

}  // namespace

BodyMotion::BodyMotion(const Model& model, const BodyMotionOptions& options) : options_(options) {
  if (model.lungs.empty()) return;
  const mesh::BodyAxes& axes = model.lungs.front().regions.axes;
  up_ = axes.up.normalized();
  across1_ = axes.left();
  across2_ = up_.cross(across1_).normalized();
  const double h = options.cell_m;
  const double margin = 4.0 * options.lateral_sigma_m + 2.0 * h;
  for (const LungModel& lung : model.lungs) {
    LungMap map;
    // The footprint's bounds across the body, with room for the fade.
    double lo1 = std::numeric_limits<double>::infinity(), hi1 = -lo1, lo2 = lo1, hi2 = -lo1;
    for (const auto& v : lung.rest.vertices) {
      lo1 = std::min(lo1, v.dot(across1_));
      hi1 = std::max(hi1, v.dot(across1_));
      lo2 = std::min(lo2, v.dot(across2_));
      hi2 = std::max(hi2, v.dot(across2_));
    }
    lo1 -= margin;
    lo2 -= margin;
    map.nx = static_cast<std::size_t>(std::ceil((hi1 + margin - lo1) / h)) + 1;
    map.ny = static_cast<std::size_t>(std::ceil((hi2 + margin - lo2) / h)) + 1;
    map.origin = lo1 * across1_ + lo2 * across2_;
    const std::size_t cells = map.nx * map.ny;
    // The lowest downward-facing surface point over each cell centre, and its displacement along up.
    std::vector<double> lowest(cells, std::numeric_limits<double>::infinity()), amplitude(cells, 0.0);
    for (const auto& t : lung.rest.triangles) {
      const Eigen::Vector3d& a = lung.rest.vertices[t[0]];
      const Eigen::Vector3d& b = lung.rest.vertices[t[1]];
      const Eigen::Vector3d& c = lung.rest.vertices[t[2]];
      if ((b - a).cross(c - a).dot(up_) >= 0.0) continue;  // faces up or sideways
      const Eigen::Vector2d pa((a.dot(across1_) - lo1) / h, (a.dot(across2_) - lo2) / h);
      const Eigen::Vector2d pb((b.dot(across1_) - lo1) / h, (b.dot(across2_) - lo2) / h);
      const Eigen::Vector2d pc((c.dot(across1_) - lo1) / h, (c.dot(across2_) - lo2) / h);
      const double area = (pb - pa).x() * (pc - pa).y() - (pb - pa).y() * (pc - pa).x();
      if (std::abs(area) < 1e-12) continue;
      const auto i0 = static_cast<std::size_t>(std::max(0.0, std::floor(std::min({pa.x(), pb.x(), pc.x()}))));
      const auto j0 = static_cast<std::size_t>(std::max(0.0, std::floor(std::min({pa.y(), pb.y(), pc.y()}))));
      const auto i1 = std::min(map.nx - 1, static_cast<std::size_t>(std::ceil(std::max({pa.x(), pb.x(), pc.x()}))));
      const auto j1 = std::min(map.ny - 1, static_cast<std::size_t>(std::ceil(std::max({pa.y(), pb.y(), pc.y()}))));
      for (std::size_t j = j0; j <= j1; ++j) {
        for (std::size_t i = i0; i <= i1; ++i) {
          const Eigen::Vector2d p(static_cast<double>(i), static_cast<double>(j));
          const double wa = ((pb - p).x() * (pc - p).y() - (pb - p).y() * (pc - p).x()) / area;
          const double wb = ((pc - p).x() * (pa - p).y() - (pc - p).y() * (pa - p).x()) / area;
          const double wc = 1.0 - wa - wb;
          if (wa < 0.0 || wb < 0.0 || wc < 0.0) continue;
          const double z = wa * a.dot(up_) + wb * b.dot(up_) + wc * c.dot(up_);
          const std::size_t cell = i + map.nx * j;
          if (z < lowest[cell]) {
            lowest[cell] = z;
            amplitude[cell] = (wa * lung.unit_displacement[t[0]] + wb * lung.unit_displacement[t[1]] +
                               wc * lung.unit_displacement[t[2]])
                                  .dot(up_);
          }
        }
      }
    }
    // Beyond the footprint: normalised Gaussian averages of a and z, faded by the Gaussian's reach
    // (the footprint's blurred indicator, 1/2 at a straight edge: doubled and capped at 1).
    std::vector<double> mask(cells, 0.0), masked_a(cells, 0.0), masked_z(cells, 0.0);
    for (std::size_t k = 0; k < cells; ++k) {
      if (std::isfinite(lowest[k])) {
        mask[k] = 1.0;
        masked_a[k] = amplitude[k];
        masked_z[k] = lowest[k];
      }
    }
    const double sigma_cells = options.lateral_sigma_m / h;
    const std::vector<double> weight = blur(mask, map.nx, map.ny, sigma_cells);
    const std::vector<double> sum_a = blur(masked_a, map.nx, map.ny, sigma_cells);
    const std::vector<double> sum_z = blur(masked_z, map.nx, map.ny, sigma_cells);
    map.amplitude.assign(cells, 0.0);
    map.height.assign(cells, 0.0);
    for (std::size_t k = 0; k < cells; ++k) {
      if (mask[k] > 0.0) {
        map.amplitude[k] = amplitude[k];
        map.height[k] = lowest[k];
      } else if (weight[k] > 1e-12) {
        map.amplitude[k] = sum_a[k] / weight[k] * std::min(1.0, 2.0 * weight[k]);
        map.height[k] = sum_z[k] / weight[k];
      }
    }
    lungs_.push_back(std::move(map));
  }
}

Eigen::Vector3d BodyMotion::displacement(const Eigen::Vector3d& x, std::span<const double> scales) const {
  double along_up = 0.0;
  const double h = options_.cell_m;
  for (std::size_t l = 0; l < lungs_.size() && l < scales.size(); ++l) {
    const LungMap& m = lungs_[l];
    const Eigen::Vector3d d = x - m.origin;
    const double fi = d.dot(across1_) / h, fj = d.dot(across2_) / h;
    if (!(fi >= 0.0 && fj >= 0.0)) continue;
    const auto i = static_cast<std::size_t>(fi), j = static_cast<std::size_t>(fj);
    if (i + 1 >= m.nx || j + 1 >= m.ny) continue;
    const double ti = fi - static_cast<double>(i), tj = fj - static_cast<double>(j);
    // Bilinear in both maps: continuous across cells.
    auto at = [&](const std::vector<double>& v) {
      const std::size_t k = i + m.nx * j;
      return (1 - ti) * (1 - tj) * v[k] + ti * (1 - tj) * v[k + 1] + (1 - ti) * tj * v[k + m.nx] +
             ti * tj * v[k + m.nx + 1];
    };
    const double a = at(m.amplitude);
    if (a == 0.0) continue;
    along_up += scales[l] * a * std::exp(-std::abs(x.dot(up_) - at(m.height)) / options_.decay_length_m);
  }
  return along_up * up_;
}

}  // namespace pneuma::model
