// The stretch across the lung's thin parts (field/thin_lung.h) on lenses and balls, against the
// closed form of a pair of faces giving up their excess strain in equal shares.
#include <gtest/gtest.h>

#include <cmath>

#include "pneuma/core/error.h"
#include "pneuma/field/thin_lung.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

using namespace pneuma;
using namespace pneuma::field;

namespace {

// An oblate spheroid: radius R across, half-thickness c; thickness 2 c sqrt(1 - r^2/R^2) at r.
mesh::TriangleMesh lens(double radius, double half_thickness) {
  mesh::TriangleMesh m = mesh::make_icosphere(1.0, 5);
  for (Eigen::Vector3d& x : m.vertices) x = Eigen::Vector3d(radius * x.x(), radius * x.y(), half_thickness * x.z());
  return m;
}

// The lower face descends by `descent`, the upper face stands still.
std::vector<Eigen::Vector3d> lower_face_descends(const mesh::TriangleMesh& m, double descent) {
  std::vector<Eigen::Vector3d> u(m.vertices.size(), Eigen::Vector3d::Zero());
  for (std::size_t i = 0; i < u.size(); ++i) {
    if (m.vertices[i].z() < 0.0) u[i] = Eigen::Vector3d(0.0, 0.0, -descent);
  }
  return u;
}

}  // namespace

// u = a x scales the surface by 1 + a: the volume grows by (1 + a)^3, to first order 3 a. The
// volume is homogeneous of degree 3 in the vertices, so the first-order sum is 3 a exactly.
TEST(ThinLung, MeanVolumeStrainOfAUniformExpansionIsThreeTimesItsStretch) {
  const mesh::TriangleMesh ball = mesh::make_icosphere(0.07, 3);
  std::vector<Eigen::Vector3d> u(ball.vertices.size());
  for (std::size_t i = 0; i < u.size(); ++i) u[i] = 0.01 * ball.vertices[i];
  EXPECT_NEAR(mean_volume_strain(ball, u), 0.03, 1e-12);
  EXPECT_THROW(mean_volume_strain(ball, std::vector<Eigen::Vector3d>(3)), ValueError);
}

// A lens 8 mm thick whose lower face descends 4 mm under a still upper face: across its middle
// the strain is 4 / 8 = 0.5, over the bound 0.25. Each face gives up half the excess along the
// (vertical) ray: the faces end up high t apart in motion, their mean motion kept (the lens is
// thinner than 10 mm: the full excess), so at radius r
// the upper face descends (D - high t(r)) / 2 and the lower D - (D - high t(r)) / 2,
// t(r) = 2 c sqrt(1 - r^2 / R^2). No horizontal motion appears.
TEST(ThinLung, AThinPartsTwoFacesGiveUpTheirExcessStretchInEqualShares) {
  const double radius = 0.1, half = 0.004, descent = 0.004, high = 0.25;
  const mesh::TriangleMesh m = lens(radius, half);
  std::vector<Eigen::Vector3d> u = lower_face_descends(m, descent);
  limit_the_stretch_across_thin_parts(m, u, high);
  int checked = 0;
  double worst = 0.0;
  for (std::size_t i = 0; i < u.size(); ++i) {
    const Eigen::Vector3d& x = m.vertices[i];
    const double r = std::hypot(x.x(), x.y());
    if (r > 0.03 || std::abs(x.z()) < 0.5 * half) continue;  // the middle, off the rim
    const double t = 2.0 * half * std::sqrt(1.0 - r * r / (radius * radius));
    const double given_up = 0.5 * (descent - high * t);
    const double expected = x.z() > 0.0 ? -given_up : -descent + given_up;
    worst = std::max(worst, std::abs(u[i].z() - expected));
    EXPECT_NEAR(u[i].x(), 0.0, 2e-5);
    EXPECT_NEAR(u[i].y(), 0.0, 2e-5);
    ++checked;
  }
  EXPECT_GT(checked, 100);
  EXPECT_LT(worst, 2e-5) << "of a 4 mm descent";  // 0.02 mm: the tilt of rays off the axis
}

// Where the strain across lies within the bound, nothing moves: the same lens with a 1 mm
// descent (strain 1 / t(r), in the bound out to r = 0.87 R, where t = 4 mm) keeps its field to
// the bit out to r = 0.5 R (the rim's change, averaged along the surface over 8 edges of 3.3 mm,
// reaches no nearer); a ball 200 mm across, thicker than the rays' reach, keeps the 4 mm
// field everywhere.
TEST(ThinLung, NothingMovesWhereTheLungIsThickForItsStretch) {
  const double radius = 0.1, half = 0.004;
  const mesh::TriangleMesh m = lens(radius, half);
  const std::vector<Eigen::Vector3d> before = lower_face_descends(m, 0.001);
  std::vector<Eigen::Vector3d> u = before;
  limit_the_stretch_across_thin_parts(m, u, 0.25);
  int kept = 0, moved_at_rim = 0;
  for (std::size_t i = 0; i < u.size(); ++i) {
    const double r = std::hypot(m.vertices[i].x(), m.vertices[i].y());
    if (r < 0.5 * radius) {
      EXPECT_EQ(u[i], before[i]) << "vertex " << i << " at r = " << r;
      ++kept;
    } else if (u[i] != before[i]) {
      ++moved_at_rim;
    }
  }
  EXPECT_GT(kept, 500);
  EXPECT_GT(moved_at_rim, 0);  // the rim, thinner than 4 mm, is held

  const mesh::TriangleMesh ball = mesh::make_icosphere(0.1, 4);
  const std::vector<Eigen::Vector3d> field = lower_face_descends(ball, 0.004);
  std::vector<Eigen::Vector3d> v = field;
  limit_the_stretch_across_thin_lung(ball, v);
  EXPECT_EQ(v, field);
}
