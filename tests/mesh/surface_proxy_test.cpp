// The coarse proxy of a fine surface (mesh/geometry/surface_proxy.h) and what is read through it
// (smoothed_normals from a proxy), against analytic oracles: a sphere's volume and radial
// normals, fields known in closed form, two plates a thin part's width apart.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/mesh/anatomy/regions.h"
#include "pneuma/mesh/geometry/surface_proxy.h"

namespace pneuma::mesh {
namespace {

constexpr double kRadius = 0.05;  // a sphere of a lung's curvature
constexpr double kCell = 3e-3;

// An icosphere of 40,962 vertices, mean edge about 0.8 mm: fine enough for a proxy.
const TriangleMesh& fine_sphere() {
  static const TriangleMesh sphere = make_icosphere(kRadius, 6);
  return sphere;
}

// A flat square plate of side `side` at height z, n x n squares, facing +z (up) or -z.
TriangleMesh plate(double side, int n, double z, bool up) {
  TriangleMesh m;
  const double h = side / n;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) m.vertices.emplace_back(i * h, j * h, z);
  }
  auto id = [n](int i, int j) { return static_cast<std::uint32_t>(j * (n + 1) + i); };
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const Triangle a{id(i, j), id(i + 1, j), id(i + 1, j + 1)}, b{id(i, j), id(i + 1, j + 1), id(i, j + 1)};
      m.triangles.push_back(up ? a : Triangle{a[0], a[2], a[1]});
      m.triangles.push_back(up ? b : Triangle{b[0], b[2], b[1]});
    }
  }
  return m;
}

TEST(SurfaceProxy, EveryVertexLiesWithinACellDiagonalOfTheFineVertexStandingForIt) {
  const TriangleMesh& fine = fine_sphere();
  ASSERT_LT(mean_edge_length(fine), kProxyBelowEdgeM);
  const SurfaceProxy proxy = surface_proxy(fine, kCell);
  ASSERT_EQ(proxy.group.size(), fine.vertices.size());
  ASSERT_EQ(proxy.fine_vertex.size(), proxy.mesh.vertices.size());
  // At most a quarter of the vertices (cells of 3 mm over edges of 0.8 mm), at least one a cell.
  EXPECT_LT(proxy.mesh.vertices.size(), fine.vertices.size() / 4);
  const double area_per_cell = 4.0 * std::numbers::pi * kRadius * kRadius / (kCell * kCell);
  EXPECT_GT(static_cast<double>(proxy.mesh.vertices.size()), area_per_cell);
  for (std::size_t j = 0; j < proxy.fine_vertex.size(); ++j) {
    EXPECT_EQ(proxy.mesh.vertices[j], fine.vertices[proxy.fine_vertex[j]]);  // a fine vertex itself
    EXPECT_EQ(proxy.group[proxy.fine_vertex[j]], j);                         // standing for itself
    if (j > 0) {
      EXPECT_LT(proxy.fine_vertex[j - 1], proxy.fine_vertex[j]);  // in vertex order
    }
  }
  double farthest = 0.0;
  for (std::size_t i = 0; i < fine.vertices.size(); ++i)
    farthest = std::max(farthest, (fine.vertices[i] - proxy.mesh.vertices[proxy.group[i]]).norm());
  EXPECT_LE(farthest, std::sqrt(3.0) * proxy.cell_m);
  EXPECT_GT(farthest, 0.5 * proxy.cell_m);  // the groups do span their cells
}

TEST(SurfaceProxy, TheProxyOfASphereEnclosesTheSpheresVolume) {
  const SurfaceProxy proxy = surface_proxy(fine_sphere(), kCell);
  const double sphere = 4.0 / 3.0 * std::numbers::pi * std::pow(kRadius, 3);
  // Chords of about 3-5 mm on a 50 mm sphere cut off 1-3 % of it; holes or flipped triangles far more.
  EXPECT_NEAR(enclosed_volume(proxy.mesh) / sphere, 1.0, 0.03);
  EXPECT_NEAR(surface_area(proxy.mesh) / (4.0 * std::numbers::pi * kRadius * kRadius), 1.0, 0.03);
}

TEST(SurfaceProxy, IsBuiltOnlyBelowTheThresholdEdge) {
  EXPECT_TRUE(proxy_for(fine_sphere()));
  const TriangleMesh coarse = make_icosphere(kRadius, 4);  // mean edge about 3.4 mm
  ASSERT_GT(mean_edge_length(coarse), kProxyBelowEdgeM);
  EXPECT_FALSE(proxy_for(coarse));
  EXPECT_THROW(surface_proxy(coarse, 0.0), ValueError);
}

