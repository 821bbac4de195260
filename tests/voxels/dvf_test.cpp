// Forward and pull-back DVFs and Jacobians of an affine motion of a tetrahedralised cube, against
// the motion's closed forms.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cmath>
#include <cstring>
#include <optional>
#include <utility>

#include "pneuma/core/error.h"
#include "pneuma/voxels/dvf.h"
#include "pneuma/voxels/jacobian.h"
#include "tet_fixtures.h"

namespace pneuma::voxels {
namespace {

// The fields are stored as float32 (dvf.h): half an ulp per component, sqrt(3) of it for a
// vector, over the largest value, and the double computation's own 1e-12.
constexpr double kFloat32 = 0.5 * 1.1920929e-7 * 1.7320508 + 1e-12;

struct AffineCube {
  Eigen::Vector3d origin_m{0.010, -0.020, 0.030};
  double h_m = 5e-3;
  int cells = 4;
  double length_m() const { return h_m * cells; }
  mesh::TetMesh mesh = test::cube_cells(origin_m, h_m, cells);
  Eigen::Matrix3d a = (Eigen::Matrix3d() << 0.05, 0.02, -0.01, 0.01, -0.04, 0.03, 0.02, 0.01, 0.06).finished();
  Eigen::Vector3d b{1e-3, -2e-3, 0.5e-3};
  double s = 0.7;
  std::vector<Eigen::Vector3d> u = test::affine_field(mesh, a, b);
  // Axes turned about (1, 2, 3), anisotropic voxels, centred on the cube.
  Grid grid =
      test::oblique_grid({56, 56, 56}, Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix(),
                         Eigen::Vector3d(1.1e-3, 1.3e-3, 0.9e-3),
                         origin_m + Eigen::Vector3d::Constant(length_m() / 2) -
                             Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix() *
                                 Eigen::Vector3d(1.1e-3, 1.3e-3, 0.9e-3).cwiseProduct(Eigen::Vector3d::Constant(27.5)));

