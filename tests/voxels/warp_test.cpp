// Label maps and images pulled back through the DVF of a ball-like lung dilated radially.
#include <gtest/gtest.h>

#include <cmath>

#include "pneuma/voxels/dvf.h"
#include "pneuma/voxels/jacobian.h"
#include "pneuma/voxels/warp.h"
#include "tet_fixtures.h"

namespace pneuma::voxels {
namespace {

std::size_t count_label(const image::LabelMap& map, std::int32_t label) {
  return static_cast<std::size_t>(std::count(map.labels.begin(), map.labels.end(), label));
}

TEST(WarpLabels, DilatedBallGrowsByTheCubeOfItsScale) {
  const test::Ball ball = test::make_ball();
  const double c = 0.4, s = 0.5;  // (1 + s c)^3 = 1.728
  const std::vector<Eigen::Vector3d> u = ball.radial(c);
  const std::vector<LungMotion> lungs{LungMotion{ball.mesh, u, s}};
  const JacobianStats j = jacobian_stats(lungs);
  const double factor = std::pow(1 + s * c, 3);
  EXPECT_GT(j.min, 0.0);
  EXPECT_NEAR(j.min, factor, 1e-12);
  EXPECT_NEAR(j.max, factor, 1e-12);
  EXPECT_NEAR(j.deformed_volume_m3, factor * j.rest_volume_m3, 1e-12 * j.rest_volume_m3);

  const DisplacementField pull = pullback_dvf(ball.grid, lungs);
  const image::LabelMap warped = warp_labels(ball.labels, pull);
  EXPECT_EQ(warped.size, ball.labels.size);
  EXPECT_EQ(warped.segments.size(), 3u);
  // Voxel by voxel against the analytic inverse: inside the deformed ball (the rest point
  // c + (x - c) / (1 + s c) in a cell of the mesh) the rest label nearest that point, elsewhere
  // the label at x itself (v = 0). Ties of the rounding aside, every voxel agrees.
  const Eigen::Matrix4d to_ijk = ball.grid.lps_to_ijk();
  std::size_t mismatches = 0, moved = 0;
  for (std::size_t v = 0; v < warped.labels.size(); ++v) {
    const Eigen::Vector3d x = pull.grid.centre_m(v % 64, (v / 64) % 64, v / 4096);
    const Eigen::Vector3d rest = ball.centre_m + (x - ball.centre_m) / (1 + s * c);
    const bool inside = ball.inside(rest);
    moved += inside;
    EXPECT_EQ(pull.lung[v], inside ? 1 : 0) << v;
    const Eigen::Vector3d at = inside ? rest : x;
    const Eigen::Vector3d q = (to_ijk.block<3, 3>(0, 0) * at + to_ijk.block<3, 1>(0, 3)).array().round();
    const std::int32_t expected =
        q.minCoeff() < 0 || q.maxCoeff() > 63
            ? 0
            : ball.labels.labels[ball.grid.index(static_cast<std::size_t>(q.x()), static_cast<std::size_t>(q.y()),
                                                 static_cast<std::size_t>(q.z()))];
    mismatches += warped.labels[v] != expected;
  }
  EXPECT_LE(mismatches, 10u);
  // The deformed mesh holds (1 + s c)^3 times the rest mesh's volume in voxels (to 1 %).
  const double voxel_m3 = ball.grid.voxel_volume_m3();
  EXPECT_NEAR(static_cast<double>(moved) * voxel_m3, factor * j.rest_volume_m3, 0.01 * factor * j.rest_volume_m3);
  // The warped label volume: (1 + s c)^3 times the rest label volume, less the shell where the
  // rest labels reach beyond the mesh (nearest-label sampling near the surface, up to half a
  // voxel: the voxels just outside the deformed surface have v = 0 and keep their own label, so
  // nothing comes back in). Measured: -5.1 % for this 20 mm ball with 1 mm voxels (it scales as
  // voxel size over radius: about 1 % for an adult lung at 1 mm).
  const double rest_m3 = static_cast<double>(count_label(ball.labels, 1) + count_label(ball.labels, 2)) * voxel_m3;
  const double warped_m3 = static_cast<double>(count_label(warped, 1) + count_label(warped, 2)) * voxel_m3;
  EXPECT_NEAR(rest_m3, j.rest_volume_m3, 0.02 * j.rest_volume_m3);
  EXPECT_LT(warped_m3, factor * rest_m3);
  EXPECT_GT(warped_m3, 0.93 * factor * rest_m3);
  // Outside the deformed ball v = 0: the slab above keeps its labels.
  EXPECT_EQ(count_label(warped, 7), count_label(ball.labels, 7));
}

TEST(WarpImage, LinearImageIsSampledExactlyAndOutsideIsAir) {
  const test::Ball ball = test::make_ball();
  // A CT that is linear in position: trilinear interpolation reproduces it exactly.
  Image ct;
  ct.grid = ball.grid;
  ct.values.resize(ct.grid.voxel_count());
  const Eigen::Vector3d gradient_hu_per_m(2e4, -1e4, 3e4);
  const auto hu = [&](const Eigen::Vector3d& y) { return 40.0 + gradient_hu_per_m.dot(y - ball.centre_m); };
  for (std::size_t v = 0; v < ct.values.size(); ++v) {
    ct.values[v] = static_cast<float>(hu(ct.grid.centre_m(v % 64, (v / 64) % 64, v / 4096)));
  }
  // A shift large enough to pull samples from outside the image.
  const std::vector<Eigen::Vector3d> u = ball.radial(-0.3, Eigen::Vector3d(0, 0, 12e-3));
  const std::vector<LungMotion> lungs{LungMotion{ball.mesh, u, 1.0}};
  const DisplacementField pull = pullback_dvf(ball.grid, lungs, [](const Eigen::Vector3d&, const Eigen::Vector3d*) {
    return Eigen::Vector3d(0, 0, -40e-3);  // a body field pulling from 40 mm below
  });
  const Image warped = warp_image(ct, pull);
  const Eigen::Matrix4d to_ijk = ct.grid.lps_to_ijk();
  std::size_t inside = 0, outside = 0;
  for (std::size_t v = 0; v < warped.values.size(); ++v) {
    const Eigen::Vector3d y =
        pull.grid.centre_m(v % 64, (v / 64) % 64, v / 4096) + pull.displacement_m[v].cast<double>();
    const Eigen::Vector3d q = to_ijk.block<3, 3>(0, 0) * y + to_ijk.block<3, 1>(0, 3);
    if (q.minCoeff() >= 0 && q.maxCoeff() <= 63) {
      ++inside;
      EXPECT_NEAR(warped.values[v], hu(y), 2e-3) << v;
    } else if (q.minCoeff() < -0.5 || q.maxCoeff() > 63.5) {
      ++outside;
      EXPECT_EQ(warped.values[v], kOutsideHu) << v;
    }
  }
  EXPECT_GT(inside, 10000u);
  EXPECT_GT(outside, 10000u);
}

}  // namespace
}  // namespace pneuma::voxels
