#include "pneuma/field/heart.h"

#include <algorithm>
#include <array>

#include "pneuma/core/error.h"
#include "step_down.h"

namespace pneuma::field {

namespace {
// The band of the lung's height over which a face goes from under the diaphragm to not, below
// the dome's top (0.05: 10-13 mm of a CT lung).
constexpr double kUnderBand = 0.05;
// The surface around a face under the diaphragm, in space: about a recess's thickness.
constexpr double kUnderSigma = 1e-2;
// The costophrenic margin: the costal and diaphragmatic weights, and the normals, blurred in
// space at about the thickness of the lung's edge there (10-15 mm on case009's anterior recess),
// so both faces of the edge see the border between them and each other's normal.
constexpr double kMarginSigma = 1e-2;

using detail::step_down;
// The costal and diaphragmatic weights, blurred in space at kMarginSigma.
std::vector<Eigen::Vector2d> blurred_costal_and_diaphragmatic(const mesh::TriangleMesh& mesh,
                                                              const mesh::SurfaceRegions& regions,
                                                              const std::vector<double>& area) {
  std::vector<Eigen::Vector2d> weight(mesh.vertices.size());
  for (std::size_t i = 0; i < weight.size(); ++i)
    weight[i] = {regions.weight[i][static_cast<std::size_t>(mesh::Region::costal)],
                 regions.weight[i][static_cast<std::size_t>(mesh::Region::diaphragmatic)]};
  return mesh::blurred_in_space(mesh, area, weight, kMarginSigma);
}
// Per vertex: 1 - |the outward normal averaged in space|, 0 on a flat face, 0.3 at a right-angled
// edge, about 0.7 in an edge of 30 degrees (case009's anterior recess), 1 between opposite faces.
std::vector<double> thinness(const mesh::TriangleMesh& mesh, const std::vector<double>& area) {
  const std::vector<Eigen::Vector3d> around =
      mesh::blurred_in_space(mesh, area, mesh::vertex_normals(mesh), kMarginSigma);
  std::vector<double> thin(around.size());
  for (std::size_t i = 0; i < around.size(); ++i) thin[i] = std::clamp(1.0 - around[i].norm(), 0.0, 1.0);
  return thin;
}
// under_diaphragm() with the vertex areas given.
std::vector<double> under_diaphragm_given_areas(const mesh::TriangleMesh& mesh, const mesh::SurfaceRegions& regions,
                                                Margin margin, const std::vector<Eigen::Vector3d>& normal,
                                                const std::vector<double>& area) {
  mesh::require_regions_of(regions, mesh, regions.axes, "under_diaphragm");
  const std::size_t n = mesh.vertices.size();
  const std::vector<bool> on_top = mesh::dome_top_vertices(mesh, regions);
  double dome_top = -1.0;  // no dome: no face lies under it
  for (std::size_t i = 0; i < n; ++i) {
    if (on_top[i]) dome_top = std::max(dome_top, regions.height[i]);
  }
  if (normal.size() != n) throw ValueError("under_diaphragm: one smoothed normal per vertex");
  const bool with_margin = margin == Margin::moved;
  const std::vector<Eigen::Vector2d> costal_diaphragmatic =
      with_margin ? blurred_costal_and_diaphragmatic(mesh, regions, area) : std::vector<Eigen::Vector2d>{};
  const std::vector<double> thin = with_margin ? thinness(mesh, area) : std::vector<double>{};
  std::vector<double> under(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double looks_up = std::max(0.0, regions.axes.up.dot(normal[i]));
    const double on_the_margin =
        with_margin ? std::min(1.0, 4.0 * costal_diaphragmatic[i][0] * costal_diaphragmatic[i][1]) * thin[i] : 0.0;
    under[i] =
        step_down((regions.height[i] - (dome_top - kUnderBand)) / kUnderBand) * std::max(looks_up, on_the_margin);
  }
  return under;
}
}  // namespace

std::vector<Eigen::Vector3d> heart_descent_field(const mesh::TriangleMesh& mesh, const mesh::SurfaceRegions& regions,
                                                 const HeartDescent& heart, double sigma) {
  return heart_descent_field(mesh, regions, heart,
                             heart.active() ? mesh::smoothed_normals(mesh, sigma) : std::vector<Eigen::Vector3d>{});
}

std::vector<Eigen::Vector3d> heart_descent_field(const mesh::TriangleMesh& mesh, const mesh::SurfaceRegions& regions,
                                                 const HeartDescent& heart,
                                                 const std::vector<Eigen::Vector3d>& normal) {
  if (!(heart.descent >= 0.0 && heart.descent <= 1.0 && heart.top > 0.1 && heart.top < 0.9))
    throw ValueError("heart_descent_field: expected a descent in [0, 1] and a top in (0.1, 0.9)");
  mesh::require_regions_of(regions, mesh, regions.axes, "heart_descent_field");
  const std::size_t n = mesh.vertices.size();
  std::vector<Eigen::Vector3d> moved(n, Eigen::Vector3d::Zero());
  if (!heart.active()) return moved;
  if (normal.size() != n) throw ValueError("heart_descent_field: one smoothed normal per vertex");
  constexpr auto kMediastinal = static_cast<std::size_t>(mesh::Region::mediastinal);
  for (std::size_t i = 0; i < n; ++i) {
    const double below_top = step_down((regions.height[i] - (heart.top - 0.1)) / 0.2);
    const double facing_down = std::max(0.0, -regions.axes.up.dot(normal[i]));
    moved[i] = heart.descent * regions.weight[i][kMediastinal] * below_top * facing_down * -regions.axes.up;
  }
  return moved;
}

std::vector<double> under_diaphragm(const mesh::TriangleMesh& mesh, const mesh::SurfaceRegions& regions,
                                    Margin margin) {
  return under_diaphragm(mesh, regions, margin, mesh::smoothed_normals(mesh, kFaceNormalSigma));
}

std::vector<double> under_diaphragm(const mesh::TriangleMesh& mesh, const mesh::SurfaceRegions& regions, Margin margin,
                                    const std::vector<Eigen::Vector3d>& normal) {
  return under_diaphragm_given_areas(mesh, regions, margin, normal, mesh::vertex_areas(mesh));
}

void follow_the_diaphragm_over(const mesh::TriangleMesh& mesh, const mesh::SurfaceRegions& regions,
                               std::vector<Eigen::Vector3d>& u, Margin margin) {
  if (u.size() != mesh.vertices.size()) throw ValueError("follow_the_diaphragm_over: one displacement per vertex");
  follow_the_diaphragm_over(mesh, regions, u, margin, mesh::smoothed_normals(mesh, kFaceNormalSigma));
}

void follow_the_diaphragm_over(const mesh::TriangleMesh& mesh, const mesh::SurfaceRegions& regions,
                               std::vector<Eigen::Vector3d>& u, Margin margin,
                               const std::vector<Eigen::Vector3d>& face_normal) {
  if (u.size() != mesh.vertices.size()) throw ValueError("follow_the_diaphragm_over: one displacement per vertex");
  // The vertex areas once for the three blurs (each computed its own, #50).
  const std::vector<double> area = mesh::vertex_areas(mesh);
  const std::vector<double> under = under_diaphragm_given_areas(mesh, regions, margin, face_normal, area);
  const std::vector<Eigen::Vector3d> mean = mesh::blurred_in_space(mesh, area, u, kUnderSigma);
  for (std::size_t i = 0; i < u.size(); ++i) u[i] += under[i] * (mean[i] - u[i]);
}

}  // namespace pneuma::field