  std::vector<LungMotion> lungs() const { return {LungMotion{mesh, u, s}}; }
  // +1 inside the rest cube, -1 outside, 0 within 1e-9 of its faces.
  int side(const Eigen::Vector3d& p) const {
    const Eigen::Vector3d local = (p - origin_m) / length_m();
    if (local.minCoeff() > 1e-9 && local.maxCoeff() < 1 - 1e-9) return 1;
    if (local.minCoeff() < -1e-9 || local.maxCoeff() > 1 + 1e-9) return -1;
    return 0;
  }
  // The rest point that x + s (A x + b) carries to y.
  Eigen::Vector3d inverse(const Eigen::Vector3d& y) const {
    return (Eigen::Matrix3d::Identity() + s * a).lu().solve(y - s * b);
  }
};

TEST(ForwardDvf, AffineMotionIsReproducedAtEveryVoxelInside) {
  const AffineCube cube;
  const DisplacementField f = forward_dvf(cube.grid, cube.lungs());
  double largest_m = 0.0;
  for (const Eigen::Vector3d& x : cube.mesh.nodes)
    largest_m = std::max(largest_m, (cube.s * (cube.a * x + cube.b)).norm());
  std::size_t inside = 0;
  for (std::size_t k = 0; k < cube.grid.size[2]; ++k)
    for (std::size_t j = 0; j < cube.grid.size[1]; ++j)
      for (std::size_t i = 0; i < cube.grid.size[0]; ++i) {
        const std::size_t v = cube.grid.index(i, j, k);
        const Eigen::Vector3d x = cube.grid.centre_m(i, j, k);
        const int side = cube.side(x);
        if (side == 1) {
          EXPECT_EQ(f.lung[v], 1) << i << " " << j << " " << k;
        }
        if (side == -1) {
          EXPECT_EQ(f.lung[v], 0) << i << " " << j << " " << k;
        }
        if (f.lung[v] == 0) {
          EXPECT_EQ(f.displacement_m[v], Eigen::Vector3f::Zero());
          continue;
        }
        ++inside;
        EXPECT_LE((f.displacement_m[v].cast<double>() - cube.s * (cube.a * x + cube.b)).norm(), kFloat32 * largest_m);
      }
  // About the cube's volume in voxels.
  const double expected = std::pow(cube.length_m(), 3) / cube.grid.voxel_volume_m3();
  EXPECT_NEAR(static_cast<double>(inside), expected, 0.05 * expected);
  EXPECT_EQ(f.inside_count(), inside);
}

// The rest tets kept between time points (RestRaster): the second scale's field, replayed, is
// s (A x + b) at every lung voxel as the first's is, and bit for bit the field rasterised afresh;
// other lungs (a node moved) are rasterised again, not replayed, and kept in place of the first.
TEST(ForwardDvf, ARestRasterReplayedGivesTheFieldRasterisedAfresh) {
  const AffineCube cube;
  RestRaster rest;
  DisplacementField kept;
  for (const double s : {0.7, -0.4, 1.3}) {
    std::vector<LungMotion> lungs = cube.lungs();
    lungs[0].scale = s;
    forward_dvf(cube.grid, lungs, kept, {}, &rest);
    ASSERT_TRUE(rest.holds(cube.grid, lungs));
    const DisplacementField fresh = forward_dvf(cube.grid, lungs);
    EXPECT_EQ(kept.lung, fresh.lung) << s;
    ASSERT_EQ(kept.displacement_m.size(), fresh.displacement_m.size());
    EXPECT_EQ(std::memcmp(kept.displacement_m.data(), fresh.displacement_m.data(),
                          fresh.displacement_m.size() * sizeof(Eigen::Vector3f)),
              0)
        << s;
    double largest_m = 0.0;
    for (const Eigen::Vector3d& x : cube.mesh.nodes)
      largest_m = std::max(largest_m, (s * (cube.a * x + cube.b)).norm());
    std::size_t inside = 0;
    for (std::size_t v = 0; v < kept.lung.size(); ++v) {
      if (kept.lung[v] == 0) continue;
      ++inside;
      const std::size_t i = v % cube.grid.size[0], j = (v / cube.grid.size[0]) % cube.grid.size[1],
                        k = v / (cube.grid.size[0] * cube.grid.size[1]);
      const Eigen::Vector3d x = cube.grid.centre_m(i, j, k);
      EXPECT_LE((kept.displacement_m[v].cast<double>() - s * (cube.a * x + cube.b)).norm(), kFloat32 * largest_m) << v;
    }
    EXPECT_GT(inside, 1000u);
  }
  mesh::TetMesh moved = cube.mesh;
  moved.nodes[0].x() += 1e-3;
  const std::vector<LungMotion> other{LungMotion{moved, cube.u, cube.s}};
  EXPECT_FALSE(rest.holds(cube.grid, other));
  forward_dvf(cube.grid, other, kept, {}, &rest);
  EXPECT_TRUE(rest.holds(cube.grid, other));
  const DisplacementField fresh = forward_dvf(cube.grid, other);
  EXPECT_EQ(kept.lung, fresh.lung);
  EXPECT_EQ(std::memcmp(kept.displacement_m.data(), fresh.displacement_m.data(),
                        fresh.displacement_m.size() * sizeof(Eigen::Vector3f)),
            0);
}

TEST(PullbackDvf, IsTheAnalyticInverseOfTheAffineMotion) {
  const AffineCube cube;
  const DisplacementField v = pullback_dvf(cube.grid, cube.lungs());
  double largest_m = 0.0;
  for (const Eigen::Vector3d& x : cube.mesh.nodes)
    largest_m = std::max(largest_m, (cube.s * (cube.a * x + cube.b)).norm());
  std::size_t inside = 0;
  for (std::size_t k = 0; k < cube.grid.size[2]; ++k)
    for (std::size_t j = 0; j < cube.grid.size[1]; ++j)
      for (std::size_t i = 0; i < cube.grid.size[0]; ++i) {
        const std::size_t n = cube.grid.index(i, j, k);
        const Eigen::Vector3d x = cube.grid.centre_m(i, j, k);
        const Eigen::Vector3d rest = cube.inverse(x);
        const int side = cube.side(rest);
        if (side == 1) {
          EXPECT_EQ(v.lung[n], 1) << i << " " << j << " " << k;
        }
        if (side == -1) {
          EXPECT_EQ(v.lung[n], 0) << i << " " << j << " " << k;
        }
        if (v.lung[n] == 0) continue;
        ++inside;
        EXPECT_LE((v.displacement_m[n].cast<double>() - (rest - x)).norm(), kFloat32 * largest_m);
      }
  const double expected = std::pow(cube.length_m(), 3) * (Eigen::Matrix3d::Identity() + cube.s * cube.a).determinant() /
                          cube.grid.voxel_volume_m3();
  EXPECT_NEAR(static_cast<double>(inside), expected, 0.05 * expected);
}

TEST(Jacobian, IsDetOfIPlusSAInEveryTet) {
  const AffineCube cube;
  const double expected = (Eigen::Matrix3d::Identity() + cube.s * cube.a).determinant();
  const std::vector<double> j = tet_jacobians(cube.lungs()[0]);
  ASSERT_EQ(j.size(), 6u * 64u);
  for (const double d : j) EXPECT_NEAR(d, expected, 1e-12 * expected);
  const JacobianStats stats = jacobian_stats(cube.lungs());
  EXPECT_EQ(stats.tets, j.size());
  EXPECT_NEAR(stats.min, expected, 1e-12);
  EXPECT_NEAR(stats.max, expected, 1e-12);
  EXPECT_EQ(stats.folded_tets, 0u);
  EXPECT_EQ(stats.folded_volume_fraction, 0.0);
  EXPECT_NEAR(stats.rest_volume_m3, std::pow(cube.length_m(), 3), 1e-12 * std::pow(cube.length_m(), 3));
  EXPECT_NEAR(stats.deformed_volume_m3, expected * std::pow(cube.length_m(), 3), 1e-12 * std::pow(cube.length_m(), 3));
}

TEST(Jacobian, CountsFoldedTets) {
  const AffineCube cube;
  // det(I + 30 A) = -2.318: every tet turned inside out.
  const LungMotion folded{cube.mesh, cube.u, 30.0};
  const JacobianStats stats = jacobian_stats(std::vector<LungMotion>{folded});
  EXPECT_LT(stats.min, 0.0);
  EXPECT_EQ(stats.folded_tets, stats.tets);
  EXPECT_EQ(stats.folded_count_fraction, 1.0);
  EXPECT_DOUBLE_EQ(stats.folded_volume_fraction, 1.0);
}

TEST(Dvf, SameBytesAtAnyThreadCount) {
  const AffineCube cube;
  DisplacementField f1, p1;
  {
    const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    f1 = forward_dvf(cube.grid, cube.lungs());
    p1 = pullback_dvf(cube.grid, cube.lungs());
  }
  const DisplacementField f = forward_dvf(cube.grid, cube.lungs());
  const DisplacementField p = pullback_dvf(cube.grid, cube.lungs());
  ASSERT_EQ(f.displacement_m.size(), f1.displacement_m.size());
  EXPECT_EQ(
      std::memcmp(f.displacement_m.data(), f1.displacement_m.data(), f.displacement_m.size() * sizeof(Eigen::Vector3f)),
      0);
  EXPECT_EQ(
      std::memcmp(p.displacement_m.data(), p1.displacement_m.data(), p.displacement_m.size() * sizeof(Eigen::Vector3f)),
      0);
  EXPECT_EQ(f.lung, f1.lung);
  EXPECT_EQ(p.lung, p1.lung);
}

TEST(Dvf, FirstLungWinsAndOutsideComesFromTheCallback) {
  const AffineCube cube;
  const std::vector<Eigen::Vector3d> zero(cube.mesh.node_count(), Eigen::Vector3d::Zero());
  const std::vector<LungMotion> lungs{LungMotion{cube.mesh, zero, 1.0}, LungMotion{cube.mesh, cube.u, 1.0}};
  const Eigen::Vector3d body(1e-3, 2e-3, 3e-3);
  const DisplacementField f = forward_dvf(
      cube.grid, lungs, [&](const Eigen::Vector3d&, const Eigen::Vector3d*) { return Eigen::Vector3d(body); });
  for (std::size_t v = 0; v < f.lung.size(); ++v) {
    EXPECT_NE(f.lung[v], 2);
    EXPECT_EQ(f.displacement_m[v], f.lung[v] == 1 ? Eigen::Vector3f::Zero() : Eigen::Vector3f(body.cast<float>()));
  }
}

// The outside callback's starting guess (dvf.h, OutsideField): for each voxel outside the
// deformed cube, the line through the values given to its row neighbours i - 2 and i - 1 when both
// are outside too, the value of i - 1 when only it is (here the neighbours' centres, from the grid
// itself), else none; the same at 1 and 2 threads.
TEST(Dvf, TheOutsideCallbackIsGivenItsRowNeighboursValues) {
  const AffineCube cube;
  const Eigen::Matrix4d to_ijk = cube.grid.lps_to_ijk();
  const auto run = [&] {
    std::vector<Eigen::Vector3d> given(cube.grid.voxel_count(), Eigen::Vector3d::Constant(-1.0));
    DisplacementField field =
        pullback_dvf(cube.grid, cube.lungs(), [&](const Eigen::Vector3d& x, const Eigen::Vector3d* previous) {
          const Eigen::Vector3d ijk = (to_ijk * x.homogeneous()).head<3>();
          const std::size_t v = cube.grid.index(static_cast<std::size_t>(std::lround(ijk.x())),
                                                static_cast<std::size_t>(std::lround(ijk.y())),
                                                static_cast<std::size_t>(std::lround(ijk.z())));
          given[v] = previous ? *previous : Eigen::Vector3d::Constant(-2.0);  // each voxel once: no race
          return x;
        });
    return std::pair(std::move(field), std::move(given));
  };
  const auto [field, given] = run();
  std::size_t with = 0, with_one = 0, without = 0;
  for (std::size_t k = 0; k < cube.grid.size[2]; ++k)
    for (std::size_t j = 0; j < cube.grid.size[1]; ++j)
      for (std::size_t i = 0; i < cube.grid.size[0]; ++i) {
        const std::size_t v = cube.grid.index(i, j, k);
        if (field.lung[v] != 0) {
          EXPECT_EQ(given[v], Eigen::Vector3d::Constant(-1.0)) << "a voxel inside the cube was asked";
        } else if (i > 1 && field.lung[v - 1] == 0 && field.lung[v - 2] == 0) {
          // The neighbours' values as the field holds them (float32), extended along the row.
          const Eigen::Vector3d one = field.displacement_m[v - 1].cast<double>();
          const Eigen::Vector3d two = field.displacement_m[v - 2].cast<double>();
          EXPECT_EQ(given[v], 2.0 * one - two) << i << " " << j << " " << k;
          ++with;
        } else if (i > 0 && field.lung[v - 1] == 0) {
          EXPECT_EQ(given[v], field.displacement_m[v - 1].cast<double>()) << i << " " << j << " " << k;
          ++with_one;
        } else {
          EXPECT_EQ(given[v], Eigen::Vector3d::Constant(-2.0)) << i << " " << j << " " << k;
          ++without;
        }
      }
  for (std::size_t v = 0; v < field.lung.size(); ++v) {
    if (field.lung[v] == 0) {
      const std::size_t i = v % cube.grid.size[0], j = (v / cube.grid.size[0]) % cube.grid.size[1],
                        k = v / (cube.grid.size[0] * cube.grid.size[1]);
      ASSERT_LT((field.displacement_m[v].cast<double>() - cube.grid.centre_m(i, j, k)).norm(), 2e-8);  // float32
    }
  }
  EXPECT_GT(with, 1000u);
  EXPECT_GT(with_one, 100u);  // each row's second voxel, and the second after the cube
  EXPECT_GT(without, 100u);   // each row's first voxel, and the first after the cube
  const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  const auto [field1, given1] = run();
  EXPECT_EQ(given1, given);
}

// A grid one voxel thick (report.html's planes) gets, voxel for voxel, the values of the same
// voxels in the whole grid (to rounding): rasterize() drops the tets beside a thin grid, none
// that cross it.
TEST(Dvf, AOneVoxelPlaneIsTheWholeGridsPlane) {
  const AffineCube cube;
  const DisplacementField whole = pullback_dvf(cube.grid, cube.lungs());
  for (const std::size_t axis : {std::size_t{0}, std::size_t{1}}) {
    for (const std::size_t at : {std::size_t{20}, std::size_t{28}, std::size_t{35}}) {
      Grid plane = cube.grid;
      plane.size[axis] = 1;
      Eigen::Vector4d first = Eigen::Vector4d::UnitW();
      first[static_cast<Eigen::Index>(axis)] = static_cast<double>(at);
      plane.ijk_to_lps.col(3) = cube.grid.ijk_to_lps * first;
      const DisplacementField thin = pullback_dvf(plane, cube.lungs());
      std::size_t inside = 0;
      for (std::size_t k = 0; k < plane.size[2]; ++k)
        for (std::size_t j = 0; j < plane.size[1]; ++j)
          for (std::size_t i = 0; i < plane.size[0]; ++i) {
            const std::size_t w = axis == 0 ? cube.grid.index(at, j, k) : cube.grid.index(i, at, k);
            const std::size_t v = plane.index(i, j, k);
            ASSERT_EQ(thin.lung[v], whole.lung[w]) << axis << " " << at << ": " << i << " " << j << " " << k;
            // The same tet, its barycentric coordinates from other index coordinates: to rounding.
            ASSERT_LE((thin.displacement_m[v] - whole.displacement_m[w]).norm(), 1e-15);
            inside += thin.lung[v] != 0;
          }
      EXPECT_GT(inside, 50u) << "the plane crosses the cube";
    }
  }
}

// rest_lungs: the rest meshes' voxels alone, by the analytic cube (inside, outside).
TEST(Dvf, RestLungsAreTheVoxelsOfTheRestCube) {
  const AffineCube cube;
  const std::vector<std::uint8_t> rest = rest_lungs(cube.grid, cube.lungs());
  ASSERT_EQ(rest.size(), cube.grid.voxel_count());
  std::size_t checked = 0;
  for (std::size_t k = 0; k < cube.grid.size[2]; ++k)
    for (std::size_t j = 0; j < cube.grid.size[1]; ++j)
      for (std::size_t i = 0; i < cube.grid.size[0]; ++i) {
        const int side = cube.side(cube.grid.centre_m(i, j, k));
        if (side == 0) continue;  // on the cube's faces: either
        EXPECT_EQ(rest[cube.grid.index(i, j, k)], side == 1 ? 1 : 0) << i << " " << j << " " << k;
        ++checked;
      }
  EXPECT_GT(checked, 100u);
}

// Tets of a voxel or two (a 2 mm grid under 4 mm tets; each tet's set-up made once and read by
// every slab of k it crosses, #50): every voxel belongs to the lowest tet whose closed simplex
// holds its centre, found here by brute force over all tets with barycentric coordinates of
// their own (an LU solve in metres); the field there is that tet's P1 value of a field that
// differs from tet to tet. Slabs of four k-slices, and tets across their borders.
TEST(Dvf, EachVoxelOfACoarseGridTakesTheLowestTetHoldingItsCentre) {
  const Eigen::Vector3d origin(0.010, -0.020, 0.030);
  const mesh::TetMesh cube = test::cube_cells(origin, 5e-3, 4);
  std::vector<Eigen::Vector3d> u;  // a field with no pattern (not affine): each tet's own values
  for (std::size_t n = 0; n < cube.nodes.size(); ++n)
    u.emplace_back(std::sin(1.3 * double(n)) * 1e-3, std::cos(2.1 * double(n)) * 1e-3,
                   std::sin(0.7 * double(n) + 1.0) * 1e-3);
  const std::vector<LungMotion> lungs{LungMotion{cube, u, 1.0}};
  const Eigen::Matrix3d r = Eigen::AngleAxisd(0.4, Eigen::Vector3d(2, -1, 3).normalized()).toRotationMatrix();
  const Grid grid = test::oblique_grid({14, 13, 15}, r, Eigen::Vector3d(2.1e-3, 1.9e-3, 2.3e-3),
                                       origin - r * Eigen::Vector3d(2e-3, 3e-3, 1e-3));
  const DisplacementField f = forward_dvf(grid, lungs);
  const std::vector<std::uint8_t> rest = rest_lungs(grid, lungs);
  std::size_t inside = 0, checked = 0;
  for (std::size_t k = 0; k < grid.size[2]; ++k)
    for (std::size_t j = 0; j < grid.size[1]; ++j)
      for (std::size_t i = 0; i < grid.size[0]; ++i) {
        const std::size_t v = grid.index(i, j, k);
        const Eigen::Vector3d x = grid.centre_m(i, j, k);
        std::optional<std::size_t> owner;
        Eigen::Vector4d owner_l;
        bool near_a_face = false;  // within 1e-9 of a tet's face: the tolerance decides, either way
        for (std::size_t t = 0; t < cube.tets.size(); ++t) {
          const auto& tet = cube.tets[t];
          Eigen::Matrix3d edges;
          edges << cube.nodes[tet[1]] - cube.nodes[tet[0]], cube.nodes[tet[2]] - cube.nodes[tet[0]],
              cube.nodes[tet[3]] - cube.nodes[tet[0]];
          const Eigen::Vector3d l123 = edges.fullPivLu().solve(x - cube.nodes[tet[0]]);
          const Eigen::Vector4d l(1.0 - l123.sum(), l123.x(), l123.y(), l123.z());
          near_a_face = near_a_face || std::abs(l.minCoeff()) < 1e-9;
          if (!owner && l.minCoeff() >= 0.0) owner = t, owner_l = l;
        }
        if (near_a_face) continue;
        ++checked;
        ASSERT_EQ(f.lung[v], owner ? 1 : 0) << i << " " << j << " " << k;
        ASSERT_EQ(rest[v], f.lung[v]) << i << " " << j << " " << k;
        if (!owner) continue;
        ++inside;
        Eigen::Vector3d expected = Eigen::Vector3d::Zero();
        for (std::size_t c = 0; c < 4; ++c) expected += owner_l[Eigen::Index(c)] * u[cube.tets[*owner][c]];
        EXPECT_LE((f.displacement_m[v].cast<double>() - expected).norm(), 1e-6 * 1e-3 * 2) << i << " " << j << " " << k;
      }
  EXPECT_GT(inside, 700u);  // the cube, 8000 mm^3, holds about 870 of these 9.2 mm^3 voxels
  EXPECT_GT(checked, grid.voxel_count() / 2);
}

TEST(Dvf, RefusesADisplacementCountThatIsNotTheNodeCount) {
  const AffineCube cube;
  const std::vector<Eigen::Vector3d> short_field(3, Eigen::Vector3d::Zero());
  const std::vector<LungMotion> lungs{LungMotion{cube.mesh, short_field, 1.0}};
  EXPECT_THROW(forward_dvf(cube.grid, lungs), ValueError);
}

TEST(Grid, CoarserGridCoversTheSameExtent) {
  const Eigen::Matrix3d r = Eigen::AngleAxisd(0.4, Eigen::Vector3d(0, 0, 1)).toRotationMatrix();
  const Grid fine =
      test::oblique_grid({100, 80, 60}, r, Eigen::Vector3d(0.7e-3, 0.7e-3, 0.7e-3), Eigen::Vector3d(0.01, 0.02, -0.03));
  const Grid coarse = grid_with_spacing(fine, 2e-3);
  EXPECT_EQ(coarse.size, (std::array<std::size_t, 3>{35, 28, 21}));
  EXPECT_TRUE(coarse.spacing_m().isApprox(Eigen::Vector3d::Constant(2e-3), 1e-12));
  const auto corner = [](const Grid& g) -> Eigen::Vector3d {
    return g.centre_m(0, 0, 0) - g.ijk_to_lps.block<3, 3>(0, 0) * Eigen::Vector3d::Constant(0.5);
  };
  EXPECT_LE((corner(coarse) - corner(fine)).norm(), 1e-15);
  EXPECT_TRUE((coarse.ijk_to_lps.block<3, 3>(0, 0) / 2e-3).isApprox(r, 1e-12));
  EXPECT_THROW(grid_with_spacing(fine, 0.0), ValueError);
}

}  // namespace
}  // namespace pneuma::voxels
