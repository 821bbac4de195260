// The voxel outputs of a run (outputs: voxels; docs/voxels.md). Oracles: the physiology's volume
// (the warped label map's lung volume, counted here from the written file, against the rest
// label map's plus each lung's share of the breath), the Jacobian's sign, the surface frames
// (the forward field at the surface against the surface's own displacement), and one-line
// errors for bad options.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "pneuma/mesh/geometry/surface_queries.h"
#include "pneuma/mesh/labels/labels.h"
#include "pneuma/runner/output_registry.h"
#include "pneuma/runner/runner.h"
#include "pneuma/voxels/dvf.h"
#include "pneuma/voxels/voxel_io.h"
#include "test_support.h"

using pneuma::test::run_pneuma;
using pneuma::test::TempDir;

namespace {

struct CsvRow {
  std::string time_point;
  std::string frame;
  double expected_mL = 0, warped_mL = 0, error_percent = 0, min_jacobian = 0;
  std::size_t folded_tets = 0;
  double folded_volume_fraction = 0;
};

std::vector<CsvRow> read_voxels_csv(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "time_point,frame,time_s,scales,physiology_volume_mL,expected_lung_volume_mL,warped_lung_volume_mL,"
                  "volume_error_percent,min_jacobian,max_jacobian,folded_tets,folded_volume_fraction");
  std::vector<CsvRow> rows;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
    EXPECT_EQ(cells.size(), 12u) << line;
    if (cells.size() != 12) continue;
    rows.push_back({cells[0], cells[1], std::stod(cells[5]), std::stod(cells[6]), std::stod(cells[7]),
                    std::stod(cells[8]), std::stoul(cells[10]), std::stod(cells[11])});
  }
  return rows;
}

double lung_voxels_volume_m3(const pneuma::image::LabelMap& map, const std::vector<int>& values) {
  std::size_t n = 0;
  for (const auto v : map.labels) n += std::find(values.begin(), values.end(), v) != values.end();
  return static_cast<double>(n) * map.voxel_volume_m3();
}

constexpr const char* kPhantom = R"(name: voxels
duration: 4 s
frames: {rate: 5 Hz}
mesh: {phantom: right, edge: 8 mm}
field: {tissue: healthy-upright, interior: {edge: 8 mm}}
physiology:
  preset: healthy-adult
  driver: {mode: spontaneous, rate: 15 /min, ie_ratio: 1:2, tidal_volume: 800 mL}
outputs:
  gltf: false
  hdf5: false
  report: false
  voxels: {at: [end_expiration, end_inspiration, 1 s], spacing: 3 mm}
)";

}  // namespace

// With either mesher of the inside (field.interior.mesher), named in the manifest.
class VoxelsRunByMesher : public ::testing::TestWithParam<const char*> {};

TEST_P(VoxelsRunByMesher, ThePhantomsWarpedLungFollowsThePhysiologysVolume) {
  TempDir dir;
  std::string text = kPhantom;
  const std::string from = "interior: {edge: 8 mm}";
  ASSERT_NE(text.find(from), std::string::npos);
  text.replace(text.find(from), from.size(), std::string("interior: {edge: 8 mm, mesher: ") + GetParam() + "}");
  const auto scenario = dir.write("s.yaml", text);
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto rows = read_voxels_csv(dir / "out/voxels/voxels.csv");
  ASSERT_EQ(rows.size(), 3u);
  // Tags as asked: the moments by name, a time by its frame's time; the moments' frames are the
  // extremes of the physiology's volume at the frame rate, simulated here apart from the run.
  EXPECT_EQ(rows[0].time_point, "end_expiration");
  EXPECT_EQ(rows[1].time_point, "end_inspiration");
  EXPECT_EQ(rows[2].time_point, "1.000s");
  EXPECT_EQ(rows[2].frame, "5");
  const auto s = pneuma::runner::load_scenario(scenario);
  const auto volume = pneuma::scenario::simulate_physiology(s, s.frame_rate_hz).series.volume_m3;
  EXPECT_EQ(rows[0].frame, std::to_string(std::min_element(volume.begin(), volume.end()) - volume.begin()));
  EXPECT_EQ(rows[1].frame, std::to_string(std::max_element(volume.begin(), volume.end()) - volume.begin()));
  const auto rest = pneuma::image::read_label_map(dir / "out/voxels/labels-end_expiration.nii.gz");
  const double rest_m3 = lung_voxels_volume_m3(rest, {1});
  for (const CsvRow& row : rows) {
    for (const char* kind : {"dvf-forward-", "dvf-pullback-", "labels-"}) {
      EXPECT_TRUE(std::filesystem::exists(dir / "out/voxels" / (kind + row.time_point + ".nii.gz"))) << row.time_point;
    }
    // Counted here from the file written, not taken from the CSV.
    const auto warped = pneuma::image::read_label_map(dir / "out/voxels" / ("labels-" + row.time_point + ".nii.gz"));
    const double warped_m3 = lung_voxels_volume_m3(warped, {1});
    EXPECT_NEAR(warped_m3 * 1e6, row.warped_mL, 1e-3 * row.warped_mL);
    EXPECT_NEAR(warped_m3 * 1e6 / row.expected_mL, 1.0, 0.02) << row.time_point;
    EXPECT_GT(row.min_jacobian, 0.0) << row.time_point;
    std::cout << row.time_point << ": warped lung " << warped_m3 * 1e6 << " mL, expected " << row.expected_mL << " mL ("
              << row.error_percent << " %), min Jacobian " << row.min_jacobian << "\n";
  }
  // End-inspiration holds more lung than end-expiration, by about the right lung's share of 800 mL.
  const double breath_mL = rows[1].expected_mL - rows[0].expected_mL;
  EXPECT_GT(breath_mL, 300.0);
  EXPECT_NEAR(rows[1].warped_mL - rows[0].warped_mL, breath_mL, 0.1 * breath_mL);
  EXPECT_NEAR(lung_voxels_volume_m3(rest, {1}) * 1e6, rows[0].warped_mL, 1e-3 * rows[0].warped_mL);
  (void)rest_m3;
  const auto manifest = nlohmann::json::parse(pneuma::test::read_text(dir / "out/manifest.json"));
  EXPECT_EQ(manifest.at("facts").at("voxels.time_points").get<std::string>(), "3");
  EXPECT_GT(std::stod(manifest.at("facts").at("voxels.min_jacobian").get<std::string>()), 0.0);
  EXPECT_EQ(manifest.at("facts").at("voxels.interior_mesher").get<std::string>(), GetParam());
}

