// The deflation's ladder (model::field_for_deflation, docs/voxels.md "The scan's place on the
// breath") asks that the field it keeps be a contraction on the surface at 1.5 times the depth:
// on a sphere sheared along itself, which never self-intersects but stretches pairs of points
// apart, the field is smoothed until the slope over every pair, counted directly, is below 1, and
// the ladder's step below still stretches a pair; without the shear the field is kept as it is.
#include <gtest/gtest.h>

#include <iostream>
#include <numbers>
#include <vector>

#include "../field/pair_slope.h"
#include "pneuma/field/deflation.h"
#include "pneuma/mesh/geometry/surface_queries.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"
#include "pneuma/model/model.h"
#include "pneuma/model/volume_scale.h"

namespace pneuma::model {
namespace {

using test::field_at;
using test::slope_over_all_pairs;
using test::times;

// The sphere's volume `depth_m3` below its rest volume under rest + s u: s.
double scale_at_depth(const mesh::TriangleMesh& rest, const std::vector<Eigen::Vector3d>& u, double depth_m3) {
  const VolumeScaleMap map(rest.vertices, u, rest.triangles);
  return map.scale_for(map.volume(0.0) - depth_m3);
}

// The deflation's ladder asks for a contraction: a sphere whose field shrinks it radially and
// shears it along itself (each ring of latitude turned about the axis by a wave in z, a map
// that is one to one at any amplitude: the surface never crosses itself) is smoothed once the
// shear stretches pairs apart at 1.5 times the depth, and the field it keeps is then a contraction
// there by every pair counted directly; without the shear the field is kept as it is.
TEST(DeflationLadder, AFieldThatStretchesPairsApartIsSmoothedUntilItContracts) {
  const mesh::TriangleMesh sphere = mesh::make_icosphere(0.05, 4);  // 2562 vertices, edges about 4 mm
  const double depth_m3 = 100e-6;                                   // 100 mL of its 524 mL
  const double k = 2.0 * std::numbers::pi / 0.02;                   // a shear of 20 mm wavelength
  for (const double shear : {0.0, 1.5e-3}) {
    const std::vector<Eigen::Vector3d> u = field_at(sphere.vertices, [&](const Eigen::Vector3d& p) -> Eigen::Vector3d {
      return 1e-3 * p.normalized() + shear * std::sin(k * p.z()) * Eigen::Vector3d(-p.y(), p.x(), 0.0) / 0.05;
    });
    const double s = scale_at_depth(sphere, u, 1.5 * depth_m3);
    ASSERT_LT(s, -4.0);  // the radius shrinks by about 5 mm
    const std::vector<Eigen::Vector3d> d = times(s, u);
    mesh::TriangleMesh moved = sphere;
    for (std::size_t i = 0; i < d.size(); ++i) moved.vertices[i] += d[i];
    ASSERT_FALSE(mesh::self_intersects(moved)) << shear;
    const double unsmoothed = slope_over_all_pairs(sphere.vertices, d);
    const DeflationField field = field_for_deflation(sphere, u, depth_m3);
    if (shear == 0.0) {
      EXPECT_LT(unsmoothed, 0.2);  // |s| / radius: about 0.1
      EXPECT_EQ(field.sigma_m, 0.0);
      EXPECT_EQ(field.unit_displacement, u);
      EXPECT_TRUE(field.passes);
      continue;
    }
    EXPECT_GT(unsmoothed, 2.0);  // |s| shear k: about 2.5 at the equator
    ASSERT_GT(field.sigma_m, 0.0);
    EXPECT_TRUE(field.passes);
    std::cout << "the sheared sphere's field is smoothed at " << field.sigma_m * 1e3 << " mm\n";
    const double s_kept = scale_at_depth(sphere, field.unit_displacement, 1.5 * depth_m3);
    EXPECT_LT(slope_over_all_pairs(sphere.vertices, times(s_kept, field.unit_displacement)), 1.0)
        << field.sigma_m * 1e3 << " mm";
    // The least smoothing that works: the ladder's step below it still stretches a pair apart.
    const double below =
        field.sigma_m > 2.1e-3 ? (field.sigma_m > 8.1e-3 ? field.sigma_m - 4e-3 : field.sigma_m - 2e-3) : 0.0;
    const std::vector<Eigen::Vector3d> less = field::smooth_field_in_space(sphere, u, below);
    const double s_less = scale_at_depth(sphere, less, 1.5 * depth_m3);
    EXPECT_GE(slope_over_all_pairs(sphere.vertices, times(s_less, less)), 1.0) << below * 1e3 << " mm";
  }
}

// A field that no step of the ladder makes deflate cleanly says so (the run then warns): a shear
// of a wavelength longer than the sphere (200 mm), which the last step (16 mm) leaves nearly
// whole and whose swirl swells the sphere faster than its radial part shrinks it, so that the
// sphere cannot reach 1.5 times the depth below its rest volume under any scale of the field kept
// (the volume map's own reach says so, independently of the ladder).
TEST(DeflationLadder, AFieldNoStepMakesDeflateCleanlySaysSo) {
  const mesh::TriangleMesh sphere = mesh::make_icosphere(0.05, 3);  // 642 vertices
  const double depth_m3 = 100e-6;
  const double k = 2.0 * std::numbers::pi / 0.2;
  const std::vector<Eigen::Vector3d> u = field_at(sphere.vertices, [&](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return 1e-3 * p.normalized() + 1e-2 * std::sin(k * p.z()) * Eigen::Vector3d(-p.y(), p.x(), 0.0) / 0.05;
  });
  const DeflationField field = field_for_deflation(sphere, u, depth_m3);
  EXPECT_FALSE(field.passes);
  EXPECT_EQ(field.sigma_m, 16e-3);  // the last step's field
  const VolumeScaleMap map(sphere.vertices, field.unit_displacement, sphere.triangles);
  EXPECT_FALSE(map.reachable(map.volume(0.0) - 1.5 * depth_m3));
}

}  // namespace
}  // namespace pneuma::model
