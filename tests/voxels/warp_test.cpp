// Label maps and images pulled back through the DVF of a ball-like lung dilated radially.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

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

// warp_image's rule with the rest lungs and the tissue masks, written out plainly (warp.h): the
// trilinear corners on x's side of the pleura with a weight, and (given the tissue masks) of x's
// tissue with a weight of at least 1e-4, renormalised; null where every corner is across the pleura (the ring search,
// not checked here). Each corner's weight is the product of its axes' in i, j, k order.
std::optional<float> corner_rule(const Image& image, const Eigen::Vector3d& q, std::uint8_t side, std::uint8_t tissue,
                                 const std::vector<std::uint8_t>& rest_lung,
                                 const std::vector<std::uint8_t>* rest_tissue) {
  std::array<std::size_t, 3> lo{}, hi{};
  std::array<double, 3> t{};
  for (std::size_t a = 0; a < 3; ++a) {
    const double top = static_cast<double>(image.grid.size[a] - 1);
    const double c = std::clamp(q[static_cast<Eigen::Index>(a)], 0.0, top);
    const double base = std::min(std::floor(c), top - 1.0);
    lo[a] = static_cast<std::size_t>(base);
    hi[a] = lo[a] + 1;
    t[a] = c - base;
  }
  double side_value = 0.0, side_weight = 0.0, tissue_value = 0.0, tissue_weight = 0.0;
  for (int corner = 0; corner < 8; ++corner) {
    const bool up[3] = {(corner & 1) != 0, (corner & 2) != 0, (corner & 4) != 0};
    const double weight = (up[0] ? t[0] : 1.0 - t[0]) * (up[1] ? t[1] : 1.0 - t[1]) * (up[2] ? t[2] : 1.0 - t[2]);
    const std::size_t c = image.grid.index(up[0] ? hi[0] : lo[0], up[1] ? hi[1] : lo[1], up[2] ? hi[2] : lo[2]);
    if (weight == 0.0 || rest_lung[c] != side) continue;
    side_value += weight * static_cast<double>(image.values[c]);
    side_weight += weight;
    if (rest_tissue != nullptr && weight >= 1e-4 && (*rest_tissue)[c] == tissue) {
      tissue_value += weight * static_cast<double>(image.values[c]);
      tissue_weight += weight;
    }
  }
  if (tissue_weight > 0.0) return static_cast<float>(tissue_value / tissue_weight);
  if (side_weight == 0.0) return std::nullopt;
  return static_cast<float>(side_value / side_weight);
}