INSTANTIATE_TEST_SUITE_P(Meshers, VoxelsRunByMesher, ::testing::Values("delaunay", "lattice"));

// A synthetic CT of the phantom (parenchyma -849.5 HU, soft tissue 40 HU) through a run: at
// every time point the lung's mass, (HU + 1000) summed over its voxels times their volume, is the
// rest scan's within 1 %, and the mean lung HU at end-inspiration is the mass-preserving
// prediction -1000 + 150.5 V0 / V within 2 HU; the soft tissue keeps its HU; the Jacobian image
// inside the lung averages V / V0; the warped CT is the same bytes at one and two threads. With
// `density: unchanged` the lung keeps its HU instead.
TEST(VoxelsRun, TheWarpedCtsLungKeepsItsMass) {
  TempDir dir;
  // The rest lung on the run's grid: end-expiration of this breath is the rest shape (s = 0).
  const auto first = dir.write("s.yaml", kPhantom);
  ASSERT_EQ(run_pneuma({"run", first.string(), "-o", (dir / "rest").string(), "--quiet"}).exit_code, 0);
  const auto rest_rows = read_voxels_csv(dir / "rest/voxels/voxels.csv");
  const auto rest =
      pneuma::image::read_label_map(dir / "rest/voxels" / ("labels-" + rest_rows[0].time_point + ".nii.gz"));
  pneuma::voxels::Image ct;
  ct.grid = pneuma::voxels::grid_of(rest);
  ct.values.resize(rest.labels.size());
  std::size_t rest_voxels = 0;
  for (std::size_t v = 0; v < ct.values.size(); ++v) {
    const bool lung = rest.labels[v] == 1;
    ct.values[v] = lung ? -849.5f : 40.0f;
    rest_voxels += lung;
  }
  pneuma::voxels::write_image(dir / "ct.nii.gz", ct);
  const double voxel_m3 = rest.voxel_volume_m3();
  const double rest_mass = static_cast<double>(rest_voxels) * 150.5 * voxel_m3;

  for (const bool preserving : {true, false}) {
    std::string text = kPhantom;
    const std::string from = "voxels: {at: [end_expiration, end_inspiration, 1 s], spacing: 3 mm}";
    ASSERT_NE(text.find(from), std::string::npos);
    text.replace(text.find(from), from.size(),
                 std::string("voxels: {at: [end_expiration, end_inspiration, 1 s], spacing: 3 mm, image: ct.nii.gz") +
                     (preserving ? "}" : ", density: unchanged}"));
    const std::string out = preserving ? "preserving" : "unchanged";
    const auto scenario = dir.write(out + ".yaml", text);
    const auto r = run_pneuma({"--threads", "2", "run", scenario.string(), "-o", (dir / out).string(), "--quiet"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    if (preserving) {  // the warped CT is the same bytes at one thread
      const auto one =
          run_pneuma({"--threads", "1", "run", scenario.string(), "-o", (dir / "one").string(), "--quiet"});
      ASSERT_EQ(one.exit_code, 0) << one.err;
      for (const std::string tag : {"end_inspiration", "1.000s"}) {
        const std::string name = "voxels/ct-" + tag + ".nii.gz";
        EXPECT_TRUE(pneuma::test::read_text(dir / out / name) == pneuma::test::read_text(dir / "one" / name)) << name;
      }
    }
    const auto rows = read_voxels_csv(dir / out / "voxels/voxels.csv");
    ASSERT_EQ(rows.size(), 3u);
    for (const CsvRow& row : rows) {
      const auto labels =
          pneuma::image::read_label_map(dir / out / "voxels" / ("labels-" + row.time_point + ".nii.gz"));
      const auto warped = pneuma::voxels::read_image(dir / out / "voxels" / ("ct-" + row.time_point + ".nii.gz"));
      const auto jacobian =
          pneuma::voxels::read_image(dir / out / "voxels" / ("jacobian-" + row.time_point + ".nii.gz"));
      ASSERT_EQ(warped.values.size(), labels.labels.size());
      double mass = 0.0, lung_hu = 0.0, jacobian_sum = 0.0;
      std::size_t voxels = 0;
      for (std::size_t v = 0; v < labels.labels.size(); ++v) {
        if (labels.labels[v] == 1) {
          mass += (warped.values[v] + 1000.0) * voxel_m3;
          lung_hu += warped.values[v];
          ++voxels;
        } else if (std::abs(warped.values[v] - 40.0f) > 1e-3f &&
                   warped.values[v] != -1024.0f) {  // -1024: beyond the scan
          ADD_FAILURE() << out << " " << row.time_point << ": soft tissue at voxel " << v << " is " << warped.values[v]
                        << " HU";
          break;
        }
        if (rest.labels[v] == 1) jacobian_sum += jacobian.values[v];
      }
      const double growth = static_cast<double>(voxels) / static_cast<double>(rest_voxels);  // V / V0
      if (preserving) {
        EXPECT_NEAR(mass / rest_mass, 1.0, 0.01) << row.time_point;
        EXPECT_NEAR(lung_hu / static_cast<double>(voxels), -1000.0 + 150.5 / growth, 2.0) << row.time_point;
      } else {
        EXPECT_NEAR(lung_hu / static_cast<double>(voxels), -849.5, 0.1) << row.time_point;
      }
      // The mean forward Jacobian over the rest lung is the lung's growth (to its voxelisation).
      EXPECT_NEAR(jacobian_sum / static_cast<double>(rest_voxels), growth, 0.02 * growth) << row.time_point;
      std::cout << out << " " << row.time_point << ": lung " << voxels << " voxels (x" << growth << "), mass x"
                << mass / rest_mass << ", mean " << lung_hu / static_cast<double>(voxels) << " HU\n";
    }
  }
}

// The warped lung's boundary is the surface frame's: the interior's boundary nodes, moved as the
// DVFs move them (the interior field at scale s), lie on the surface of the same frame, and the
// forward DVF at every voxel inside the lung is the interior field there (the DVF's own P1
// interpolation, checked against the tets' nodes by a point-in-tet search here).
TEST(VoxelsRun, TheWarpedLungsBoundaryIsTheSurfaceFrames) {
  TempDir dir;
  const auto file = dir.write("s.yaml", kPhantom);
  const auto s = pneuma::runner::load_scenario(file);
  const auto drive = pneuma::scenario::simulate_physiology(s, s.frame_rate_hz);
  const auto c = pneuma::runner::prepare(s, drive, {.auto_cache_file = dir.path() / "field.h5", .interior = true});
  const auto& lung = c.model.lungs[0];
  const auto& inside = *lung.interior;
  const double scale = c.scales[0].max_scale;
  pneuma::mesh::TriangleMesh frame = lung.rest;
  for (std::size_t v = 0; v < frame.vertices.size(); ++v) frame.vertices[v] += scale * lung.unit_displacement[v];
  std::vector<Eigen::Vector3d> moved;
  for (const auto b : inside.boundary_nodes)
    moved.push_back(inside.mesh.nodes[b] + scale * inside.unit_displacement[b]);
  // The field "position" carried to each point is the closest point of the frame's surface.
  const auto closest = pneuma::mesh::transfer_vertex_field(frame, frame.vertices, moved);
  double worst = 0.0;
  for (std::size_t i = 0; i < moved.size(); ++i) worst = std::max(worst, (moved[i] - closest[i]).norm());
  EXPECT_LT(worst, 1e-6) << "a boundary node left the surface frame by " << worst * 1e3 << " mm";

  pneuma::voxels::Grid grid;
  const double h = 4e-3;
  const auto box = pneuma::mesh::bounding_box(lung.rest.vertices);
  for (int a = 0; a < 3; ++a) grid.size[a] = static_cast<std::size_t>(std::ceil((box[1][a] - box[0][a]) / h)) + 3;
  grid.ijk_to_lps.block<3, 3>(0, 0) *= h;
  grid.ijk_to_lps.block<3, 1>(0, 3) = box[0] - Eigen::Vector3d::Constant(h);
  const std::vector<pneuma::voxels::LungMotion> lungs{{inside.mesh, inside.unit_displacement, scale}};
  const auto forward = pneuma::voxels::forward_dvf(grid, lungs);
  std::size_t checked = 0;
  double largest_error = 0.0, largest_m = 0.0;
  for (std::size_t t = 0; t < inside.mesh.tet_count(); t += 5) {
    // The voxel centre nearest to the tet's centroid, where it lies in this tet.
    const auto& tet = inside.mesh.tets[t];
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto n : tet) centroid += inside.mesh.nodes[n] / 4.0;
    const Eigen::Vector3d ijk = (grid.lps_to_ijk() * centroid.homogeneous()).head<3>().array().round();
    const Eigen::Vector3d x = (grid.ijk_to_lps * ijk.homogeneous()).head<3>();
    Eigen::Matrix3d edges;
    for (int k = 0; k < 3; ++k) edges.col(k) = inside.mesh.nodes[tet[k + 1]] - inside.mesh.nodes[tet[0]];
    const Eigen::Vector3d l = edges.inverse() * (x - inside.mesh.nodes[tet[0]]);
    if (l.minCoeff() < 1e-6 || l.sum() > 1.0 - 1e-6) continue;  // not inside this tet
    const Eigen::Vector3d expected =
        scale * ((1.0 - l.sum()) * inside.unit_displacement[tet[0]] + l[0] * inside.unit_displacement[tet[1]] +
                 l[1] * inside.unit_displacement[tet[2]] + l[2] * inside.unit_displacement[tet[3]]);
    const std::size_t at = grid.index(static_cast<std::size_t>(ijk.x()), static_cast<std::size_t>(ijk.y()),
                                      static_cast<std::size_t>(ijk.z()));
    largest_error = std::max(largest_error, (forward.displacement_m[at].cast<double>() - expected).norm());
    largest_m = std::max(largest_m, expected.norm());
    ++checked;
  }
  ASSERT_GT(checked, 50u);
  EXPECT_LT(largest_error, 1e-9 + 1.1e-7 * largest_m);  // the field's float32: half an ulp per component
}

// `at: [phases]`: a DVF pair and warped label map per respiratory bin of outputs.phases, each at
// the bin's mean volume. Oracles: phases.csv (the bins' mean volumes, from the binning of the
// frames' volumes) and the lung volume counted here in each warped label map.
TEST(VoxelsRun, EachPhaseBinGetsItsFieldsAndLabelMapAtItsMeanVolume) {
  TempDir dir;
  std::string text = kPhantom;
  text.replace(text.find("duration: 4 s"), std::string("duration: 4 s").size(), "duration: 12 s");
  const std::string voxels = "voxels: {at: [end_expiration, end_inspiration, 1 s], spacing: 3 mm}";
  text.replace(text.find(voxels), voxels.size(),
               "voxels: {at: [phases], spacing: 4 mm}\n  phases: {bins: 4, surfaces: false}");
  const auto scenario = dir.write("s.yaml", text);
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;

  std::vector<double> mean_mL;  // phases.csv, by bin
  {
    std::ifstream csv(dir / "out/phases.csv");
    std::string line;
    std::getline(csv, line);
    while (std::getline(csv, line)) {
      std::vector<std::string> cells;
      std::stringstream ss(line);
      for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
      ASSERT_GE(cells.size(), 5u) << line;
      mean_mL.push_back(std::stod(cells[4]));
    }
  }
  ASSERT_EQ(mean_mL.size(), 4u);
  const auto rows = read_voxels_csv(dir / "out/voxels/voxels.csv");
  ASSERT_EQ(rows.size(), 4u);
  std::vector<double> warped_mL;
  for (std::size_t b = 0; b < rows.size(); ++b) {
    EXPECT_EQ(rows[b].time_point, fmt::format("bin_{:02}", b));
    for (const char* kind : {"dvf-forward-", "dvf-pullback-"}) {
      EXPECT_TRUE(std::filesystem::exists(dir / "out/voxels" / (kind + rows[b].time_point + ".nii.gz")));
    }
    const auto warped =
        pneuma::image::read_label_map(dir / "out/voxels" / ("labels-" + rows[b].time_point + ".nii.gz"));
    warped_mL.push_back(lung_voxels_volume_m3(warped, {1}) * 1e6);
    EXPECT_NEAR(warped_mL.back() / rows[b].expected_mL, 1.0, 0.02) << b;
    EXPECT_GT(rows[b].min_jacobian, 0.0) << b;
  }
  // 0 % is end-inspiration, 50 % (bin 2 of 4) end-expiration: the most and the least lung.
  EXPECT_EQ(std::max_element(warped_mL.begin(), warped_mL.end()) - warped_mL.begin(), 0);
  EXPECT_EQ(std::min_element(warped_mL.begin(), warped_mL.end()) - warped_mL.begin(), 2);
  // The warped lung changes between bins as the bins' mean volumes do, times the lung's share
  // (the same share for every pair: one lung, one field).
  const double share = (rows[0].expected_mL - rows[2].expected_mL) / (mean_mL[0] - mean_mL[2]);
  EXPECT_GT(share, 0.3);
  EXPECT_LT(share, 1.0);
  for (std::size_t b : {1u, 3u}) {
    EXPECT_NEAR((rows[b].expected_mL - rows[2].expected_mL) / (mean_mL[b] - mean_mL[2]), share, 1e-3 * share) << b;
    EXPECT_NEAR(warped_mL[b] - warped_mL[2], share * (mean_mL[b] - mean_mL[2]), 0.1 * share * (mean_mL[0] - mean_mL[2]))
        << b;
  }
}

TEST(VoxelsRun, BadOptionsAreOneLineErrorsAndWriteNothing) {
  TempDir dir;
  struct Case {
    std::string voxels, expected;
  };
  const std::vector<Case> cases{
      {"{at: [noon]}",
       "outputs.voxels.at[0]: expected end_expiration, end_inspiration, phases or a time >= 0 with its unit, such as "
       "'2.4 s'"},
      {"{spacing: 0.1 mm}", "outputs.voxels.spacing: expected a voxel size between 0.25 mm and 20 mm, such as '2 mm'"},
      {"{image: missing.nii.gz}", "outputs.voxels.image:"},
      {"{format: png}", "outputs.voxels.format:"},
      {"{format: mha, dvf_convention: nifti}",
       "outputs.voxels.dvf_convention: nifti is NIfTI's convention, and format is mha; expected format nii.gz or nii, "
       "or dvf_convention: itk"},
      {"{dvf_convention: ras}", "outputs.voxels.dvf_convention:"},
      {"{sequences: [mp4]}",
       "outputs.voxels.sequences[0]: expected seq.nrrd (a 3D Slicer sequence) or nii.gz (a 4D NIfTI)"},
  };
  for (const Case& c : cases) {
    std::string text = kPhantom;
    text.replace(text.find("{at: [end_expiration, end_inspiration, 1 s], spacing: 3 mm}"),
                 std::string("{at: [end_expiration, end_inspiration, 1 s], spacing: 3 mm}").size(), c.voxels);
    const auto scenario = dir.write("bad.yaml", text);
    const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
    EXPECT_EQ(r.exit_code, 3) << c.voxels << ": " << r.err;
    EXPECT_NE(r.err.find(c.expected), std::string::npos) << c.voxels << ": " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "out")) << c.voxels;
  }
}

