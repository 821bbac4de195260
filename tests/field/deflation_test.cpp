// The field smoothed in space for a deflation below the scan (field/deflation.h, #45), checked
// against invariants that do not depend on how it is computed: on a sphere a radial field stays
// radial (symmetry) with the same first-order area rate (the area unit kept, mesh::area_gradient);
// a field with a step across the equator gets a spatial slope of at most its range over sigma
// (the bound the smoothing is for) where it had one of its range over an edge; the same bits at
// one and at two threads; sigma 0 returns the field untouched.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>

#include "pneuma/core/error.h"
#include "pneuma/field/deflation.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::field {
namespace {

double area_rate(const mesh::TriangleMesh& m, const std::vector<Eigen::Vector3d>& u) {
  const std::vector<Eigen::Vector3d> g = mesh::area_gradient(m);
  double rate = 0.0;
  for (std::size_t i = 0; i < u.size(); ++i) rate += g[i].dot(u[i]);
  return rate;
}

// The largest |u_i - u_j| / |x_i - x_j| over the edges of the mesh.
double steepest_edge_slope(const mesh::TriangleMesh& m, const std::vector<Eigen::Vector3d>& u) {
  double steepest = 0.0;
  for (const mesh::Triangle& t : m.triangles) {
    for (std::size_t a = 0; a < 3; ++a) {
      const std::uint32_t i = t[a], j = t[(a + 1) % 3];
      steepest = std::max(steepest, (u[i] - u[j]).norm() / (m.vertices[i] - m.vertices[j]).norm());
    }
  }
  return steepest;
}

TEST(DeflationField, ARadialFieldStaysRadialWithItsAreaRate) {
  const mesh::TriangleMesh sphere = mesh::make_icosphere(0.05, 4);
  std::vector<Eigen::Vector3d> u;
  for (const Eigen::Vector3d& x : sphere.vertices) u.push_back(x / 0.05 * 1e-4);
  const std::vector<Eigen::Vector3d> smooth = smooth_field_in_space(sphere, u, 8e-3);
  for (std::size_t i = 0; i < u.size(); ++i) {
    EXPECT_LT(smooth[i].normalized().cross(sphere.vertices[i].normalized()).norm(), 1e-3) << i;
    EXPECT_NEAR(smooth[i].norm() / u[i].norm(), 1.0, 0.02) << i;
  }
  EXPECT_NEAR(area_rate(sphere, smooth) / area_rate(sphere, u), 1.0, 1e-12);
  EXPECT_EQ(smooth_field_in_space(sphere, u, 0.0), u);
}

TEST(DeflationField, AStepGetsASlopeOfAtMostItsRangeOverSigmaTheSameAtAnyThreadCount) {
  const mesh::TriangleMesh sphere = mesh::make_icosphere(0.05, 4);  // edges about 4 mm
  // Outward 1 mm per unit below the equator (a diaphragm), 0 above (a face that stands still).
  std::vector<Eigen::Vector3d> u;
  for (const Eigen::Vector3d& x : sphere.vertices)
    u.push_back(x.z() < 0.0 ? Eigen::Vector3d(x / x.norm() * 1e-3) : Eigen::Vector3d::Zero());
  const double range = 1e-3;
  ASSERT_GT(steepest_edge_slope(sphere, u), range / 5e-3);
  for (const double sigma : {6e-3, 12e-3}) {
    const std::vector<Eigen::Vector3d> smooth = smooth_field_in_space(sphere, u, sigma);
    EXPECT_LT(steepest_edge_slope(sphere, smooth), 1.1 * range / sigma) << sigma * 1e3 << " mm";
    std::vector<Eigen::Vector3d> one_thread;
    {
      const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
      one_thread = smooth_field_in_space(sphere, u, sigma);
    }
    EXPECT_EQ(one_thread, smooth);
  }
}

TEST(DeflationField, SizesThatDoNotMatchAreRefused) {
  const mesh::TriangleMesh sphere = mesh::make_icosphere(0.05, 1);
  EXPECT_THROW(smooth_field_in_space(sphere, std::vector<Eigen::Vector3d>(3), 1e-3), ValueError);
}

}  // namespace
}  // namespace pneuma::field
