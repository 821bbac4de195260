#include "pneuma/mesh/anatomy/sliding.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "pneuma/core/error.h"

namespace pneuma::mesh {
namespace {

double smooth(double u) {
  u = std::clamp(u, 0.0, 1.0);
  return u * u * (3.0 - 2.0 * u);
}

}  // namespace

std::vector<Eigen::Vector3d> sliding_field(const TriangleMesh& mesh, const SurfaceRegions& regions,
                                           const Sliding& sliding, double sigma) {
  return sliding_field(mesh, regions, sliding,
                       sliding.active() ? smoothed_normals(mesh, sigma) : std::vector<Eigen::Vector3d>{});
}

std::vector<Eigen::Vector3d> sliding_field(const TriangleMesh& mesh, const SurfaceRegions& regions,
                                           const Sliding& sliding, const std::vector<Eigen::Vector3d>& normal) {
  if (!(sliding.caudal >= 0.0 && sliding.anterior >= 0.0 && sliding.mediastinal >= 0.0 && sliding.blur_m >= 0.0 &&
        sliding.exponent > 0.0 && sliding.base >= 0.0 && sliding.base < 1.0))
    throw ValueError("sliding_field: the amplitudes must be >= 0");
  require_regions_of(regions, mesh, regions.axes, "sliding_field");
  const std::size_t n = mesh.vertices.size();
  std::vector<Eigen::Vector3d> slide(n, Eigen::Vector3d::Zero());
  if (!sliding.active()) return slide;
  if (normal.size() != n) throw ValueError("sliding_field: one smoothed normal per vertex");
  const Eigen::Vector3d up = regions.axes.up, anterior = regions.axes.anterior;
  double back = std::numeric_limits<double>::infinity(), front = -back;
  for (const Eigen::Vector3d& x : mesh.vertices) {
    back = std::min(back, x.dot(anterior));
    front = std::max(front, x.dot(anterior));
  }
  auto across = [](const Eigen::Vector3d& v, const Eigen::Vector3d& nrm) -> Eigen::Vector3d {
    return v - v.dot(nrm) * nrm;
  };
  constexpr auto kCostal = static_cast<std::size_t>(Region::costal);
  constexpr auto kMediastinal = static_cast<std::size_t>(Region::mediastinal);
  std::vector<double> share(n);
  for (std::size_t i = 0; i < n; ++i) share[i] = regions.weight[i][kCostal];
  if (sliding.blur_m > 0.0) {
    share = blurred_in_space(mesh, share, sliding.blur_m);
    for (std::size_t i = 0; i < n; ++i) share[i] *= 1.0 - regions.weight[i][kMediastinal];
  }
  for (std::size_t i = 0; i < n; ++i) share[i] += sliding.mediastinal * regions.weight[i][kMediastinal];
  for (std::size_t i = 0; i < n; ++i) {
    const double a = front > back ? (mesh.vertices[i].dot(anterior) - back) / (front - back) : 0.0;
    const double fade = sliding.base > 0.0 ? smooth(regions.height[i] / sliding.base) : 1.0;
    slide[i] = fade * share[i] *
               (sliding.caudal * std::pow(1.0 - regions.height[i], sliding.exponent) * across(-up, normal[i]) +
                sliding.anterior * a * across(anterior, normal[i]));
  }
  return slide;
}

double diaphragm_descent(const TriangleMesh& mesh, const SurfaceRegions& regions,
                         const std::vector<Eigen::Vector3d>& displacement) {
  if (displacement.size() != mesh.vertices.size() || regions.weight.size() != mesh.vertices.size())
    throw ValueError("diaphragm_descent: one displacement and one region weight per vertex");
  const std::vector<double> area = vertex_areas(mesh);
  constexpr auto kDiaphragm = static_cast<std::size_t>(Region::diaphragmatic);
  double sum = 0.0, weight = 0.0;
  for (std::size_t i = 0; i < displacement.size(); ++i) {
    const double w = area[i] * regions.weight[i][kDiaphragm];
    sum -= w * displacement[i].dot(regions.axes.up);
    weight += w;
  }
  return weight > 0.0 ? sum / weight : 0.0;
}

}  // namespace pneuma::mesh
