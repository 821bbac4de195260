// Area and volume of analytic shapes; CGAL's measures agree with the plain Eigen ones.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "mesh_fixture.h"
#include "pneuma/core/error.h"
#include "pneuma/mesh/geometry/validate.h"

using namespace pneuma::mesh;
using pneuma::mesh::test::make_cube;
using pneuma::mesh::test::make_torus;

namespace {
constexpr double pi = std::numbers::pi;
}

TEST(Measure, CubeIsExact) {
  const TriangleMesh c = make_cube(0.02, {0.1, -0.3, 0.05});  // away from the origin: volume is translation-invariant
  EXPECT_NEAR(surface_area(c), 6 * 0.02 * 0.02, 1e-15);
  EXPECT_NEAR(enclosed_volume(c), 0.02 * 0.02 * 0.02, 1e-17);
  EXPECT_NEAR(cgal_surface_area(c), 6 * 0.02 * 0.02, 1e-15);
  EXPECT_NEAR(cgal_enclosed_volume(c), 0.02 * 0.02 * 0.02, 1e-17);
}

TEST(Measure, IcosphereApproachesTheSphereAndCgalAgrees) {
  // Inscribed polyhedron: below the sphere, error O(h^2), i.e. about 4x smaller per level.
  const double r = 0.05;
  double previous = 1.0;
  for (int k = 1; k <= 5; ++k) {
    const TriangleMesh s = make_icosphere(r, k);
    const double a = surface_area(s), v = enclosed_volume(s);
    EXPECT_NEAR(cgal_surface_area(s), a, 1e-12 * a) << k;
    EXPECT_NEAR(cgal_enclosed_volume(s), v, 1e-12 * v) << k;
    const double area_error = 1 - a / (4 * pi * r * r), volume_error = 1 - v / (4.0 / 3.0 * pi * r * r * r);
    EXPECT_GT(area_error, 0.0);
    EXPECT_GT(volume_error, 0.0);
    // O(h^2) with h ~ r / 2^k: the deficit is about 0.51 / 4^k (0.127 at k = 1).
    EXPECT_LT(volume_error, 0.6 * std::pow(0.5, 2 * k)) << k;
    EXPECT_GT(volume_error, 0.4 * std::pow(0.5, 2 * k)) << k;
    if (k >= 3) {
      EXPECT_NEAR(previous / volume_error, 4.0, 0.3) << k;
    }
    previous = volume_error;
  }
}

TEST(Measure, TorusConvergesToPappus) {
  // Area 4 pi^2 R r and volume 2 pi^2 R r^2 (Pappus); the grid error halves twice per refinement.
  const double R = 0.1, r = 0.03;
  double previous = 0.0;
  for (int n : {32, 64, 128}) {
    const TriangleMesh t = make_torus(R, r, 2 * n, n);
    const double a = surface_area(t), v = enclosed_volume(t);
    EXPECT_NEAR(cgal_surface_area(t), a, 1e-12 * a);
    EXPECT_NEAR(cgal_enclosed_volume(t), v, 1e-12 * v);
    const double volume_error = std::abs(1 - v / (2 * pi * pi * R * r * r));
    EXPECT_LT(std::abs(1 - a / (4 * pi * pi * R * r)), 20.0 / (n * n));
    EXPECT_LT(volume_error, 20.0 / (n * n));
    if (previous > 0) {
      EXPECT_NEAR(previous / volume_error, 4.0, 0.4) << n;
    }
    previous = volume_error;
  }
}

TEST(Measure, CgalVolumeRefusesAnOpenSurface) {
  TriangleMesh c = make_cube(1.0);
  c.triangles.pop_back();
  EXPECT_THROW(cgal_enclosed_volume(c), pneuma::ValueError);
}