// A time after the run's end used to become the last frame, and a CT that is a slice or misses the
// lungs gave -1024 HU everywhere (#49): each is one line at its key, and nothing is written.
TEST(VoxelsRun, ATimeAfterTheEndOrACtThatMissesTheLungsIsRefusedAtItsKey) {
  TempDir dir;
  // A slice, and a 3D block of 4 mm at the origin's corner far from the phantom (the voxels' outer
  // faces from x = 100 mm on, the lungs within 20 cm of the origin).
  pneuma::voxels::Image slice, block;
  slice.grid.size = {8, 8, 1};
  slice.values.assign(64, 0.0f);
  pneuma::voxels::write_image(dir / "slice.nii.gz", slice);
  block.grid.size = {4, 4, 4};
  block.grid.ijk_to_lps.block<3, 1>(0, 3) = Eigen::Vector3d(0.1005, 0.1005, 0.1005);
  block.grid.ijk_to_lps.block<3, 3>(0, 0) *= 1e-3;
  block.values.assign(64, 0.0f);
  pneuma::voxels::write_image(dir / "block.nii.gz", block);
  const std::string from = "{at: [end_expiration, end_inspiration, 1 s], spacing: 3 mm}";
  const auto write = [&](const std::string& voxels) {
    std::string text = kPhantom;
    text.replace(text.find(from), from.size(), voxels);
    return dir.write("bad.yaml", text).string();
  };
  struct Case {
    std::string voxels, expected_begin, expected_end;
  };
  const std::vector<Case> cases{
      {"{at: [1 s, 100 s]}",
       ":13:22: outputs.voxels.at[1]: 100 s is after the run's end (4 s); expected a time from 0 to 4 s\n", ""},
      {"{image: slice.nii.gz}",
       ":13:19: outputs.voxels.image: " + (dir / "slice.nii.gz").string() +
           ": 8 x 8 x 1 voxels; expected a 3D CT around the lungs\n",
       ""},
      {"{image: block.nii.gz}",
       ":13:19: outputs.voxels.image: " + (dir / "block.nii.gz").string() +
           " covers x 100.0..104.0, y 100.0..104.0, z 100.0..104.0 mm (LPS), not all of the lungs at rest (",
       "); expected a CT around the lungs\n"},
  };
  for (const Case& c : cases) {
    const std::string scenario = write(c.voxels);
    const auto r = run_pneuma({"run", scenario, "-o", (dir / "out").string(), "--quiet"});
    EXPECT_EQ(r.exit_code, 3) << c.voxels << ": " << r.err;
    EXPECT_EQ(r.err.substr(0, scenario.size() + c.expected_begin.size()), scenario + c.expected_begin) << r.err;
    EXPECT_TRUE(r.err.ends_with(c.expected_end)) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    // The CT's reach is known after compile, once the run's (empty) folder exists.
    EXPECT_TRUE(!std::filesystem::exists(dir / "out") || std::filesystem::is_empty(dir / "out")) << c.voxels;
  }
}

