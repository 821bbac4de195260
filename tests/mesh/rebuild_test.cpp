// repair()'s last resort, the rebuild from the inside (mesh/repair/src/voxel_rebuild.cpp): handles of
// segmentations removed, non-manifold closed surfaces made valid, and what must stay as it is
// (a wide handle, an open non-manifold surface) kept or refused. Oracles: analytic volumes, the
// Euler characteristic, the validator.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "mesh_fixture.h"
#include "pneuma/core/error.h"
#include "pneuma/mesh/geometry/validate.h"
#include "pneuma/mesh/labels/labels.h"
#include "pneuma/mesh/repair/repair.h"

using namespace pneuma::mesh;
using namespace pneuma::image;

namespace {

constexpr double kPi = std::numbers::pi;

bool mentions(const RepairReport& report, const std::string& text) {
  for (const auto& a : report.actions()) {
    if (a.find(text) != std::string::npos) return true;
  }
  return false;
}

std::string actions(const RepairReport& report) {
  std::string all;
  for (const auto& a : report.actions()) all += a + "\n";
  return all;
}

// A ball of radius 30 mm on a 1 mm grid with a straight tunnel of radius 2 mm bored through it
// along x: a genus-1 surface whose handle is a segmentation-sized defect.
TriangleMesh bored_ball() {
  LabelMap map;
  map.size = {80, 80, 80};
  map.ijk_to_lps.topLeftCorner<3, 3>() *= 1e-3;
  map.labels.assign(map.voxel_count(), 0);
  for (std::size_t k = 0; k < 80; ++k)
    for (std::size_t j = 0; j < 80; ++j)
      for (std::size_t i = 0; i < 80; ++i) {
        const double x = static_cast<double>(i) - 39.5, y = static_cast<double>(j) - 39.5,
                     z = static_cast<double>(k) - 39.5;
        const bool ball = x * x + y * y + z * z <= 30.0 * 30.0, tunnel = y * y + z * z <= 2.0 * 2.0;
        map.labels[i + 80 * (j + 80 * k)] = ball && !tunnel ? 1 : 0;
      }
  return surface_from_labels(
             map, "bored", {1},
             {.edge_length_m = 2e-3, .smoothing_m = 0.6e-3, .closing_radius_m = 0.0, .remove_handles = false})
      .mesh;
}

}  // namespace

TEST(Rebuild, ASmallHandleIsRemovedAndTheVolumeKept) {
  const TriangleMesh bored = bored_ball();
  const ValidationReport before = validate(bored);
  ASSERT_TRUE(before.valid()) << before.summary();
  ASSERT_EQ(before.genus, 1) << "the fixture has its handle";

  const RepairResult r = repair(bored, "bored");
  const ValidationReport after = validate(r.mesh);
  EXPECT_TRUE(after.valid()) << after.summary();
  EXPECT_EQ(after.genus, 0);
  EXPECT_EQ(after.component_count, 1u);
  EXPECT_EQ(r.report.handles_removed, 1);
  EXPECT_EQ(r.report.handles_kept, 0);
  EXPECT_TRUE(mentions(r.report, "rebuilt 1 component from its inside (1 handle)")) << actions(r.report);
  EXPECT_TRUE(mentions(r.report, "removed 1 handle")) << actions(r.report);
  // The tunnel (0.75 mL) is filled: the whole ball, 113.1 mL, within the smoothing's rounding.
  EXPECT_NEAR(enclosed_volume(r.mesh) / (4.0 / 3.0 * kPi * std::pow(30e-3, 3)), 1.0, 0.02);
}

TEST(Rebuild, AWideHandleIsKeptAndReported) {
  // A torus (hole 40 mm across): filling it would add about half again to the volume.
  const TriangleMesh torus = test::make_torus(30e-3, 10e-3, 64, 32);
  ASSERT_EQ(validate(torus).genus, 1);
  const RepairResult r = repair(torus, "torus");
  EXPECT_EQ(r.mesh.triangle_count(), torus.triangle_count()) << "kept as it was";
  EXPECT_EQ(r.report.handles_removed, 0);
  EXPECT_EQ(r.report.handles_kept, 1);
  EXPECT_EQ(r.report.rebuilt_components, 0u);
  EXPECT_TRUE(mentions(r.report, "kept 1 handle (genus 1): removing them would change the enclosed volume by +"))
      << actions(r.report);
  // Off: kept without trying.
  const RepairResult off = repair(torus, "torus", {.rebuild_through_voxels = false});
  EXPECT_TRUE(mentions(off.report, "kept 1 handle (genus 1): rebuilding is off")) << actions(off.report);
}

TEST(Rebuild, TwoSolidsSharingAWallBecomeOneValidSurface) {
  // Two 20 mm cubes that share a face, both complete (as lobes exported with their fissure):
  // the wall's four vertices shared, its edges on four faces each.
  TriangleMesh m = test::make_cube(20e-3, {10e-3, 10e-3, 10e-3});
  const TriangleMesh second = test::make_cube(20e-3, {30e-3, 10e-3, 10e-3});
  std::vector<std::uint32_t> index(second.vertex_count());
  for (std::size_t v = 0; v < second.vertex_count(); ++v) {
    const auto same = std::find_if(m.vertices.begin(), m.vertices.end(),
                                   [&](const Eigen::Vector3d& p) { return (p - second.vertices[v]).norm() < 1e-12; });
    index[v] = static_cast<std::uint32_t>(same - m.vertices.begin());
    if (same == m.vertices.end()) m.vertices.push_back(second.vertices[v]);
  }
  for (Triangle t : second.triangles) {
    for (auto& v : t) v = index[v];
    m.triangles.push_back(t);
  }
  ASSERT_EQ(m.vertex_count(), 12u) << "the wall's corners are shared";
  const ValidationReport before = validate(m);
  ASSERT_FALSE(before.manifold()) << before.summary();

  const RepairResult r = repair(m, "lobes");
  const ValidationReport after = validate(r.mesh);
  EXPECT_TRUE(after.valid()) << after.summary();
  EXPECT_EQ(after.genus, 0);
  EXPECT_EQ(after.component_count, 1u);
  EXPECT_EQ(r.report.rebuilt_components, 1u);
  EXPECT_TRUE(mentions(r.report, "rebuilt 1 component from its inside (4 non-manifold edges, first 1-3"))
      << actions(r.report);
  // The 40 x 20 x 20 mm block, 16 mL, its edges rounded by one voxel of smoothing; no wall inside.
  EXPECT_NEAR(enclosed_volume(r.mesh) / 16e-6, 1.0, 0.05);
  const auto box = bounding_box(r.mesh.vertices);
  EXPECT_NEAR(box[1].x() - box[0].x(), 40e-3, 1.5e-3);
  EXPECT_NEAR(box[1].y() - box[0].y(), 20e-3, 1.5e-3);
  EXPECT_THROW(repair(m, "lobes", {.rebuild_through_voxels = false}), pneuma::InputError);
}
