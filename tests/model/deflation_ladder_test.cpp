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

// The pull-back of a deflation, counted on the deformed surface: the largest |v_i - v_j| / |y_i - y_j|
// over every pair, y = x + d the deflated points and v = -d their pull-backs to the rest surface.
double pull_back_slope(const std::vector<Eigen::Vector3d>& x, const std::vector<Eigen::Vector3d>& d) {
  std::vector<Eigen::Vector3d> y(x.size()), v(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    y[i] = x[i] + d[i];
    v[i] = -d[i];
  }
  return slope_over_all_pairs(y, v);
}

// The ladder asks, besides the contraction at 1.5 times the depth, that at the depth itself no two
// pull-backs part by more than their points' distance (#45's neighbour check on the voxels' pull-back
// DVF): a sphere shrunk radially whose field also compresses it along z by a wave (u_z = a sin(k z):
// the belts where cos(k z) > 0 close to about half their height at the depth) passes the older
// rules unsmoothed (no self-intersection and a contraction at 1.5 times the depth, both checked
// here directly) while its pull-back, counted over every pair of the deflated sphere, parts
// neighbours by more than their distance; the ladder smooths it until the pull-back of the field it
// keeps does not, by the same count.
TEST(DeflationLadder, APullBackThatPartsNeighboursIsSmoothedUntilItDoesNot) {
  const mesh::TriangleMesh sphere = mesh::make_icosphere(0.05, 4);  // 2562 vertices, edges about 4 mm
  const double depth_m3 = 100e-6;                                   // 100 mL of its 524 mL
  const double k = 2.0 * std::numbers::pi / 0.04;                   // a wave of 40 mm along z
  const std::vector<Eigen::Vector3d> u = field_at(sphere.vertices, [&](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return 1e-3 * p.normalized() + Eigen::Vector3d(0.0, 0.0, 1e-3 * std::sin(k * p.z()));
  });
  // The older rules pass: at 1.5 times the depth the mirror neither crosses itself nor stretches a pair.
  const double s_margin = scale_at_depth(sphere, u, 1.5 * depth_m3);
  const std::vector<Eigen::Vector3d> d_margin = times(s_margin, u);
  mesh::TriangleMesh moved = sphere;
  for (std::size_t i = 0; i < d_margin.size(); ++i) moved.vertices[i] += d_margin[i];
  ASSERT_FALSE(mesh::self_intersects(moved));
  const double slope_margin = slope_over_all_pairs(sphere.vertices, d_margin);
  EXPECT_LT(slope_margin, 1.0);
  // But at the depth the pull-back parts neighbours by more than their distance.
  const double unsmoothed = pull_back_slope(sphere.vertices, times(scale_at_depth(sphere, u, depth_m3), u));
  EXPECT_GT(unsmoothed, 1.0);
  std::cout << "unsmoothed: slope " << slope_margin << " at 1.5 times the depth, pull-back slope " << unsmoothed
            << " at the depth\n";
  const DeflationField field = field_for_deflation(sphere, u, depth_m3);
  ASSERT_GT(field.sigma_m, 0.0);
  EXPECT_TRUE(field.passes);
  const double kept = pull_back_slope(
      sphere.vertices, times(scale_at_depth(sphere, field.unit_displacement, depth_m3), field.unit_displacement));
  std::cout << "smoothed at " << field.sigma_m * 1e3 << " mm: pull-back slope " << kept << "\n";
  EXPECT_LE(kept, 1.0);
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
