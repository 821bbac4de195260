// The Jacobian image and the mass-preserving CT (voxels/density.h). Oracles: the mass-preserving
// rule's arithmetic, det(I + s A) for an affine field (exact in P1 tets and for central
// differences), and the mass of a ball-like lung's parenchyma summed over voxels before and
// after a radial dilation of known Jacobian.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "pneuma/core/error.h"
#include "pneuma/voxels/density.h"
#include "pneuma/voxels/dvf.h"
#include "pneuma/voxels/jacobian.h"
#include "pneuma/voxels/time_point.h"
#include "pneuma/voxels/warp.h"
#include "tet_fixtures.h"

namespace pneuma::voxels {
namespace {

TEST(MassPreservingHu, ParenchymaScalesByOneOverTheJacobianWithinAirAndWater) {
  // An inhaling lung at -849.5 HU stretched by J = 1.1: (150.5 / 1.1) - 1000.
  EXPECT_NEAR(mass_preserving_hu(-849.5f, 1.1), 150.5 / 1.1 - 1000.0, 1e-4);
  EXPECT_FLOAT_EQ(mass_preserving_hu(-849.5f, 1.0), -849.5f);
  EXPECT_FLOAT_EQ(mass_preserving_hu(-1000.0f, 1.3), -1000.0f);  // air has no mass
  EXPECT_FLOAT_EQ(mass_preserving_hu(-100.0f, 0.5), 0.0f);       // 800 HU, held at water
  EXPECT_FLOAT_EQ(mass_preserving_hu(40.0f, 1.2), 40.0f);        // blood and vessels keep their HU
  EXPECT_FLOAT_EQ(mass_preserving_hu(-1024.0f, 1.2), -1024.0f);  // outside the scan: as it was
  EXPECT_FLOAT_EQ(mass_preserving_hu(-500.0f, 0.0), -500.0f);    // a folded tet changes nothing
}

// u = s (A x + b) on the ball: inside the tets (P1 exact) and outside them (central differences
// of an affine field are exact), so every voxel's Jacobian is det(I + s A).
struct AffineMotion {
  test::Ball ball = test::make_ball();
  Eigen::Matrix3d a;
  Eigen::Vector3d b{0.001, -0.002, 0.003};
  double s = 0.8;
  std::vector<Eigen::Vector3d> u;  // the unit field per node, which lungs' span views
  std::vector<LungMotion> lungs;
  OutsideField outside;
  double jacobian = 0.0;