TEST(VoxelsRun, AnUnfoldingVolumeOutOfRangeOrAnUnknownMesherIsRefusedAtItsKey) {
  struct Case {
    std::string interior, expected;
  };
  for (const Case& c : {Case{"interior: {edge: 8 mm, unfold: 9 L}",
                             "field.interior.unfold: expected a volume from 0 L to 5 L above rest, such as '1 L'"},
                        Case{"interior: {edge: 8 mm, mesher: voronoi}",
                             "field.interior.mesher: expected one of: delaunay, lattice; got 'voronoi'"}}) {
    TempDir dir;
    std::string text = kPhantom;
    const std::string from = "interior: {edge: 8 mm}";
    ASSERT_NE(text.find(from), std::string::npos);
    text.replace(text.find(from), from.size(), c.interior);
    const auto scenario = dir.write("bad.yaml", text);
    const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
    EXPECT_EQ(r.exit_code, 3) << r.err;
    EXPECT_NE(r.err.find(c.expected), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "out"));
  }
}

// Both lungs of each shared CT case: the warped label map's lungs follow the physiology's volume
// within 2 % at end-expiration and end-inspiration, and no tetrahedron of the forward map folds
// (the unfolding, docs/voxels.md: before it 1-5 of ~50k per lung folded at 6 mm). The tets
// with all four nodes on the surface that fold are left out of the map: their volume is bounded.
class CtVoxels : public ::testing::TestWithParam<const char*> {};

