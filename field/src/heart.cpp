#include "pneuma/field/heart.h"

#include <algorithm>

#include "pneuma/core/error.h"

namespace pneuma::field {

std::vector<Eigen::Vector3d> heart_descent_field(const mesh::TriangleMesh& mesh, const mesh::SurfaceRegions& regions,
                                                 const HeartDescent& heart, double sigma) {
  if (!(heart.descent >= 0.0 && heart.descent <= 1.0 && heart.top > 0.1 && heart.top < 0.9))
    throw ValueError("heart_descent_field: expected a descent in [0, 1] and a top in (0.1, 0.9)");
  mesh::require_regions_of(regions, mesh, regions.axes, "heart_descent_field");
  const std::size_t n = mesh.vertices.size();
  std::vector<Eigen::Vector3d> moved(n, Eigen::Vector3d::Zero());
  if (!heart.active()) return moved;
  const std::vector<Eigen::Vector3d> normal = mesh::smoothed_normals(mesh, sigma);
  constexpr auto kMediastinal = static_cast<std::size_t>(mesh::Region::mediastinal);
  for (std::size_t i = 0; i < n; ++i) {
    const double u = std::clamp((regions.height[i] - (heart.top - 0.1)) / 0.2, 0.0, 1.0);
    const double below_top = 1.0 - u * u * (3.0 - 2.0 * u);
    const double facing_down = std::max(0.0, -regions.axes.up.dot(normal[i]));
    moved[i] = heart.descent * regions.weight[i][kMediastinal] * below_top * facing_down * -regions.axes.up;
  }
  return moved;
}

}  // namespace pneuma::field
