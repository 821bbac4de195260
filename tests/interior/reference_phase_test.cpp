// A breath-hold scan (issue #45, docs/voxels.md "The scan's place on the breath"): on every shared
// CT lung (six cases, both lungs), `mesh.breath: end_inspiration` with a 500 mL quiet breath puts
// the scan at the breath's peak, so each lung deflates from it by its share of 500 mL. The run
// prepares (runner::prepare: V -> s and the CGAL check of both lungs at both extremes), and at
// end-expiration, checked here apart from the code that made it:
//  - each lung's surface does not self-intersect (CGAL), and the two lungs do not cut each other;
//  - no tetrahedron of either inside folds: the Jacobian of rest -> end-expiration, each tet's
//    deformed volume over its rest volume from its own four nodes, stays above 0.1;
//  - the lungs' volume, CGAL's enclosed volume of the moved surfaces (not the volume cubic that
//    chose s), is the scan's (CGAL's enclosed volume of the rest surfaces) minus the breath's
//    500 mL within 2 % (of the end-expiration volume), and each lung's change is its share of it.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <iostream>

#include "pneuma/mesh/geometry/deformed_surface.h"
#include "pneuma/mesh/geometry/surface_queries.h"
#include "pneuma/mesh/geometry/validate.h"
#include "pneuma/runner/output_registry.h"
#include "pneuma/runner/runner.h"
#include "pneuma/scenario/physiology_config.h"
#include "test_support.h"

namespace pneuma {
namespace {

mesh::TriangleMesh moved_surface(const model::LungModel& lung, double s) {
  mesh::TriangleMesh out = lung.rest;
  for (std::size_t i = 0; i < out.vertices.size(); ++i) out.vertices[i] += s * lung.unit_displacement[i];
  return out;
}

// The smallest Jacobian det(d moved / d rest) over the lung's tetrahedra at scale s.
double min_tet_jacobian(const model::LungInterior& inside, double s) {
  double lowest = 1e300;
  for (const mesh::Tetrahedron& q : inside.mesh.tets) {
    const double rest = mesh::tet_volume6(inside.mesh.nodes[q[0]], inside.mesh.nodes[q[1]], inside.mesh.nodes[q[2]],
                                          inside.mesh.nodes[q[3]]);
    lowest = std::min(lowest, mesh::deformed_volume6(inside.mesh, q, inside.unit_displacement, s) / rest);
  }
  return lowest;
}

class CtBreathHold : public ::testing::TestWithParam<const char*> {};

TEST_P(CtBreathHold, AQuietBreathFromTheScanAtEndInspirationNeitherFoldsNorSelfIntersects) {
  const auto file = test::ct_lobes_dir() / (std::string(GetParam()) + "_lobes.nii.gz");
  if (!std::filesystem::exists(file)) {
    GTEST_SKIP() << "no CT lobe maps at " << file.parent_path()
                 << " (set PNEUMA_CT_LOBES to the folder of case00N_lobes.nii.gz)";
  }
  test::TempDir dir;
  const auto yaml = dir.write("s.yaml", "name: breath-hold\nduration: 6 s\nframes: {rate: 10 Hz}\n"
                                        "mesh:\n  labels: " +
                                            file.string() +
                                            "\n  lungs: {right: [3, 4, 5], left: [1, 2]}\n"
                                            "  edge: 4 mm\n  breath: end_inspiration\n"
                                            "field: {tissue: healthy-supine, cache: off, interior: {edge: 6 mm}}\n"
                                            "physiology: {preset: healthy-adult}\n"
                                            "outputs: {gltf: false, report: false, hdf5: false}\n");
  const scenario::Scenario s = runner::load_scenario(yaml);
  const auto drive = scenario::simulate_physiology(s, s.frame_rate_hz);
  const auto [lowest, highest] = std::minmax_element(drive.series.volume_m3.begin(), drive.series.volume_m3.end());
  const double tidal_m3 = *highest - *lowest;
  ASSERT_NEAR(tidal_m3, 500e-6, 25e-6);  // the preset's quiet breath

  const runner::Prepared c = runner::prepare(s, drive, {.interior = true});  // throws on a fold
  ASSERT_EQ(c.model.lungs.size(), 2u);
  double scan_m3 = 0.0, expiration_m3 = 0.0;
  std::array<double, 2> at{};
  for (std::size_t i = 0; i < 2; ++i) {
    const model::LungModel& lung = c.model.lungs[i];
    SCOPED_TRACE(std::string(GetParam()) + (i == 0 ? " right" : " left"));
    EXPECT_DOUBLE_EQ(lung.reference_volume_m3, *highest);
    at[i] = c.scales[i].min_scale;
    EXPECT_LT(at[i], 0.0);
    EXPECT_LE(c.scales[i].max_scale, 1e-9);  // the scan is the breath's largest lung
    const mesh::TriangleMesh moved = moved_surface(lung, at[i]);
    EXPECT_FALSE(mesh::self_intersects(moved));
    const double rest_m3 = mesh::cgal_enclosed_volume(lung.rest);
    const double moved_m3 = mesh::cgal_enclosed_volume(moved);
    EXPECT_NEAR((rest_m3 - moved_m3) / (lung.share * tidal_m3), 1.0, 0.02);
    scan_m3 += rest_m3;
    expiration_m3 += moved_m3;
    ASSERT_NE(lung.interior, nullptr);
    const double j = min_tet_jacobian(*lung.interior, at[i]);
    EXPECT_GT(j, 0.1);
    std::cout << GetParam() << (i == 0 ? " right" : " left") << ": scan " << rest_m3 * 1e6 << " mL, end-expiration "
              << moved_m3 * 1e6 << " mL (" << (rest_m3 - moved_m3) * 1e6 << " mL less, share "
              << lung.share * tidal_m3 * 1e6 << " mL), deflation smoothing " << lung.deflation_sigma_m * 1e3
              << " mm, min J " << j << ", " << lung.interior->mesh.tet_count() << " tets\n";
  }
  EXPECT_NEAR(expiration_m3 / (scan_m3 - tidal_m3), 1.0, 0.02);
  // The two lungs at end-expiration, as one surface: they do not cut into each other.
  mesh::TriangleMesh both = moved_surface(c.model.lungs[0], at[0]);
  const mesh::TriangleMesh left = moved_surface(c.model.lungs[1], at[1]);
  const auto offset = static_cast<std::uint32_t>(both.vertices.size());
  both.vertices.insert(both.vertices.end(), left.vertices.begin(), left.vertices.end());
  for (mesh::Triangle t : left.triangles) {
    for (auto& v : t) v += offset;
    both.triangles.push_back(t);
  }
  EXPECT_FALSE(mesh::self_intersects(both));
  std::cout << GetParam() << ": both lungs " << scan_m3 * 1e6 << " mL at the scan, " << expiration_m3 * 1e6
            << " mL at end-expiration (expected " << (scan_m3 - tidal_m3) * 1e6
            << " mL: " << (expiration_m3 / (scan_m3 - tidal_m3) - 1.0) * 100 << " %)\n";
}

INSTANTIATE_TEST_SUITE_P(RealAnatomy, CtBreathHold,
                         ::testing::Values("case004", "case005", "case006", "case007", "case008", "case009"));

}  // namespace
}  // namespace pneuma