TEST_P(CtVoxels, TheWarpedLobesFollowThePhysiologysVolume) {
  const auto file = pneuma::test::ct_lobes_dir() / (std::string(GetParam()) + "_lobes.nii.gz");
  if (!std::filesystem::exists(file)) {
    GTEST_SKIP() << "no CT lobe maps at " << file.parent_path()
                 << " (set PNEUMA_CT_LOBES to the folder of case00N_lobes.nii.gz)";
  }
  TempDir dir;
  const auto scenario =
      dir.write("ct.yaml", "duration: 4 s\nframes: {rate: 5 Hz}\nmesh: {labels: " + file.string() +
                               ", lungs: {right: [3, 4, 5], left: [1, 2]}, edge: 5 mm}\n"
                               "field: {tissue: healthy-upright-ct, interior: {edge: 6 mm}}\n"
                               "physiology:\n  preset: healthy-adult\n"
                               "  driver: {mode: spontaneous, rate: 15 /min, ie_ratio: 1:2, tidal_volume: 800 mL}\n"
                               "outputs: {gltf: false, report: false, hdf5: false, voxels: {spacing: 4 mm}}\n");
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << GetParam() << ": " << r.err;
  const auto rows = read_voxels_csv(dir / "out/voxels/voxels.csv");
  ASSERT_EQ(rows.size(), 2u);
  for (const CsvRow& row : rows) {
    const auto warped = pneuma::image::read_label_map(dir / "out/voxels" / ("labels-" + row.time_point + ".nii.gz"));
    const double warped_mL = lung_voxels_volume_m3(warped, {1, 2, 3, 4, 5}) * 1e6;
    EXPECT_NEAR(warped_mL / row.expected_mL, 1.0, 0.02) << GetParam() << " " << row.time_point;
    EXPECT_EQ(row.folded_tets, 0u) << GetParam() << " " << row.time_point;
    EXPECT_GT(row.min_jacobian, 0.0) << GetParam() << " " << row.time_point;
    std::cout << GetParam() << " " << row.time_point << ": warped lungs " << warped_mL << " mL, expected "
              << row.expected_mL << " mL, min Jacobian " << row.min_jacobian << ", folded tets " << row.folded_tets
              << " (" << row.folded_volume_fraction << " of the volume)\n";
  }
  EXPECT_GT(rows[1].warped_mL - rows[0].warped_mL, 600.0) << GetParam();
  const auto manifest = nlohmann::json::parse(pneuma::test::read_text(dir / "out/manifest.json"));
  const double dropped_mm3 = std::stod(manifest.at("facts").at("voxels.dropped_volume_mm3").get<std::string>());
  EXPECT_LT(dropped_mm3, 1e-4 * rows[0].warped_mL * 1e3) << GetParam();  // below 1e-4 of the lungs
  std::cout << GetParam() << ": unfolded nodes " << manifest.at("facts").at("voxels.unfolded_nodes").get<std::string>()
            << ", dropped tets " << manifest.at("facts").at("voxels.dropped_tets").get<std::string>() << " ("
            << dropped_mm3 << " mm3)\n";
}