// warp_image takes a short way where all eight corners are on x's side and of x's tissue (#50);
// it gives the rule's bits there and elsewhere. A hand-made pull-back field on a 1 mm grid mixes
// samples on voxel centres (a zero field: weights of exactly 0), samples a few 1e-5 voxel off
// them (weights below the tissue rule's 1e-4), and general ones; a ball of lung and a shifted
// ball of lung tissue put mixed corners along both boundaries.
TEST(WarpImage, CornersAllOnOneSideAndTissueGiveTheCornerRuleBitForBit) {
  Grid grid;
  grid.size = {20, 18, 16};
  grid.ijk_to_lps.block<3, 3>(0, 0) = 1e-3 * Eigen::Matrix3d::Identity();
  grid.ijk_to_lps.block<3, 1>(0, 3) = Eigen::Vector3d(-0.02, 0.01, 0.3);
  const auto inside = [&](std::size_t i, std::size_t j, std::size_t k, const Eigen::Vector3d& centre, double r) {
    return (Eigen::Vector3d(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k)) - centre).norm() <
           r;
  };
  const Eigen::Vector3d lung_centre(9.5, 8.5, 7.5), tissue_centre(11.0, 8.0, 7.0);
  Image image;
  image.grid = grid;
  image.values.resize(grid.voxel_count());
  std::vector<std::uint8_t> rest_lung(grid.voxel_count()), rest_tissue(grid.voxel_count());
  DisplacementField pull;
  pull.grid = grid;
  pull.displacement_m.resize(grid.voxel_count());
  pull.lung.resize(grid.voxel_count());
  std::vector<std::uint8_t> warped_tissue(grid.voxel_count());
  for (std::size_t k = 0; k < grid.size[2]; ++k)
    for (std::size_t j = 0; j < grid.size[1]; ++j)
      for (std::size_t i = 0; i < grid.size[0]; ++i) {
        const std::size_t v = grid.index(i, j, k);
        image.values[v] = static_cast<float>(static_cast<int>((v * 2654435761u) % 2001u) - 1000) + 0.37f;
        rest_lung[v] = inside(i, j, k, lung_centre, 6.0) ? 1 : 0;
        rest_tissue[v] = inside(i, j, k, tissue_centre, 5.0) ? 1 : 0;
        pull.lung[v] = inside(i, j, k, lung_centre, 6.5) ? 1 : 0;
        warped_tissue[v] = inside(i, j, k, tissue_centre, 5.5) ? 1 : 0;
        const double phase =
            0.37 * static_cast<double>(i) + 0.61 * static_cast<double>(j) + 0.23 * static_cast<double>(k);
        switch (v % 4) {
          case 0:  // on a voxel centre
            pull.displacement_m[v] = Eigen::Vector3f::Zero();
            break;
          case 1:  // 3e-5 voxel off one along i: that corner's weight below 1e-4
            pull.displacement_m[v] = Eigen::Vector3f(3e-8f, 0.0f, 1e-3f);
            break;
          default:
            pull.displacement_m[v] =
                (0.9e-3 * Eigen::Vector3d(std::sin(phase), std::cos(1.3 * phase), std::sin(0.7 * phase))).cast<float>();
        }
      }
  // With the tissue masks, and without them (no CT tissue: the side of the pleura only).
  for (const bool with_tissue : {true, false}) {
    const Image warped = with_tissue
                             ? warp_image(image, pull, kOutsideHu, &rest_lung, Tissue{&rest_tissue, &warped_tissue})
                             : warp_image(image, pull, kOutsideHu, &rest_lung, Tissue{});
    const Eigen::Matrix4d to_ijk = grid.lps_to_ijk();
    std::size_t uniform = 0, mixed = 0, uniform_with_negligible = 0;
    for (std::size_t k = 0; k < grid.size[2]; ++k)
      for (std::size_t j = 0; j < grid.size[1]; ++j)
        for (std::size_t i = 0; i < grid.size[0]; ++i) {
          const std::size_t v = grid.index(i, j, k);
          const Eigen::Vector3d y = grid.centre_m(i, j, k) + pull.displacement_m[v].cast<double>();
          const Eigen::Vector3d q = to_ijk.block<3, 3>(0, 0) * y + to_ijk.block<3, 1>(0, 3);
          if (q.minCoeff() < 0.0 || q[0] > 19.0 || q[1] > 17.0 || q[2] > 15.0) continue;  // the edges: other tests
          const std::optional<float> expected =
              corner_rule(image, q, pull.lung[v], warped_tissue[v], rest_lung, with_tissue ? &rest_tissue : nullptr);
          if (!expected) continue;
          EXPECT_EQ(warped.values[v], *expected) << i << " " << j << " " << k << (with_tissue ? "" : ", no tissue");
          // Whether the short way applied: the eight corners of one side and tissue.
          bool all = true, negligible = false;
          for (int corner = 0; corner < 8; ++corner) {
            const std::array<double, 3> c{std::floor(q[0]) + (corner & 1), std::floor(q[1]) + ((corner >> 1) & 1),
                                          std::floor(q[2]) + ((corner >> 2) & 1)};
            const std::size_t at = grid.index(static_cast<std::size_t>(std::min(c[0], 19.0)),
                                              static_cast<std::size_t>(std::min(c[1], 17.0)),
                                              static_cast<std::size_t>(std::min(c[2], 15.0)));
            all = all && rest_lung[at] == pull.lung[v] && (!with_tissue || rest_tissue[at] == warped_tissue[v]);
          }
          for (std::size_t a = 0; a < 3; ++a) {
            const double frac = q[static_cast<Eigen::Index>(a)] - std::floor(q[static_cast<Eigen::Index>(a)]);
            negligible = negligible || (frac > 0.0 && (frac < 1e-4 || frac > 1.0 - 1e-4));
          }
          uniform += all;
          mixed += !all;
          uniform_with_negligible += all && negligible;
        }
    EXPECT_GT(uniform, 2000u) << with_tissue;
    EXPECT_GT(mixed, with_tissue ? 200u : 50u) << with_tissue;
    EXPECT_GT(uniform_with_negligible, 300u) << with_tissue;
  }
}

