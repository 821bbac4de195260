// The volume cubic against the directly measured volume, and its inversion.
#include "pneuma/model/volume_scale.h"

#include <gtest/gtest.h>

#include <cmath>

#include "pneuma/core/error.h"

using pneuma::model::VolumeScaleMap;
using namespace pneuma::mesh;

namespace {

// A smooth, non-uniform outward field: larger near the bottom, with a sideways component.
std::vector<Eigen::Vector3d> wavy_field(const TriangleMesh& m) {
  const auto n = vertex_normals(m);
  std::vector<Eigen::Vector3d> u(m.vertex_count());
  for (std::size_t i = 0; i < u.size(); ++i) {
    const auto& p = m.vertices[i];
    u[i] = (1.5 - p.z() / 0.1) * 1e-3 * n[i] + Eigen::Vector3d(0.2e-3 * std::sin(40 * p.y()), 0, 0);
  }
  return u;
}

}  // namespace

TEST(VolumeScale, CubicEqualsTheMeasuredVolumeOfTheDeformedMesh) {
  const TriangleMesh m = make_icosphere(0.1, 3);
  const auto u = wavy_field(m);
  const VolumeScaleMap map(m.vertices, u, m.triangles);
  EXPECT_NEAR(map.coefficients()[0], enclosed_volume(m), 1e-15);
  for (double s : {-20.0, -3.0, 0.5, 7.0, 40.0}) {
    std::vector<Eigen::Vector3d> x(m.vertices);
    for (std::size_t i = 0; i < x.size(); ++i) x[i] += s * u[i];
    const double measured = enclosed_volume(x, m.triangles);
    EXPECT_NEAR(map.volume(s), measured, 1e-12 * std::abs(measured)) << "s = " << s;
  }
}

TEST(VolumeScale, InversionRecoversTheScaleFromAnyGuess) {
  const TriangleMesh m = make_icosphere(0.1, 3);
  const VolumeScaleMap map(m.vertices, wavy_field(m), m.triangles);
  for (double s : {-10.0, -0.1, 0.0, 0.3, 5.0, 25.0}) {
    for (double guess : {0.0, s, 100.0, -50.0}) {
      EXPECT_NEAR(map.scale_for(map.volume(s), guess), s, 1e-9 * std::max(1.0, std::abs(s)));
    }
  }
}

TEST(VolumeScale, MonotoneRangeEndsWhereTheSlopeVanishes) {
  // V(s) = 1 + s - s^3 / 3: V' = 1 - s^2 vanishes at -1 and 1, so volumes between 1 - 2/3 and
  // 1 + 2/3 are reachable and nothing else is.
  const VolumeScaleMap map({1.0, 1.0, 0.0, -1.0 / 3.0});
  EXPECT_DOUBLE_EQ(map.min_scale(), -1.0);
  EXPECT_DOUBLE_EQ(map.max_scale(), 1.0);
  EXPECT_DOUBLE_EQ(map.max_volume(), 5.0 / 3.0);
  EXPECT_NEAR(map.scale_for(1.5), 0.5578746983315245, 1e-12);  // root of s - s^3/3 = 0.5 in (0, 1), by bisection
  EXPECT_THROW(map.scale_for(1.7), pneuma::UnsupportedError);
  EXPECT_THROW(map.scale_for(0.3), pneuma::UnsupportedError);
}

TEST(VolumeScale, AUniformlyGrowingSphereIsMonotoneEverywhere) {
  // u = x / r * 1e-3 on a sphere of radius r = 0.1: V(s) = V0 (1 + s / 100)^3, whose slope only
  // touches zero at s = -100 (where the sphere collapses to a point).
  const TriangleMesh m = make_icosphere(0.1, 2);
  std::vector<Eigen::Vector3d> u(m.vertex_count());
  for (std::size_t i = 0; i < u.size(); ++i) u[i] = m.vertices[i] / 0.1 * 1e-3;
  const VolumeScaleMap map(m.vertices, u, m.triangles);
  EXPECT_NEAR(map.volume(-100.0), 0.0, 1e-15);
  EXPECT_NEAR(map.volume(100.0), 8.0 * enclosed_volume(m), 1e-12);
  EXPECT_NEAR(map.scale_for(8.0 * enclosed_volume(m)), 100.0, 1e-9);
}
