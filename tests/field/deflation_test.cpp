// The field smoothed in space for a deflation below the scan (field/deflation.h, #45), checked
// against invariants that do not depend on how it is computed: on a sphere a radial field stays
// radial (symmetry) with the same first-order area rate (the area unit kept, mesh::area_gradient);
// a field with a step across the equator gets a spatial slope of at most its range over sigma
// (the bound the smoothing is for) where it had one of its range over an edge; the same bits at
// one and at two threads; sigma 0 returns the field untouched. The contraction test
// (field::is_contraction, steepest_pair_slope) against displacements whose Lipschitz constant is
// known in closed form and against the slope over every pair counted directly (the deflation's
// ladder that uses it: tests/model/deflation_ladder_test.cpp).
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include "pair_slope.h"
#include "pneuma/core/error.h"
#include "pneuma/field/deflation.h"
#include "pneuma/mesh/geometry/surface_queries.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::field {
namespace {

using test::field_at;
using test::slope_over_all_pairs;
using test::times;

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
  EXPECT_THROW(is_contraction(sphere.vertices, std::vector<Eigen::Vector3d>(3)), ValueError);
  EXPECT_THROW(steepest_pair_slope(sphere.vertices, std::vector<Eigen::Vector3d>(3), 1.0), ValueError);
  std::vector<Eigen::Vector3d> not_finite(sphere.vertices.size(), Eigen::Vector3d::Zero());
  not_finite[7].y() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(is_contraction(sphere.vertices, not_finite), ValueError);
  EXPECT_THROW(steepest_pair_slope(sphere.vertices, not_finite, 1.0), ValueError);
}

// A 13 x 13 x 13 lattice of 5 mm (60 mm across).
std::vector<Eigen::Vector3d> lattice() {
  std::vector<Eigen::Vector3d> x;
  for (int i = 0; i < 13; ++i) {
    for (int j = 0; j < 13; ++j) {
      for (int k = 0; k < 13; ++k) x.emplace_back(5e-3 * i, 5e-3 * j, 5e-3 * k);
    }
  }
  return x;
}

// d(x) = A x has the Lipschitz constant of A's largest singular value, reached by every pair
// along its right singular vector (the lattice's x axis here): the contraction test flips there.
TEST(Contraction, ALinearMapsSlopeIsItsLargestSingularValue) {
  const std::vector<Eigen::Vector3d> x = lattice();
  Eigen::Matrix3d rotation;  // about x, so that x stays A's top right singular vector
  const double a = 0.7;
  rotation << 1, 0, 0, 0, std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a);
  for (const double sigma : {0.5, 0.99, 1.01, 1.5}) {
    const Eigen::Matrix3d map = rotation * Eigen::Vector3d(sigma, 0.4, -0.3).asDiagonal();
    const std::vector<Eigen::Vector3d> d =
        field_at(x, [&](const Eigen::Vector3d& p) -> Eigen::Vector3d { return map * p; });
    EXPECT_NEAR(steepest_pair_slope(x, d, 1.0), sigma, 1e-12) << sigma;
    EXPECT_EQ(is_contraction(x, d), sigma < 1.0) << sigma;
  }
}

// d = a sin(k (x - h / 2)) along y: Lipschitz constant a k, which the pairs of the h = 5 mm lattice
// straddling a zero of the sine reach to within the chord's shortfall (sin(k h / 2) / (k h / 2),
// 0.9886 here).
TEST(Contraction, AWaveSlopeIsItsAmplitudeTimesItsWavenumber) {
  const std::vector<Eigen::Vector3d> x = lattice();
  const double k = 2.0 * std::numbers::pi / 0.06;  // one wavelength across the lattice
  for (const double lipschitz : {0.8, 1.2}) {
    const std::vector<Eigen::Vector3d> d = field_at(x, [&](const Eigen::Vector3d& p) {
      return Eigen::Vector3d(0.0, lipschitz / k * std::sin(k * (p.x() - 2.5e-3)), 0.0);
    });
    const double slope = steepest_pair_slope(x, d, 1.0);
    EXPECT_NEAR(slope, lipschitz * std::sin(k * 2.5e-3) / (k * 2.5e-3), 1e-12);
    EXPECT_EQ(is_contraction(x, d), lipschitz < 1.0) << lipschitz;
  }
}

// Only pairs closer than 2 max |d| can fail, and is_contraction visits no other: two clusters
// 40 mm apart pushed towards each other fail exactly when their gap closes (2 a >= 40 mm), whatever
// the grid; random fields agree with every pair counted directly, at one thread and at all.
TEST(Contraction, FarPairsAreFoundAndEveryPairAgreesWithTheDirectCount) {
  std::vector<Eigen::Vector3d> x;
  for (int a = 0; a < 4; ++a) {
    for (int b = 0; b < 5; ++b) {
      x.emplace_back(1e-3 * a, 1e-3 * b, 0.0);
      x.emplace_back(1e-3 * a, 1e-3 * b, 0.04);
    }
  }
  for (const double push : {0.0195, 0.0205}) {
    const std::vector<Eigen::Vector3d> d =
        field_at(x, [&](const Eigen::Vector3d& p) { return Eigen::Vector3d(0.0, 0.0, p.z() > 0.0 ? -push : push); });
    EXPECT_NEAR(slope_over_all_pairs(x, d), 2.0 * push / 0.04, 1e-12);
    EXPECT_EQ(is_contraction(x, d), 2.0 * push < 0.04) << push;
  }
  std::mt19937 random(45);
  std::uniform_real_distribution<double> place(-0.05, 0.05);
  std::normal_distribution<double> wobble(0.0, 1.0);
  for (const double scale : {0.002, 0.004, 0.006, 0.01}) {
    std::vector<Eigen::Vector3d> points, d;
    for (int i = 0; i < 600; ++i) {
      const Eigen::Vector3d p(place(random), place(random), place(random));
      points.push_back(p);
      // Smooth (a slope of about scale / 0.02 m) plus a little noise, so that the ratios spread.
      d.push_back(scale * Eigen::Vector3d(std::sin(p.y() / 0.02), std::cos(p.z() / 0.02), std::sin(p.x() / 0.02)) +
                  1e-4 * Eigen::Vector3d(wobble(random), wobble(random), wobble(random)));
    }
    const double every_pair = slope_over_all_pairs(points, d);
    double largest = 0.0;
    for (const Eigen::Vector3d& v : d) largest = std::max(largest, v.norm());
    // The same ratios, one rounded as sqrt(a / b), the other as |a| / |b|: equal to an ulp or two.
    const double threaded = steepest_pair_slope(points, d, 1.0);
    EXPECT_NEAR(threaded, every_pair, 1e-14 * every_pair) << scale;
    EXPECT_EQ(is_contraction(points, d), every_pair < 1.0) << scale << ": " << every_pair;
    const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    EXPECT_EQ(steepest_pair_slope(points, d, 1.0), threaded) << scale;  // the same bits on one thread
    EXPECT_EQ(steepest_pair_slope(points, d, 2.0 * largest), threaded) << scale;
    EXPECT_EQ(is_contraction(points, d), every_pair < 1.0) << scale;
  }
}

}  // namespace
}  // namespace pneuma::field