// A lung deflating below its scan, with a lobe map whose lung reaches 2 voxels beyond the rest
// mesh (the rim a smoothed surface leaves inside a CT's lobe map), and a body that lags the
// pleura: the ball shrinks by (1 - 0.2)^3 while the body outside it pulls back from 1.1 times as
// far from the centre (a uniform radial scale), so the body voxels between the deformed surface
// (0.8 R) and R / 1.1 pull back into the rest mesh. Oracle: the deformed mesh's volume (the rest
// mesh's, an exact sum of cells, times 0.512) plus the rim's carried by the body (its rest voxels
// over 1.1^3). With the lung labels, warp_labels gives the body's own tissue in that gap; without
// them the gap takes the rim's lung labels, the excess #45 measured on CT lungs (+0.6-1.7 %).
TEST(WarpLabels, ALungDeflatingBelowItsScanHoldsTheDeformedMeshAndTheRimOnly) {
  test::Ball ball = test::make_ball();
  const double c = 0.4, s = -0.5, body = 0.1;  // (1 + s c)^3 = 0.512
  const std::vector<Eigen::Vector3d> u = ball.radial(c);
  const std::vector<LungMotion> lungs{LungMotion{ball.mesh, u, s}};
  const std::vector<LungMotion> at_rest{LungMotion{ball.mesh, u, 0.0}};
  const std::vector<std::uint8_t> rest_lung = rest_lungs(ball.grid, at_rest);
  // The rim: every voxel within 2 voxels (Chebyshev) of the rest mesh's lung is lung (label 1).
  const auto& size = ball.grid.size;
  std::size_t rim = 0;
  for (std::size_t k = 2; k + 2 < size[2]; ++k)
    for (std::size_t j = 2; j + 2 < size[1]; ++j)
      for (std::size_t i = 2; i + 2 < size[0]; ++i) {
        const std::size_t v = ball.grid.index(i, j, k);
        if (rest_lung[v] != 0) continue;
        bool near = false;
        for (std::size_t dk = 0; dk < 5 && !near; ++dk)
          for (std::size_t dj = 0; dj < 5 && !near; ++dj)
            for (std::size_t di = 0; di < 5 && !near; ++di)
              near = rest_lung[ball.grid.index(i + di - 2, j + dj - 2, k + dk - 2)] != 0;
        if (near) {
          ball.labels.labels[v] = 1;
          ++rim;
        }
      }
  EXPECT_GT(rim, 5000u);
  const std::vector<int> lung_labels{1, 2};
  const JacobianStats stats = jacobian_stats(lungs);
  const double voxel_m3 = ball.grid.voxel_volume_m3();
  const double expected_m3 = stats.deformed_volume_m3 + static_cast<double>(rim) * voxel_m3 / std::pow(1 + body, 3);
  EXPECT_NEAR(stats.deformed_volume_m3, std::pow(1 + s * c, 3) * stats.rest_volume_m3, 1e-12);
  const DisplacementField pull = pullback_dvf(ball.grid, lungs, [&](const Eigen::Vector3d& x, const Eigen::Vector3d*) {
    return Eigen::Vector3d(body * (x - ball.centre_m));
  });
  const auto lung_m3 = [&](const image::LabelMap& map) {
    return static_cast<double>(count_label(map, 1) + count_label(map, 2)) * voxel_m3;
  };
  const image::LabelMap warped = warp_labels(ball.labels, pull, &rest_lung, lung_labels);
  // 3 %: the rim's voxels sampled by the body's map at 1.1 voxels (their faces are planes of the
  // cells, so the sampling's phase does not average out).
  EXPECT_NEAR(lung_m3(warped) / expected_m3, 1.0, 0.03);
  // Voxel by voxel by the analytic maps: lung inside the deformed mesh (its rest point
  // c + (x - c) / 0.8 in a cell), else where the body's rest point's nearest voxel is the rim's.
  const Eigen::Matrix4d to_ijk = ball.grid.lps_to_ijk();
  std::size_t analytic = 0;
  for (std::size_t v = 0; v < warped.labels.size(); ++v) {
    const Eigen::Vector3d x = pull.grid.centre_m(v % 64, (v / 64) % 64, v / 4096);
    if (ball.inside(ball.centre_m + (x - ball.centre_m) / (1 + s * c))) {
      ++analytic;
      continue;
    }
    const Eigen::Vector3d at = x + body * (x - ball.centre_m);
    const Eigen::Vector3d q = (to_ijk.block<3, 3>(0, 0) * at + to_ijk.block<3, 1>(0, 3)).array().round();
    if (q.minCoeff() < 0 || q.maxCoeff() > 63) continue;
    const std::size_t r = ball.grid.index(static_cast<std::size_t>(q.x()), static_cast<std::size_t>(q.y()),
                                          static_cast<std::size_t>(q.z()));
    analytic += rest_lung[r] == 0 && ball.labels.labels[r] == 1;
  }
  // Measured: 25,994 voxels both ways, 0.982 of the volume oracle (the rule before: 1.238).
  EXPECT_NEAR(lung_m3(warped) / voxel_m3, static_cast<double>(analytic), 0.002 * static_cast<double>(analytic));
  // No voxel outside the deformed lung whose pull-back lands a voxel deep in the rest mesh is lung.
  std::size_t gap = 0, gap_lung = 0;
  for (std::size_t v = 0; v < warped.labels.size(); ++v) {
    if (pull.lung[v] != 0) continue;
    const Eigen::Vector3d x = pull.grid.centre_m(v % 64, (v / 64) % 64, v / 4096);
    // x + v(x) a voxel or more inside the rest mesh (along each axis): the body's, not the rim's.
    const Eigen::Vector3d q = x + body * (x - ball.centre_m);
    bool deep = ball.inside(q);
    for (int a = 0; a < 3 && deep; ++a)
      deep = ball.inside(q + 1e-3 * Eigen::Vector3d::Unit(a)) && ball.inside(q - 1e-3 * Eigen::Vector3d::Unit(a));
    if (!deep) continue;
    ++gap;
    gap_lung += warped.labels[v] == 1 || warped.labels[v] == 2;
  }
  EXPECT_GT(gap, 2000u);  // the gap, 15.2-17.3 mm from the centre, less a voxel: 2,975 voxels
  EXPECT_EQ(gap_lung, 0u);
  // Without the lung labels (the rule before #45's fix) the gap takes the rim's lung labels.
  const image::LabelMap by_side = warp_labels(ball.labels, pull, &rest_lung);
  EXPECT_GT(lung_m3(by_side) / expected_m3, 1.2);
}

}  // namespace
}  // namespace pneuma::voxels