TEST(SurfaceProxy, ATransferredFieldIsExactWhenConstantAndWithinItsChangeOverTwoCellsElsewhere) {
  const TriangleMesh& fine = fine_sphere();
  const SurfaceProxy proxy = surface_proxy(fine, kCell);
  const double lambda = 0.02;  // a field varying over 20 mm, as the tissue's inputs do
  auto field = [lambda](const Eigen::Vector3d& x) {
    return Eigen::Vector3d(std::sin(x.x() / lambda), std::cos(x.y() / lambda), x.z() / lambda);
  };
  std::vector<Eigen::Vector3d> constant(proxy.mesh.vertices.size(), Eigen::Vector3d(1.0, -2.0, 3.0)), sampled;
  for (const Eigen::Vector3d& p : proxy.mesh.vertices) sampled.push_back(field(p));
  const std::vector<Eigen::Vector3d> one = transferred_to_fine(fine, proxy, constant);
  const std::vector<Eigen::Vector3d> moved = transferred_to_fine(fine, proxy, sampled);
  double worst = 0.0, mean = 0.0;
  for (std::size_t i = 0; i < fine.vertices.size(); ++i) {
    EXPECT_LT((one[i] - Eigen::Vector3d(1.0, -2.0, 3.0)).norm(), 1e-12);
    const double error = (moved[i] - field(fine.vertices[i])).norm();
    worst = std::max(worst, error);
    mean += error / static_cast<double>(fine.vertices.size());
  }
  // Each value a weighted mean of samples within 2 cells: off by at most |grad| x 2 cells
  // (|grad| <= sqrt(3) / lambda); on average far less (the weights centre on the vertex).
  EXPECT_LT(worst, std::sqrt(3.0) / lambda * 2.0 * proxy.cell_m);
  EXPECT_LT(mean, 0.25 * std::sqrt(3.0) / lambda * proxy.cell_m);
  EXPECT_THROW(transferred_to_fine(fine, proxy, std::vector<Eigen::Vector3d>(3)), ValueError);
}

TEST(SurfaceProxy, TheTwoFacesOfAPartThinnerThanACellKeepTheirOwnValues) {
  // Two plates 1.5 mm apart, facing away from each other: a thin part's two faces in one cell.
  TriangleMesh both = plate(0.06, 80, 0.0, false);
  const TriangleMesh top = plate(0.06, 80, 1.5e-3, true);
  const auto offset = static_cast<std::uint32_t>(both.vertices.size());
  both.vertices.insert(both.vertices.end(), top.vertices.begin(), top.vertices.end());
  for (Triangle t : top.triangles) both.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  const SurfaceProxy proxy = surface_proxy(both, kCell);
  std::vector<Eigen::Vector3d> value(proxy.mesh.vertices.size());
  for (std::size_t j = 0; j < value.size(); ++j)
    value[j] = Eigen::Vector3d(0.0, 0.0, proxy.fine_vertex[j] < offset ? -1.0 : 1.0);
  const std::vector<Eigen::Vector3d> back = transferred_to_fine(both, proxy, value);
  for (std::size_t i = 0; i < both.vertices.size(); ++i)
    ASSERT_EQ(back[i].z(), i < offset ? -1.0 : 1.0) << "vertex " << i;
}

TEST(SurfaceProxy, NormalsSmoothedFromTheProxyOfASphereAreRadial) {
  const TriangleMesh& fine = fine_sphere();
  const SurfaceProxy proxy = surface_proxy(fine, kCell);
  for (const double sigma : {3e-3, 1e-2, 2e-2}) {
    const std::vector<Eigen::Vector3d> normal = smoothed_normals(fine, &proxy, sigma);
    ASSERT_EQ(normal.size(), fine.vertices.size());
    double worst = 0.0;
    for (std::size_t i = 0; i < normal.size(); ++i)
      worst = std::max(worst, std::acos(std::min(1.0, normal[i].dot(fine.vertices[i].normalized()))));
    // The blurred normal field of a sphere is radial by symmetry: off only by the proxy's facets.
    EXPECT_LT(worst * 180.0 / std::numbers::pi, 2.0) << "sigma " << sigma;
  }
  EXPECT_THROW(smoothed_normals(make_icosphere(kRadius, 3), &proxy, 3e-3), ValueError);
}

}  // namespace
}  // namespace pneuma::mesh