  AffineMotion() {
    a << 0.10, 0.02, -0.01, 0.00, 0.05, 0.03, 0.01, -0.02, 0.20;
    u = test::affine_field(ball.mesh, a, b);
    lungs.push_back(LungMotion{ball.mesh, u, s});
    outside = [a = a, b = b, s = s](const Eigen::Vector3d& x, const Eigen::Vector3d*) {
      return Eigen::Vector3d(s * (a * x + b));
    };
    jacobian = (Eigen::Matrix3d::Identity() + s * a).determinant();
  }
  // lungs refers to ball and u: a copy would refer to the original's.
  AffineMotion(const AffineMotion&) = delete;
  AffineMotion& operator=(const AffineMotion&) = delete;
  AffineMotion(AffineMotion&&) = delete;
  AffineMotion& operator=(AffineMotion&&) = delete;
  ~AffineMotion() = default;
};

TEST(JacobianImage, AnAffineFieldHasItsDeterminantInsideAndOutsideTheLung) {
  const AffineMotion motion;
  const DisplacementField forward = forward_dvf(motion.ball.grid, motion.lungs, motion.outside);
  Image jacobian;
  jacobian_image(motion.lungs, forward, jacobian);
  ASSERT_EQ(jacobian.values.size(), motion.ball.grid.voxel_count());
  std::size_t inside = 0;
  for (std::size_t v = 0; v < jacobian.values.size(); ++v) {
    EXPECT_NEAR(jacobian.values[v], motion.jacobian, 1e-5) << v;
    inside += forward.lung[v] != 0;
  }
  EXPECT_GT(inside, 10000u);
  EXPECT_LT(inside, motion.ball.grid.voxel_count() / 2);
}

// The voxel outputs' one rasterisation for both (forward_dvf_with_jacobian, then
// jacobian_image_outside): det(I + s A) at every voxel as above, and the same field and image, bit
// for bit, as forward_dvf and jacobian_image apart (the files of a run must not change).
TEST(JacobianImage, MadeWithTheForwardFieldItIsTheSameImage) {
  const AffineMotion motion;
  DisplacementField fused;
  Image jacobian;
  forward_dvf_with_jacobian(motion.ball.grid, motion.lungs, fused, motion.outside, jacobian);
  jacobian_image_outside(fused, jacobian);
  ASSERT_EQ(jacobian.values.size(), motion.ball.grid.voxel_count());
  for (std::size_t v = 0; v < jacobian.values.size(); ++v) EXPECT_NEAR(jacobian.values[v], motion.jacobian, 1e-5) << v;

  const DisplacementField apart = forward_dvf(motion.ball.grid, motion.lungs, motion.outside);
  Image apart_jacobian;
  jacobian_image(motion.lungs, apart, apart_jacobian);
  EXPECT_EQ(fused.lung, apart.lung);
  EXPECT_TRUE(std::equal(fused.displacement_m.begin(), fused.displacement_m.end(), apart.displacement_m.begin()));
  EXPECT_EQ(jacobian.values, apart_jacobian.values);
  // A field and image that do not belong together are refused.
  Image other;
  EXPECT_THROW(jacobian_image_outside(fused, other), ValueError);
}

// A ball of parenchyma (-850 HU) in soft tissue (40 HU), dilated radially by (1 + s c)^3: the
// lung's voxels of the warped mass-preserving CT hold the rest lung's mass, (HU + 1000) summed
// over voxels times their volume, within 1 %, at the predicted -1000 + 150 / J; without the rule
// the mass grows by J. Pulled back without the rest lungs, the rim blends in the soft tissue.
TEST(MassPreservingCt, AWarpedDilatedLungKeepsItsMass) {
  const test::Ball ball = test::make_ball();
  const double c = 0.4, s = 0.5;
  const double j = std::pow(1 + s * c, 3);  // 1.728
  const std::vector<Eigen::Vector3d> u = ball.radial(c);
  const std::vector<LungMotion> lungs{LungMotion{ball.mesh, u, s}};
  Image rest;
  rest.grid = ball.grid;
  rest.values.assign(ball.grid.voxel_count(), 40.0f);
  const std::vector<LungMotion> at_rest{LungMotion{ball.mesh, u, 0.0}};
  const std::vector<std::uint8_t> rest_lung = rest_lungs(ball.grid, at_rest);
  for (std::size_t v = 0; v < rest.values.size(); ++v)
    if (rest_lung[v] != 0) rest.values[v] = -850.0f;
  const DisplacementField pull = pullback_dvf(ball.grid, lungs);
  auto lung_mass = [&](const Image& image, const std::vector<std::uint8_t>& in_lung) {
    double mass = 0.0;
    for (std::size_t v = 0; v < image.values.size(); ++v)
      if (in_lung[v] != 0) mass += image.values[v] + 1000.0;
    return mass * ball.grid.voxel_volume_m3();
  };
  const double rest_mass = lung_mass(rest, rest_lung);

  Image preserved, warped;
  std::vector<std::uint8_t> ct_lung;
  mass_preserving_ct(rest, lungs, preserved, ct_lung);
  EXPECT_EQ(ct_lung, rest_lung);
  warp_image(preserved, pull, warped, kOutsideHu, &ct_lung);
  EXPECT_NEAR(lung_mass(warped, pull.lung) / rest_mass, 1.0, 0.01);
  // Deep inside the lung every voxel shows the predicted value.
  const std::size_t centre = ball.grid.index(32, 32, 32);
  ASSERT_NE(pull.lung[centre], 0);
  EXPECT_NEAR(warped.values[centre], -1000.0 + 150.0 / j, 1e-3);
  // Outside the lung the soft tissue keeps its HU.
  EXPECT_FLOAT_EQ(warped.values[0], 40.0f);

  Image unchanged;
  warp_image(rest, pull, unchanged, kOutsideHu, &rest_lung);
  EXPECT_NEAR(lung_mass(unchanged, pull.lung) / rest_mass, j, 0.02 * j);
  Image blended;
  warp_image(preserved, pull, blended);
  EXPECT_GT(lung_mass(blended, pull.lung) / rest_mass, 1.1);
}

// The ball's lung with a vessel in it: soft tissue (40 HU) that the lung's mesh holds but the label
// map does not call lung (a 5 mm ball of label 0 inside label 1), dilated as above. Interpolated by
// the pleura's side alone, the lung voxels beside the vessel take some of its HU, 7 times the
// parenchyma's mass (the warped lung gains mass, and shows values between the two); interpolated
// with the label map's tissue (warp_image's Tissue), every warped lung voxel shows the predicted
// -1000 + 150 / J (a uniform J: the same value at every corner), the vessel's voxels keep 40 HU,
// and the warped lung holds the rest lung's mass within 1 %.
TEST(MassPreservingCt, ALungVoxelIsInterpolatedFromLungVoxelsOnly) {
  test::Ball ball = test::make_ball();
  const double c = 0.4, s = 0.5;
  const double j = std::pow(1 + s * c, 3);
  const Eigen::Vector3d vessel_centre = ball.centre_m + Eigen::Vector3d(-8e-3, 3e-3, -2e-3);
  for (std::size_t k = 0; k < ball.grid.size[2]; ++k)
    for (std::size_t jj = 0; jj < ball.grid.size[1]; ++jj)
      for (std::size_t i = 0; i < ball.grid.size[0]; ++i)
        if ((ball.grid.centre_m(i, jj, k) - vessel_centre).norm() < 5e-3)
          ball.labels.labels[ball.grid.index(i, jj, k)] = 0;
  const std::vector<int> lung_labels{1, 2};
  const std::vector<Eigen::Vector3d> u = ball.radial(c);
  const std::vector<LungMotion> lungs{LungMotion{ball.mesh, u, s}};
  const std::vector<LungMotion> at_rest{LungMotion{ball.mesh, u, 0.0}};
  const std::vector<std::uint8_t> rest_lung = rest_lungs(ball.grid, at_rest);
  std::vector<std::uint8_t> rest_tissue;
  lung_tissue(ball.labels, lung_labels, ball.grid, rest_tissue);
  Image rest;
  rest.grid = ball.grid;
  rest.values.resize(ball.grid.voxel_count());
  std::size_t vessel_voxels = 0;
  for (std::size_t v = 0; v < rest.values.size(); ++v) {
    rest.values[v] = rest_tissue[v] != 0 ? -850.0f : 40.0f;
    vessel_voxels += rest_lung[v] != 0 && rest_tissue[v] == 0;
  }
  EXPECT_GT(vessel_voxels, 400u);  // 4/3 pi 5^3 = 524 voxels of 1 mm
  const DisplacementField pull = pullback_dvf(ball.grid, lungs);
  const image::LabelMap warped_labels = warp_labels(ball.labels, pull, &rest_lung);
  std::vector<std::uint8_t> warped_tissue;
  lung_tissue(warped_labels, lung_labels, warped_tissue);
  const auto lung_mass = [&](const Image& image, const std::vector<std::uint8_t>& tissue) {
    double mass = 0.0;
    for (std::size_t v = 0; v < image.values.size(); ++v)
      if (tissue[v] != 0) mass += image.values[v] + 1000.0;
    return mass;
  };
  const double rest_mass = lung_mass(rest, rest_tissue);
  Image preserved;
  std::vector<std::uint8_t> ct_lung;
  mass_preserving_ct(rest, lungs, preserved, ct_lung);

  const Image by_side = warp_image(preserved, pull, kOutsideHu, &ct_lung);
  EXPECT_GT(lung_mass(by_side, warped_tissue) / rest_mass, 1.02);
  const Image by_tissue = warp_image(preserved, pull, kOutsideHu, &ct_lung, Tissue{&rest_tissue, &warped_tissue});
  EXPECT_NEAR(lung_mass(by_tissue, warped_tissue) / rest_mass, 1.0, 0.01);
  std::size_t lung_voxels = 0, vessel_after = 0, blended_by_side = 0;
  for (std::size_t v = 0; v < by_tissue.values.size(); ++v) {
    if (pull.lung[v] == 0) continue;
    if (warped_tissue[v] != 0) {
      ++lung_voxels;
      EXPECT_NEAR(by_tissue.values[v], -1000.0 + 150.0 / j, 1e-3) << v;
      blended_by_side += std::abs(by_side.values[v] - (-1000.0 + 150.0 / j)) > 1.0;
    } else {
      ++vessel_after;
      EXPECT_FLOAT_EQ(by_tissue.values[v], 40.0f) << v;
    }
  }
  EXPECT_GT(lung_voxels, 40000u);
  EXPECT_GT(vessel_after, vessel_voxels);  // the vessel grew with the lung around it
  EXPECT_GT(blended_by_side, 100u);
}

// A CT on the forward field's own grid: its mass-preserving image made in the forward field's
// rasterisation of the rest tets (forward_dvf_with_rest_images) is bit for bit the image that
// mass_preserving_ct makes apart, its rest lungs the field's `lung`, the field and the Jacobian
// image those made apart; the same when the rest tets are kept and when they are replayed. A CT on
// another grid is refused.
TEST(MassPreservingCt, MadeWithTheForwardFieldItIsTheSameImage) {
  const test::Ball ball = test::make_ball();
  const std::vector<Eigen::Vector3d> u = ball.radial(0.4);
  const std::vector<LungMotion> lungs{LungMotion{ball.mesh, u, 0.5}};
  Image ct;
  ct.grid = ball.grid;
  ct.values.resize(ball.grid.voxel_count());
  // Air to bone: parenchyma the rule scales, values it clamps and values it keeps.
  for (std::size_t v = 0; v < ct.values.size(); ++v) ct.values[v] = -1010.0f + static_cast<float>(v % 113) * 10.0f;
  const OutsideField outside = [](const Eigen::Vector3d& x, const Eigen::Vector3d*) {
    return Eigen::Vector3d(0.01 * x);
  };

  const DisplacementField apart = forward_dvf(ball.grid, lungs, outside);
  Image apart_ct, apart_jacobian;
  std::vector<std::uint8_t> ct_lung;
  mass_preserving_ct(ct, lungs, apart_ct, ct_lung);
  jacobian_image(lungs, apart, apart_jacobian);
  std::size_t changed = 0;
  for (std::size_t v = 0; v < ct.values.size(); ++v) changed += apart_ct.values[v] != ct.values[v];
  EXPECT_GT(changed, 5000u);  // the rule acted on the lung's parenchyma

  RestRaster rest;
  for (int pass = 0; pass < 2; ++pass) {  // the rest tets kept, then replayed
    DisplacementField fused;
    Image fused_ct, fused_jacobian;
    forward_dvf_with_rest_images(ball.grid, lungs, fused, outside, RestImages{&fused_jacobian, &ct, &fused_ct}, &rest);
    jacobian_image_outside(fused, fused_jacobian);
    EXPECT_TRUE(rest.holds(ball.grid, lungs));
    EXPECT_EQ(fused.lung, ct_lung) << pass;
    EXPECT_EQ(fused_ct.values, apart_ct.values) << pass;
    EXPECT_EQ(fused_jacobian.values, apart_jacobian.values) << pass;
    EXPECT_EQ(std::memcmp(fused.displacement_m.data(), apart.displacement_m.data(),
                          apart.displacement_m.size() * sizeof(Eigen::Vector3f)),
              0)
        << pass;
  }
  Image other = ct, out;
  other.grid.ijk_to_lps(0, 3) += 1e-3;
  DisplacementField field;
  EXPECT_THROW(forward_dvf_with_rest_images(ball.grid, lungs, field, outside, RestImages{nullptr, &other, &out}),
               ValueError);
}

// One time point with the label map and a CT on its grid (a run at the label map's own grid): the
// warped CT is what the separate steps give (mass_preserving_ct, lung_tissue on both grids,
// warp_image with the rest lungs), bit for bit, whether the rest tets are kept for a later time
// point or not; a time point that keeps none holds no rest raster afterwards.
TEST(TimePoint, ACtOnTheGridIsTheSeparateStepsWarpWithOrWithoutTheKeptRestTets) {
  const test::Ball ball = test::make_ball();
  const std::vector<int> lung_labels{1, 2};
  const std::vector<Eigen::Vector3d> u = ball.radial(0.4);
  const std::vector<LungMotion> lungs{LungMotion{ball.mesh, u, 0.5}};
  const std::vector<LungMotion> at_rest{LungMotion{ball.mesh, u, 0.0}};
  const std::vector<std::uint8_t> rest_lung = rest_lungs(ball.grid, at_rest);
  Image ct;
  ct.grid = ball.grid;
  ct.values.resize(ball.grid.voxel_count());
  for (std::size_t v = 0; v < ct.values.size(); ++v)
    ct.values[v] =
        (ball.labels.labels[v] == 1 || ball.labels.labels[v] == 2 ? -850.0f : 40.0f) + static_cast<float>(v % 7);

  const DisplacementField pull = pullback_dvf(ball.grid, lungs);
  const image::LabelMap warped_labels = warp_labels(ball.labels, pull, &rest_lung, lung_labels);
  std::vector<std::uint8_t> ct_tissue, warped_tissue, ct_lung;
  lung_tissue(ball.labels, lung_labels, ct.grid, ct_tissue);
  lung_tissue(warped_labels, lung_labels, warped_tissue);
  Image preserved;
  mass_preserving_ct(ct, lungs, preserved, ct_lung);
  const Image apart = warp_image(preserved, pull, kOutsideHu, &ct_lung, Tissue{&ct_tissue, &warped_tissue});

  for (const bool keep : {false, true}) {
    TimePointInputs inputs;
    inputs.labels = &ball.labels;
    inputs.rest_lung = &rest_lung;
    inputs.lung_labels = lung_labels;
    inputs.ct = &ct;
    inputs.keep_rest_raster = keep;
    TimePoint point;
    compute_time_point(ball.grid, lungs, inputs, point);
    ASSERT_TRUE(point.ct.has_value());
    EXPECT_EQ(point.ct->values, apart.values) << keep;
    EXPECT_EQ(point.labels->labels, warped_labels.labels) << keep;
    EXPECT_EQ(point.rest_raster.holds(ball.grid, lungs), keep);
  }
}

// Two time points on one TimePoint, the first keeping the rest tets for the second: the second
// replays them and then frees them (it keeps none for a later one), and its fields and Jacobian
// image are those of a time point computed afresh at its scale.
TEST(TimePoint, TheLastTimePointFreesTheKeptRestTetsOnceReplayed) {
  const test::Ball ball = test::make_ball();
  const std::vector<Eigen::Vector3d> u = ball.radial(0.4);
  const std::vector<LungMotion> first{LungMotion{ball.mesh, u, 0.5}}, second{LungMotion{ball.mesh, u, 0.3}};
  TimePointInputs inputs;
  inputs.jacobian_map = true;
  TimePoint point;
  compute_time_point(ball.grid, first, inputs, point);
  ASSERT_TRUE(point.rest_raster.holds(ball.grid, second));  // kept: the rest tets are the same
  inputs.keep_rest_raster = false;
  compute_time_point(ball.grid, second, inputs, point);
  EXPECT_FALSE(point.rest_raster.holds(ball.grid, second));
  EXPECT_TRUE(point.rest_raster.slabs.empty());
  EXPECT_TRUE(point.rest_raster.owner.empty());

  TimePoint fresh;
  compute_time_point(ball.grid, second, inputs, fresh);
  EXPECT_EQ(point.forward.displacement_m, fresh.forward.displacement_m);
  EXPECT_EQ(point.pullback.displacement_m, fresh.pullback.displacement_m);
  ASSERT_TRUE(point.jacobian_map.has_value() && fresh.jacobian_map.has_value());
  EXPECT_EQ(point.jacobian_map->values, fresh.jacobian_map->values);
}

// The label map and an image on its grid warped in one pass (warp_labels_and_image) are the two
// warps made apart, bit for bit: by the pleura's side alone, and with no rest lungs at all. An
// image on another grid is refused.
TEST(WarpLabelsAndImage, OnePassIsTheTwoWarpsBitForBit) {
  const test::Ball ball = test::make_ball();
  const std::vector<int> lung_labels{1, 2};
  const std::vector<Eigen::Vector3d> u = ball.radial(0.4, Eigen::Vector3d(1e-3, -2e-3, 0.5e-3));
  const std::vector<LungMotion> lungs{LungMotion{ball.mesh, u, 0.5}};
  const std::vector<LungMotion> at_rest{LungMotion{ball.mesh, u, 0.0}};
  const std::vector<std::uint8_t> rest_lung = rest_lungs(ball.grid, at_rest);
  const OutsideField outside = [](const Eigen::Vector3d& x, const Eigen::Vector3d*) {
    return Eigen::Vector3d(Eigen::Vector3d(5e-3, -3e-3, 0.0) - 0.02 * x);
  };
  const DisplacementField pull = pullback_dvf(ball.grid, lungs, outside);
  Image image;
  image.grid = ball.grid;
  image.values.resize(ball.grid.voxel_count());
  for (std::size_t v = 0; v < image.values.size(); ++v) image.values[v] = static_cast<float>(v % 1013) * 0.37f;

  for (const bool with_rest : {true, false}) {
    const std::vector<std::uint8_t>* rest = with_rest ? &rest_lung : nullptr;
    const image::LabelMap labels_apart = warp_labels(ball.labels, pull, rest, lung_labels);
    const Image image_apart = warp_image(image, pull, kOutsideHu, rest);
    image::LabelMap labels_fused;
    Image image_fused;
    warp_labels_and_image(ball.labels, image, pull, labels_fused, image_fused, rest, lung_labels, kOutsideHu, rest,
                          nullptr);
    EXPECT_EQ(labels_fused.labels, labels_apart.labels) << with_rest;
    EXPECT_EQ(image_fused.values, image_apart.values) << with_rest;
    std::size_t outside_image = 0;
    for (const float x : image_fused.values) outside_image += x == kOutsideHu;
    EXPECT_GT(outside_image, 0u);  // some samples leave the image: its outside value
  }
  Image other = image;
  other.grid.ijk_to_lps(2, 3) += 1e-3;
  image::LabelMap labels_out;
  Image image_out;
  EXPECT_THROW(warp_labels_and_image(ball.labels, other, pull, labels_out, image_out, &rest_lung, lung_labels,
                                     kOutsideHu, nullptr, nullptr),
               ValueError);
}

// lung_tissue on the label map's own grid (the short way: each voxel its own nearest) is the rule
// itself, voxel by voxel, and what the general way gives on a grid a millionth of a voxel off it.
TEST(LungTissue, OnTheLabelMapsOwnGridEachVoxelIsItsOwnNearest) {
  const test::Ball ball = test::make_ball();
  const std::vector<int> lung_labels{1, 2};
  std::vector<std::uint8_t> own, shifted;
  lung_tissue(ball.labels, lung_labels, grid_of(ball.labels), own);
  Grid off = grid_of(ball.labels);
  off.ijk_to_lps(0, 3) += 1e-9;  // 1 mm voxels: 1e-6 voxel
  lung_tissue(ball.labels, lung_labels, off, shifted);
  ASSERT_EQ(own.size(), ball.labels.labels.size());
  std::size_t lung = 0;
  for (std::size_t v = 0; v < own.size(); ++v) {
    const std::int32_t l = ball.labels.labels[v];
    EXPECT_EQ(own[v], l == 1 || l == 2 ? 1 : 0) << v;
    lung += own[v];
  }
  EXPECT_GT(lung, 10000u);
  EXPECT_EQ(own, shifted);
}

}  // namespace
}  // namespace pneuma::voxels