INSTANTIATE_TEST_SUITE_P(RealAnatomy, CtVoxels,
                         ::testing::Values("case004", "case005", "case006", "case007", "case008", "case009"));

// A phase set is never silently empty: a run too short for one whole cycle (end-inspiration to
// end-inspiration; 2 s of 15 /min breathing holds one peak) is one line naming the key that asked
// for the bins, exit 3, and nothing written. Eight seconds at 12 /min hold one cycle now (the
// second peak counts once the volume has turned back from it).
TEST(VoxelsRun, APhaseSetWithoutAWholeCycleIsRefused) {
  TempDir dir;
  std::string text = kPhantom;
  text.replace(text.find("duration: 4 s"), 13, "duration: 2 s");
  const std::string voxels = "voxels: {at: [end_expiration, end_inspiration, 1 s], spacing: 3 mm}";
  for (const auto& [outputs, key] : {std::pair<std::string, std::string>{"phases: {bins: 10}", "outputs.phases"},
                                     {"voxels: {at: [phases], spacing: 3 mm}", "outputs.voxels.at"}}) {
    std::string with = text;
    with.replace(with.find(voxels), voxels.size(), outputs);
    const auto scenario = dir.write("short.yaml", with);
    const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
    EXPECT_EQ(r.exit_code, 3) << key;
    EXPECT_EQ(r.err, scenario.string() + ": " + key +
                         ": the 2 s run holds no whole breathing cycle, end-inspiration to end-inspiration, to bin "
                         "into phases; expected a longer duration, two breaths at least\n");
    EXPECT_TRUE(!std::filesystem::exists(dir / "out") || std::filesystem::is_empty(dir / "out")) << key;
  }
  // 8 s at 12 /min: one whole cycle, ten bins.
  const auto eight =
      dir.write("eight.yaml", std::string("name: eight\nduration: 8 s\nframes: {rate: 10 Hz}\n") +
                                  "mesh: {phantom: right, edge: 8 mm}\n"
                                  "physiology: {preset: healthy-adult}\n"
                                  "outputs: {gltf: false, hdf5: false, report: false, phases: {bins: 10}}\n");
  const auto r = run_pneuma({"run", eight.string(), "-o", (dir / "eight").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto manifest = nlohmann::json::parse(pneuma::test::read_text(dir / "eight/manifest.json"));
  EXPECT_EQ(manifest.at("facts").at("phases.cycles").get<std::string>(), "1");
}

// The shipped 10-phase example (scenarios/4d-ct-phases.yaml, case004, a coarser surface here):
// every bin holds frames of four whole cycles and gets its DVFs, warped labels and Jacobian, the
// warped lungs' volume within 2 % of the physiology's at every phase.
TEST(VoxelsRun, TheShippedPhaseExampleMakesAFullTenPhaseSet) {
  const auto data = pneuma::test::ct_lobes_dir() / "case004_lobes.nii.gz";
  if (!std::filesystem::exists(data)) GTEST_SKIP() << "no CT lobe maps at " << data.parent_path();
  TempDir dir;
  const auto scenario = std::filesystem::path(PNEUMA_SOURCE_DIR) / "scenarios/4d-ct-phases.yaml";
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet", "--edge", "6mm"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::stringstream phases(pneuma::test::read_text(dir / "out/phases.csv"));
  std::string line;
  std::getline(phases, line);
  int bins = 0;
  while (std::getline(phases, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
    ASSERT_GE(cells.size(), 4u) << line;
    EXPECT_EQ(cells[3], "4") << line;  // every bin from each of the four cycles
    ++bins;
  }
  EXPECT_EQ(bins, 10);
  const auto rows = read_voxels_csv(dir / "out/voxels/voxels.csv");
  ASSERT_EQ(rows.size(), 10u);
  for (int b = 0; b < 10; ++b) {
    const CsvRow& row = rows[static_cast<std::size_t>(b)];
    EXPECT_EQ(row.time_point, fmt::format("bin_{:02}", b));
    EXPECT_LT(std::abs(row.error_percent), 2.0) << row.time_point;
    EXPECT_EQ(row.folded_tets, 0u) << row.time_point;
    for (const char* kind : {"dvf-forward-", "dvf-pullback-", "labels-", "jacobian-"})
      EXPECT_TRUE(std::filesystem::exists(dir / "out/voxels" / (kind + row.time_point + ".nii.gz"))) << kind;
  }
}

namespace {

// The phantom voxel scenario (kPhantom) run with `mesh_keys` added to its mesh map, into dir/name:
// its voxels.csv rows.
std::vector<CsvRow> run_phantom_with_mesh_keys(const TempDir& dir, const std::string& name,
                                               const std::string& mesh_keys) {
  std::string text = kPhantom;
  text.replace(text.find("edge: 8 mm}"), 11, "edge: 8 mm" + mesh_keys + "}");
  const auto scenario = dir.write(name + ".yaml", text);
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / name).string(), "--quiet"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return read_voxels_csv(dir / name / "voxels/voxels.csv");
}

// voxels.csv's column physiology_volume_mL, row by row.
std::vector<double> physiology_volumes_mL(const std::filesystem::path& voxels_csv) {
  std::stringstream csv(pneuma::test::read_text(voxels_csv));
  std::string line;
  std::getline(csv, line);
  std::vector<double> volumes;
  while (std::getline(csv, line)) {
    std::stringstream cells(line);
    std::string cell;
    for (int c = 0; c <= 4; ++c) std::getline(cells, cell, ',');
    volumes.push_back(std::stod(cell));
  }
  return volumes;
}

}  // namespace

// A scan taken 150 mL above FRC (mesh.reference_volume): the rest label map stands for that
// volume, so each time point expects the lung's share of 150 mL less lung than the same run with
// the scan at FRC (the rest shape is the same; only what it stands for moved), and the warped
// map holds it.
TEST(VoxelsRun, TheScansVolumeIsTheReferenceOfTheExpectedVolumes) {
  TempDir dir;
  const auto at_frc = run_phantom_with_mesh_keys(dir, "frc", "");
  const auto above = run_phantom_with_mesh_keys(dir, "above", ", reference_volume: 150 mL");
  ASSERT_EQ(at_frc.size(), 3u);
  ASSERT_EQ(above.size(), 3u);
  // The lung's share of the breath, from the run at FRC (expected = rest + share V).
  const std::vector<double> physiology_mL = physiology_volumes_mL(dir / "frc/voxels/voxels.csv");
  ASSERT_EQ(physiology_mL.size(), 3u);
  const double share = (at_frc[1].expected_mL - at_frc[0].expected_mL) / (physiology_mL[1] - physiology_mL[0]);
  EXPECT_GT(share, 0.3);
  EXPECT_LE(share, 1.0);
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_EQ(above[k].time_point, at_frc[k].time_point);
    EXPECT_NEAR(at_frc[k].expected_mL - above[k].expected_mL, share * 150.0, 0.05) << above[k].time_point;  // 6 digits
    EXPECT_NEAR(above[k].warped_mL / above[k].expected_mL, 1.0, 0.02) << above[k].time_point;
    EXPECT_GT(above[k].min_jacobian, 0.0) << above[k].time_point;
  }
}

// A breath-hold scan (mesh.breath: end_inspiration, #45): the rest label map stands for the
// breath's peak, so voxels.csv expects the scan's lung at end-inspiration and the scan's minus the
// lung's share of the whole breath at end-expiration, and the warped map holds that, unfolded.
// The oracle is the same phantom run with the scan at FRC: its expected volumes less the lung's
// share of the physiology's volume give the scan's lung volume, whatever the breath.
TEST(VoxelsRun, ABreathHoldScanIsTheEndInspirationOfTheExpectedVolumes) {
  TempDir dir;
  const auto at_frc = run_phantom_with_mesh_keys(dir, "frc", "");
  const auto held = run_phantom_with_mesh_keys(dir, "held", ", breath: end_inspiration");
  ASSERT_EQ(at_frc.size(), 3u);
  ASSERT_EQ(held.size(), 3u);
  const std::vector<double> physiology_mL = physiology_volumes_mL(dir / "frc/voxels/voxels.csv");
  ASSERT_EQ(physiology_mL.size(), 3u);
  ASSERT_EQ(at_frc[0].time_point, "end_expiration");
  ASSERT_EQ(at_frc[1].time_point, "end_inspiration");
  const double share = (at_frc[1].expected_mL - at_frc[0].expected_mL) / (physiology_mL[1] - physiology_mL[0]);
  const double scan_mL = at_frc[0].expected_mL - share * physiology_mL[0];
  const double breath_mL = physiology_mL[1] - physiology_mL[0];
  EXPECT_GT(breath_mL, 700.0);  // the 800 mL breath of kPhantom
  for (std::size_t k = 0; k < 3; ++k) {
    SCOPED_TRACE(held[k].time_point);
    EXPECT_EQ(held[k].time_point, at_frc[k].time_point);
    // Below the scan by the lung's share of what the breath has still to rise.
    EXPECT_NEAR(held[k].expected_mL, scan_mL - share * (physiology_mL[1] - physiology_mL[k]), 0.05);
    EXPECT_NEAR(held[k].warped_mL / held[k].expected_mL, 1.0, 0.02);
    EXPECT_NEAR(held[k].error_percent, (held[k].warped_mL / held[k].expected_mL - 1.0) * 100.0, 0.01);
    EXPECT_EQ(held[k].folded_tets, 0u);
    EXPECT_GT(held[k].min_jacobian, 0.0);
  }
  EXPECT_NEAR(held[1].expected_mL, scan_mL, 0.05);                      // the scan is end-inspiration
  EXPECT_NEAR(held[0].expected_mL, scan_mL - share * breath_mL, 0.05);  // deflated by the whole breath
}

// A time point at rest (t = 0: the physiology at FRC, every lung at s = 0) writes exact zero
// fields, forward and pull-back, inside the lungs and out: no rounding noise for a compressor to
// store (it was 18 MB against the forward field's 1.7 MB on case004).
TEST(VoxelsRun, ATimePointAtRestIsAnExactZeroField) {
  TempDir dir;
  std::string text = kPhantom;
  const std::string at = "at: [end_expiration, end_inspiration, 1 s]";
  text.replace(text.find(at), at.size(), "at: [0 s], format: nii");
  const auto scenario = dir.write("s.yaml", text);
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* kind : {"dvf-forward-0.000s.nii", "dvf-pullback-0.000s.nii"}) {
    const auto bytes = pneuma::test::read_text(dir / "out/voxels" / kind);
    // NIfTI-1: vox_offset (a float) at byte 108; the voxels float32 from there to the end.
    float offset = 0.0f;
    std::memcpy(&offset, bytes.data() + 108, 4);
    ASSERT_GT(offset, 0.0f) << kind;
    std::size_t nonzero = 0, values = 0;
    for (std::size_t b = static_cast<std::size_t>(offset); b + 4 <= bytes.size(); b += 4, ++values) {
      float value = 0.0f;
      std::memcpy(&value, bytes.data() + b, 4);
      nonzero += value != 0.0f;
    }
    EXPECT_GT(values, 100000u) << kind;
    EXPECT_EQ(nonzero, 0u) << kind;
  }
}

