#include "pneuma/mesh/anatomy/motion_summary.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include "pneuma/core/error.h"

namespace pneuma::mesh {
std::vector<double> swept_volumes(const TriangleMesh& rest, std::span<const Eigen::Vector3d> d) {
  if (d.size() != rest.vertices.size()) throw ValueError("swept_volumes: one displacement per vertex");
  const auto& p = rest.vertices;
  std::vector<double> out(rest.triangles.size());
  for (std::size_t t = 0; t < rest.triangles.size(); ++t) {
    const auto& tri = rest.triangles[t];
    // a(t) = a + t da ...: the area vector N(t) = (b - a)(t) x (c - a)(t) / 2 = N0 + t N1 + t^2 N2,
    // the mean velocity over the triangle is (da + db + dc) / 3; the swept volume is
    // mean velocity . integral_0^1 N(t) dt = . (N0 + N1 / 2 + N2 / 3).
    const Eigen::Vector3d e1 = p[tri[1]] - p[tri[0]], e2 = p[tri[2]] - p[tri[0]];
    const Eigen::Vector3d f1 = d[tri[1]] - d[tri[0]], f2 = d[tri[2]] - d[tri[0]];
    const Eigen::Vector3d n0 = 0.5 * e1.cross(e2), n1 = 0.5 * (e1.cross(f2) + f1.cross(e2)), n2 = 0.5 * f1.cross(f2);
    const Eigen::Vector3d v = (d[tri[0]] + d[tri[1]] + d[tri[2]]) / 3.0;
    out[t] = v.dot(n0 + n1 / 2.0 + n2 / 3.0);
  }
  return out;
}

MotionSummary summarize_motion(const TriangleMesh& rest, std::span<const Eigen::Vector3d> u, double scale,
                               const SurfaceRegions& regions, double dome_top_depth_m) {
  const std::size_t n = rest.vertices.size();
  if (u.size() != n || regions.label.size() != n)
    throw ValueError("summarize_motion: one displacement and one label per vertex");
  std::vector<Eigen::Vector3d> d(n);
  for (std::size_t i = 0; i < n; ++i) d[i] = scale * u[i];
  const std::vector<double> swept = swept_volumes(rest, d);
  std::vector<double> vertex_volume(n, 0.0);
  MotionSummary s;
  for (std::size_t t = 0; t < swept.size(); ++t) {
    s.volume_change_m3 += swept[t];
    for (std::uint32_t v : rest.triangles[t]) vertex_volume[v] += swept[t] / 3.0;
  }
  const std::vector<double> area = vertex_areas(rest);
  const Eigen::Vector3d up = regions.axes.up, anterior = regions.axes.anterior, lateral = -regions.medial;
  const std::vector<bool> on_dome_top = dome_top_vertices(rest, regions, dome_top_depth_m);
  double dome_sum = 0.0, dome_area = 0.0;
  std::array<double, 5> band_sum{}, band_area{};
  for (std::size_t i = 0; i < n; ++i) {
    RegionMotion& r = s.region[static_cast<std::size_t>(regions.label[i])];
    const double caudal = -d[i].dot(up), ant = d[i].dot(anterior), lat = d[i].dot(lateral), mag = d[i].norm();
    r.area_m2 += area[i];
    r.caudal_mean_m += area[i] * caudal;
    r.anterior_mean_m += area[i] * ant;
    r.lateral_mean_m += area[i] * lat;
    r.magnitude_mean_m += area[i] * mag;
    r.caudal_max_m = std::max(r.caudal_max_m, caudal);
    r.anterior_max_m = std::max(r.anterior_max_m, ant);
    r.lateral_max_m = std::max(r.lateral_max_m, lat);
    r.magnitude_max_m = std::max(r.magnitude_max_m, mag);
    r.volume_change_m3 += vertex_volume[i];
    if (on_dome_top[i]) {
      dome_sum += area[i] * caudal;
      dome_area += area[i];
    }
    const auto band = static_cast<std::size_t>(std::clamp(static_cast<int>((1.0 - regions.height[i]) * 5.0), 0, 4));
    band_sum[band] += area[i] * caudal;
    band_area[band] += area[i];
  }
  for (RegionMotion& r : s.region) {
    if (r.area_m2 > 0.0) {
      r.caudal_mean_m /= r.area_m2;
      r.anterior_mean_m /= r.area_m2;
      r.lateral_mean_m /= r.area_m2;
      r.magnitude_mean_m /= r.area_m2;
    }
    r.volume_share = s.volume_change_m3 != 0.0 ? r.volume_change_m3 / s.volume_change_m3 : 0.0;
  }
  s.dome_top_caudal_m = dome_area > 0.0 ? dome_sum / dome_area : 0.0;
  for (std::size_t b = 0; b < 5; ++b) s.band_caudal_mean_m[b] = band_area[b] > 0.0 ? band_sum[b] / band_area[b] : 0.0;
  return s;
}

}  // namespace pneuma::mesh