// Every .nii.gz of a run (DVFs, warped labels, Jacobian) at a 1 mm grid (the DVFs over 4 MiB:
// several gzip members, voxels/gzip.h) is the same bytes at --threads 1 and 2, and nibabel reads
// from each the values of the same run written plain (`format: nii`).
TEST(VoxelsRun, TheNiftiGzFilesAreTheSameBytesAtAnyThreadCountAndNibabelReadsThem) {
  TempDir dir;
  std::string text = kPhantom;
  const std::string from = "{at: [end_expiration, end_inspiration, 1 s], spacing: 3 mm}";
  text.replace(text.find(from), from.size(), "{at: [end_inspiration], spacing: 1 mm}");
  const auto scenario = dir.write("s.yaml", text);
  std::string plain_text = text;
  plain_text.replace(plain_text.find("spacing: 1 mm"), 13, "spacing: 1 mm, format: nii");
  const auto plain = dir.write("plain.yaml", plain_text);
  for (const auto& [yaml, threads, out] :
       {std::tuple{scenario, "1", "one"}, std::tuple{scenario, "2", "two"}, std::tuple{plain, "2", "plain"}}) {
    const auto r = run_pneuma({"--threads", threads, "run", yaml.string(), "-o", (dir / out).string(), "--quiet"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  // Over 4 MiB plain: several gzip members.
  EXPECT_GT(std::filesystem::file_size(dir / "plain/voxels/dvf-pullback-end_inspiration.nii"), std::size_t{8} << 20);
  const std::vector<std::string> kinds{"dvf-forward", "dvf-pullback", "labels", "jacobian"};
  for (const auto& kind : kinds) {
    const std::string name = "voxels/" + kind + "-end_inspiration.nii.gz";
    const std::string one = pneuma::test::read_text(dir / "one" / name);
    EXPECT_TRUE(one == pneuma::test::read_text(dir / "two" / name)) << name;
  }
  if (pneuma::test::run_program("/usr/bin/python3", {"-c", "import nibabel, numpy"}).exit_code != 0)
    GTEST_SKIP() << "nibabel is not importable by /usr/bin/python3 (install-deps: python3-nibabel)";
  const std::string script =
      "import sys, nibabel, numpy as np\n"
      "for k in sys.argv[2:]:\n"
      "  gz = np.array(nibabel.load(f'{sys.argv[1]}/two/voxels/{k}-end_inspiration.nii.gz').dataobj)\n"
      "  nii = np.array(nibabel.load(f'{sys.argv[1]}/plain/voxels/{k}-end_inspiration.nii').dataobj)\n"
      "  assert gz.dtype == nii.dtype and np.array_equal(gz, nii), k\n"
      "  assert np.any(nii != 0), k\n";
  std::vector<std::string> args{"-c", script, dir.path().string()};
  args.insert(args.end(), kinds.begin(), kinds.end());
  const auto r = pneuma::test::run_program("/usr/bin/python3", args);
  EXPECT_EQ(r.exit_code, 0) << r.err;
}
