// Both lungs in one run (`phantom: both`, `mesh.lungs`): each lung's frames measured
// independently against its share of the physiology, every output with both lungs, the CT
// cases with both lungs at 4 mm, and the bad spellings as one-line errors.
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <hdf5.h>
#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pneuma/mesh/geometry/surface_queries.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "pneuma/mesh/labels/labels.h"
#include "pneuma/physiology/simulate.h"
#include "pneuma/runner/output_registry.h"
#include "pneuma/runner/runner.h"
#include "runner_fixture.h"
#include "test_support.h"

using pneuma::test::file_volume;
using pneuma::test::run_pneuma;
using pneuma::test::TempDir;

namespace {

// 9 s of quiet breathing (two cycles) at 10 frames/s on both 12 mm phantoms, every per-frame output.
constexpr const char* kBoth = R"(name: both
duration: 9 s
frames: {rate: 10 Hz}
mesh: {phantom: both, edge: 12 mm}
field: {tissue: healthy-upright}
physiology:
  preset: healthy-adult
  driver: {mode: spontaneous, rate: 15 /min, ie_ratio: 1:2, tidal_volume: 500 mL}
outputs:
  mesh_sequence: {format: ply}
  hdf5: {positions: float64}
  phases: true
)";

std::filesystem::path lung_frame(const std::filesystem::path& dir, const char* lung, std::size_t k) {
  return dir / fmt::format("{}_{:05}.ply", lung, k);
}

std::vector<double> read_column(hid_t file, const std::string& path) {
  const hid_t set = H5Dopen2(file, path.c_str(), H5P_DEFAULT);
  EXPECT_GE(set, 0) << path;
  if (set < 0) return {};
  const hid_t space = H5Dget_space(set);
  hsize_t n = 0;
  H5Sget_simple_extent_dims(space, &n, nullptr);
  std::vector<double> out(n);
  H5Dread(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data());
  H5Sclose(space);
  H5Dclose(set);
  return out;
}

double fact(const nlohmann::json& manifest, const std::string& key) {
  return std::stod(manifest.at("facts").at(key).get<std::string>());
}

}  // namespace

TEST(TwoLungs, EachLungsFramesFollowItsShareOfTheBreath) {
  TempDir dir;
  const auto scenario = dir.write("both.yaml", kBoth);
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;

  // The physiology again, independently of the runner, at the frame times.
  const auto s = pneuma::runner::load_scenario(scenario);
  auto options = s.physiology.options;
  options.output_rate_hz = 10.0;
  const auto phys = pneuma::physiology::simulate(s.physiology.protocol, options);
  ASSERT_EQ(phys.series.size(), 91u);
  const auto manifest = nlohmann::json::parse(pneuma::test::read_text(dir / "out/manifest.json"));
  for (const auto& [lung, share] : {std::pair{"right", 0.55}, std::pair{"left", 0.45}}) {
    const double rest = file_volume(lung_frame(dir / "out/frames", lung, 0));  // V(0) = 0: the rest mesh
    EXPECT_NEAR(fact(manifest, fmt::format("lungs.{}.rest_volume_m3", lung)), rest, 1e-6 * rest) << lung;
    EXPECT_EQ(fact(manifest, fmt::format("lungs.{}.share", lung)), share);
    double largest = 0.0;
    for (std::size_t k = 0; k < phys.series.size(); ++k) {
      const double expected_change = share * phys.series.volume_m3[k];
      const double measured_change = file_volume(lung_frame(dir / "out/frames", lung, k)) - rest;
      largest = std::max(largest, expected_change);
      EXPECT_NEAR(measured_change, expected_change, 1e-3 * share * 0.5e-3 + 1e-7 * rest) << lung << " frame " << k;
    }
    EXPECT_GT(largest, 0.15e-3) << lung;  // a real breath happened
  }
  // The two phantoms are two surfaces: the totals are their sums.
  EXPECT_EQ(fact(manifest, "vertices"), fact(manifest, "lungs.right.vertices") + fact(manifest, "lungs.left.vertices"));
  for (const char* file : {"field-right.h5", "field-left.h5", "phases/bin_00_right.ply", "phases/bin_00_left.ply"})
    EXPECT_TRUE(std::filesystem::exists(dir / "out" / file)) << file;
  EXPECT_FALSE(std::filesystem::exists(dir / "out/field.h5"));

  // series.h5: each lung's group, its mesh volume column against the frame files.
  const hid_t file = H5Fopen((dir / "out/series.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  for (const char* lung : {"right", "left"}) {
    const auto mesh_volume = read_column(file, fmt::format("/{}/frames/mesh_volume_m3", lung));
    const auto lung_volume = read_column(file, fmt::format("/{}/frames/lung_volume_m3", lung));
    ASSERT_EQ(mesh_volume.size(), 91u);
    for (std::size_t k : {0u, 12u, 30u}) {
      EXPECT_NEAR(mesh_volume[k], file_volume(lung_frame(dir / "out/frames", lung, k)), 1e-6 * mesh_volume[k])
          << lung << " " << k;
      EXPECT_DOUBLE_EQ(lung_volume[k], phys.series.volume_m3[k]);
    }
  }
  H5Fclose(file);
  const std::string xdmf = pneuma::test::read_text(dir / "out/series.xdmf");
  EXPECT_NE(xdmf.find("CollectionType=\"Spatial\""), std::string::npos);
  EXPECT_NE(xdmf.find("series.h5:/left/frames/positions/000090"), std::string::npos);

  // motion.csv: a lung column, rows of both lungs.
  const std::string motion = pneuma::test::read_text(dir / "out/motion.csv");
  EXPECT_EQ(motion.rfind("lung,breath,start_s,region,", 0), 0u) << motion.substr(0, 80);
  EXPECT_NE(motion.find("\nright,0,"), std::string::npos);
  EXPECT_NE(motion.find("\nleft,0,"), std::string::npos);
  EXPECT_TRUE(manifest.at("facts").contains("motion.left.diaphragmatic.caudal_mean_mm"));
}

TEST(TwoLungs, TheGlbHoldsTwoMeshesEachWithItsOwnWeightTrack) {
  TempDir dir;
  const auto scenario = dir.write("both.yaml", kBoth);
  ASSERT_EQ(run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"}).exit_code, 0);
  tinygltf::Model m;
  tinygltf::TinyGLTF loader;
  std::string error, warning;
  ASSERT_TRUE(loader.LoadBinaryFromFile(&m, &error, &warning, (dir / "out/breathing.glb").string())) << error;
  ASSERT_EQ(m.meshes.size(), 2u);
  ASSERT_EQ(m.nodes.size(), 2u);
  ASSERT_EQ(m.scenes.at(0).nodes.size(), 2u);
  ASSERT_EQ(m.animations.size(), 1u);
  ASSERT_EQ(m.animations[0].channels.size(), 2u);
  auto floats = [&](int accessor) {
    const auto& a = m.accessors.at(static_cast<std::size_t>(accessor));
    const auto& v = m.bufferViews.at(static_cast<std::size_t>(a.bufferView));
    return reinterpret_cast<const float*>(m.buffers[0].data.data() + v.byteOffset + a.byteOffset);
  };
  const pneuma::mesh::ReadOptions o;  // the unit each frame records (mm)
  for (std::size_t i = 0; i < 2; ++i) {
    const char* lung = i == 0 ? "right" : "left";
    const auto& channel = m.animations[0].channels[i];
    ASSERT_EQ(channel.target_node, static_cast<int>(i));
    EXPECT_EQ(m.nodes[i].name, std::string(lung) + " lung");
    const auto& primitive = m.meshes.at(static_cast<std::size_t>(m.nodes[i].mesh)).primitives.at(0);
    const float* rest = floats(primitive.attributes.at("POSITION"));
    const float* delta = floats(primitive.targets.at(0).at("POSITION"));
    const float* weights = floats(m.animations[0].samplers.at(static_cast<std::size_t>(channel.sampler)).output);
    for (std::size_t k : {5u, 17u, 33u}) {
      const auto frame = pneuma::mesh::read_mesh(lung_frame(dir / "out/frames", lung, k), o);
      ASSERT_EQ(frame.vertex_count(),
                m.accessors.at(static_cast<std::size_t>(primitive.attributes.at("POSITION"))).count);
      for (std::size_t v = 0; v < frame.vertex_count(); v += 7) {
        for (int c = 0; c < 3; ++c) {
          const std::size_t j = 3 * v + static_cast<std::size_t>(c);
          EXPECT_NEAR(rest[j] + weights[k] * delta[j], frame.vertices[v][c], 2e-6) << lung << " frame " << k;
        }
      }
    }
  }
}

// Bad spellings of two lungs: one line naming the file, line:col and key path; exit 3.
TEST(TwoLungs, BadSpellingsAreOneLineErrors) {
  TempDir dir;
  dir.write("r.ply", "");
  const std::string labels = (pneuma::test::ct_lobes_dir() / "case004_lobes.nii.gz").string();
  const bool have_labels = std::filesystem::exists(labels);
  struct Case {
    std::string mesh;
    std::string at;  // where in the mesh line the error points
    std::string expected;
    bool needs_labels;
  };
  const std::vector<Case> cases{
      {"{labels: " + labels + ", lungs: {right: [3, 4, 5], middle: [1, 2]}}", "[1, 2]}}",
       "mesh.lungs.middle: expected the lungs 'right' and 'left'", true},
      {"{labels: " + labels + ", lungs: {right: [3, 4, 5], left: [1, 2, 5]}}", "[1, 2, 5]",
       "mesh.lungs.left: label 5 is in both lungs", true},
      {"{phantom: both, lungs: {right: {file: r.ply}, left: {file: r.ply}}}", "{right",
       "mesh.lungs: give either phantom or lungs ('phantom: both' is both phantoms)", false},
      {"{phantom: both, share: 50 %}", "50 %",
       "mesh.share: two lungs: give each lung's share under lungs.<side>.share (default 55 %, 45 %)", false},
      {"{lungs: {right: {file: r.ply, share: 70 %}, left: {file: r.ply}}}", "{right",
       "mesh.lungs: the lungs' shares add up to 115 %, more than the whole breath", false},
      {"{phantom: middle}", "middle", "mesh.phantom: expected one of: left, right, both; got 'middle'", false},
  };
  for (const Case& c : cases) {
    if (c.needs_labels && !have_labels) continue;
    const std::string line = "mesh: " + c.mesh;
    const std::string yaml = std::string("name: bad\nduration: 1 s\nframes: {rate: 10 Hz}\nfield: {cache: off}\n") +
                             line + "\nphysiology: {preset: healthy-adult}\n";
    const auto scenario = dir.write("bad.yaml", yaml);
    const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
    EXPECT_EQ(r.exit_code, 3) << c.mesh;
    EXPECT_EQ(r.err, fmt::format("{}:5:{}: {}\n", scenario.string(), line.find(c.at) + 1, c.expected)) << c.mesh;
  }
}

// Both lungs of each shared CT case in one scenario at 4 mm, breathing 1.5 L. Oracles: each
// lung's rest volume against its voxel count (counted here, not by the surface extraction), its
// frames' volumes against its share of the breath, and the two surfaces of the written
// end-inspiration frame, read back, free of intersections.
class CtBothLungs : public ::testing::TestWithParam<const char*> {};

TEST_P(CtBothLungs, OneScenarioBreathesBothLungs) {
  const auto file = pneuma::test::ct_lobes_dir() / (std::string(GetParam()) + "_lobes.nii.gz");
  if (!std::filesystem::exists(file)) {
    GTEST_SKIP() << "no CT lobe maps at " << file.parent_path()
                 << " (set PNEUMA_CT_LOBES to the folder of case00N_lobes.nii.gz)";
  }
  TempDir dir;
  const auto scenario =
      dir.write("ct.yaml", "duration: 4 s\nframes: {rate: 5 Hz}\nmesh: {labels: " + file.string() +
                               ", lungs: {right: [3, 4, 5], left: [1, 2]}, edge: 4 mm}\n"
                               "field: {tissue: healthy-upright-ct}\n"
                               "physiology:\n  preset: healthy-adult\n"
                               "  driver: {mode: spontaneous, rate: 15 /min, ie_ratio: 1:2, tidal_volume: 1.5 L}\n"
                               "outputs: {gltf: false, report: false, hdf5: false, mesh_sequence: {format: ply}}\n");
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << GetParam() << ": " << r.err;
  const auto manifest = nlohmann::json::parse(pneuma::test::read_text(dir / "out/manifest.json"));
  const pneuma::image::LabelMap map = pneuma::image::read_label_map(file);
  const auto s = pneuma::runner::load_scenario(scenario);
  auto options = s.physiology.options;
  options.output_rate_hz = 5.0;
  const auto phys = pneuma::physiology::simulate(s.physiology.protocol, options);
  const auto end_inspiration = static_cast<std::size_t>(
      std::max_element(phys.series.volume_m3.begin(), phys.series.volume_m3.end()) - phys.series.volume_m3.begin());
  EXPECT_GT(phys.series.volume_m3[end_inspiration], 1.4e-3);
  pneuma::mesh::TriangleMesh both;
  const pneuma::mesh::ReadOptions o;  // the unit each frame records (mm)
  for (const auto& [lung, share, labels] :
       {std::tuple{"right", 0.55, std::vector<int>{3, 4, 5}}, std::tuple{"left", 0.45, std::vector<int>{1, 2}}}) {
    std::size_t voxels = 0;
    for (std::int32_t label : map.labels) voxels += std::find(labels.begin(), labels.end(), label) != labels.end();
    const double rest = fact(manifest, fmt::format("lungs.{}.rest_volume_m3", lung));
    const double voxel_volume = static_cast<double>(voxels) * map.voxel_volume_m3();
    EXPECT_NEAR(rest / voxel_volume, 1.0, 0.05) << lung;
    const double change = file_volume(lung_frame(dir / "out/frames", lung, end_inspiration)) - rest;
    EXPECT_NEAR(change, share * phys.series.volume_m3[end_inspiration], 1e-3 * share * 1.5e-3 + 1e-7 * rest) << lung;
    std::cout << GetParam() << " " << lung << ": rest " << rest * 1e3 << " L, voxels " << voxel_volume * 1e3 << " L ("
              << (rest / voxel_volume - 1.0) * 100.0 << " %), end-inspiration +" << change * 1e3 << " L\n";
    const auto frame = pneuma::mesh::read_mesh(lung_frame(dir / "out/frames", lung, end_inspiration), o);
    const auto offset = static_cast<std::uint32_t>(both.vertices.size());
    both.vertices.insert(both.vertices.end(), frame.vertices.begin(), frame.vertices.end());
    for (auto t : frame.triangles) {
      for (auto& v : t) v += offset;
      both.triangles.push_back(t);
    }
  }
  EXPECT_FALSE(pneuma::mesh::self_intersects(both)) << GetParam() << ": the lungs intersect at end-inspiration";
}

INSTANTIATE_TEST_SUITE_P(RealAnatomy, CtBothLungs,
                         ::testing::Values("case004", "case005", "case006", "case007", "case008", "case009"));

// A lung may follow one compartment of a two_compartment physiology: each lung's frames then
// take its share of that compartment's volume, measured on the written frames against the
// compartments simulated again here.
TEST(TwoLungs, EachLungMayFollowItsOwnCompartment) {
  TempDir dir;
  for (const char* side : {"right", "left"}) {
    const auto r =
        run_pneuma({"phantom", "--lung", side, "--edge", "12mm", "-o", (dir / (side + std::string(".ply"))).string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  const auto scenario = dir.write("comp.yaml", R"(name: comp
duration: 4 s
frames: {rate: 10 Hz}
mesh:
  lungs: {right: {file: right.ply, compartment: upper}, left: {file: left.ply, compartment: lower, share: 90 %}}
  unit: mm
  edge: 12 mm
physiology:
  model: two_compartment
  resistance: 1 cmH2O*s/L
  compartments:
    upper: {compliance: 0.04 L/cmH2O, resistance: 1 cmH2O*s/L}
    lower: {compliance: 0.06 L/cmH2O, resistance: 3 cmH2O*s/L}
  driver: {mode: spontaneous, rate: 15 /min, ie_ratio: 1:2, tidal_volume: 500 mL}
outputs: {mesh_sequence: {format: ply}, gltf: false, report: false, hdf5: false}
)");
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto s = pneuma::runner::load_scenario(scenario);
  auto options = s.physiology.options;
  options.output_rate_hz = 10.0;
  const auto phys = pneuma::physiology::simulate(s.physiology.protocol, options);
  ASSERT_EQ(phys.compartment_names, (std::vector<std::string>{"upper", "lower"}));
  for (const auto& [lung, compartment, share] : {std::tuple{"right", 0u, 1.0}, std::tuple{"left", 1u, 0.9}}) {
    const auto& v = phys.series.compartment_volume_m3.at(compartment);
    const double rest = file_volume(lung_frame(dir / "out/frames", lung, 0));
    double largest = 0.0;
    for (std::size_t k = 0; k < v.size(); k += 3) {
      const double measured = file_volume(lung_frame(dir / "out/frames", lung, k)) - rest;
      EXPECT_NEAR(measured, share * v[k], 1e-3 * 0.3e-3 + 1e-7 * rest) << lung << " frame " << k;
      largest = std::max(largest, share * v[k]);
    }
    EXPECT_GT(largest, 0.1e-3) << lung;
  }
  // The compartments fill differently (other compliance and resistance): the lungs do not
  // simply split the total.
  const auto& upper = phys.series.compartment_volume_m3[0];
  const auto& lower = phys.series.compartment_volume_m3[1];
  double apart = 0.0;
  for (std::size_t k = 0; k < upper.size(); ++k) apart = std::max(apart, std::abs(upper[k] - lower[k]));
  EXPECT_GT(apart, 0.05e-3);

  // A compartment of a one-compartment physiology is refused, naming the key.
  std::string yaml = pneuma::test::read_text(scenario);
  yaml = yaml.substr(0, yaml.find("physiology:")) + "physiology: {preset: healthy-adult}\n";
  const auto single = dir.write("single.yaml", yaml);
  const auto bad = run_pneuma({"run", single.string(), "-o", (dir / "bad").string(), "--quiet"});
  EXPECT_EQ(bad.exit_code, 3);
  const std::string line = yaml.substr(yaml.find("  lungs:"));
  EXPECT_EQ(bad.err, fmt::format("{}:5:{}: mesh.lungs.right.compartment: a lung follows a compartment of a "
                                 "two_compartment physiology model only\n",
                                 single.string(), line.find("upper") + 1));
}

// Two lungs that cut into each other (here the same surface twice) are refused before any
// output, with the lungs and scales named; exit 5.
TEST(TwoLungs, LungsThatIntersectEachOtherAreRefused) {
  TempDir dir;
  const auto r = run_pneuma({"phantom", "--lung", "right", "--edge", "12mm", "-o", (dir / "right.ply").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto scenario = dir.write("same.yaml", R"(name: same
duration: 2 s
frames: {rate: 10 Hz}
mesh: {lungs: {right: {file: right.ply}, left: {file: right.ply}}, unit: mm, edge: 12 mm}
physiology: {preset: healthy-adult}
)");
  const auto run = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
  EXPECT_EQ(run.exit_code, 5);
  EXPECT_EQ(
      run.err.rfind(scenario.string() + ": the right and left lungs intersect each other at their lowest scales", 0),
      0u)
      << run.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "out/manifest.json"));
}

// The fold check's pass kept in the output folder (model::NoFoldRecord, #50) skips the check only
// for the same surfaces at the same scales: in every other case the check runs afresh, and refuses
// what check_no_fold() without the record (the oracle) refuses.
TEST(TwoLungs, TheFoldChecksPassIsKeptOnlyForTheSameSurfacesAndScales) {
  TempDir dir;
  const auto r = run_pneuma({"phantom", "--lung", "right", "--edge", "12mm", "-o", (dir / "right.ply").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string head = "duration: 2 s\nframes: {rate: 10 Hz}\nphysiology: {preset: healthy-adult}\n";
  const auto apart = pneuma::runner::load_scenario(
      dir.write("apart.yaml", "name: apart\n" + head + "mesh: {phantom: both, edge: 12 mm}\n"));
  const auto same = pneuma::runner::load_scenario(dir.write(
      "same.yaml", "name: same\n" + head +
                       "mesh: {lungs: {right: {file: right.ply}, left: {file: right.ply}}, unit: mm, edge: 12 mm}\n"));
  const std::filesystem::path kept = dir / "self-intersection.check";
  const pneuma::model::NoFoldRecord record{kept, kept};
  const auto checked = [](const pneuma::runner::Prepared& p) {
    for (const auto& [stage, seconds] : p.timings_s) {
      if (stage.starts_with("self-intersection check")) return stage == "self-intersection check";
    }
    ADD_FAILURE() << "no fold check among the timings";
    return false;
  };
  const auto drive = pneuma::scenario::simulate_physiology(apart, apart.frame_rate_hz);
  const auto first = pneuma::runner::prepare(apart, drive, {.auto_cache_file = dir / "a" / "field.h5"}, record);
  EXPECT_TRUE(checked(first));
  const std::string empty_sha256 = "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855";
  EXPECT_EQ(pneuma::test::read_text(kept), "pneuma-no-fold 1\nkey " +
                                               pneuma::model::no_fold_key(first.model, first.scales) +
                                               "\nbytes 0 sha256 " + empty_sha256 + "\n");
  const auto second = pneuma::runner::prepare(apart, drive, {.auto_cache_file = dir / "a" / "field.h5"}, record);
  EXPECT_FALSE(checked(second));  // the same surfaces and scales: kept
  EXPECT_TRUE(pneuma::model::check_no_fold(second.model, second.scales, {kept, {}}));

  // Two lungs on one surface, with apart's pass at hand: checked, and refused as without it.
  const auto same_drive = pneuma::scenario::simulate_physiology(same, same.frame_rate_hz);
  const std::string before = pneuma::test::read_text(kept);
  EXPECT_THROW(pneuma::runner::prepare(same, same_drive, {.auto_cache_file = dir / "s" / "field.h5"}),
               pneuma::UnsupportedError);
  EXPECT_THROW(pneuma::runner::prepare(same, same_drive, {.auto_cache_file = dir / "s" / "field.h5"}, record),
               pneuma::UnsupportedError);
  EXPECT_EQ(pneuma::test::read_text(kept), before) << "a refused check keeps nothing";

  // The same model at scales far beyond the run's (its surfaces cross themselves): checked.
  std::vector<pneuma::model::LungScales> far = first.scales;
  for (auto& lung : far) lung.max_scale = 60.0 * std::max(1.0, lung.max_scale);
  EXPECT_THROW(pneuma::model::check_no_fold(first.model, far), pneuma::UnsupportedError);
  EXPECT_THROW(pneuma::model::check_no_fold(first.model, far, {kept, {}}), pneuma::UnsupportedError);

  // The right lung's surface moved onto the left's: checked, and refused.
  pneuma::model::Model moved = first.model;
  Eigen::Vector3d right_centre = Eigen::Vector3d::Zero(), left_centre = Eigen::Vector3d::Zero();
  for (const auto& v : moved.lungs[0].rest.vertices) right_centre += v / double(moved.lungs[0].rest.vertex_count());
  for (const auto& v : moved.lungs[1].rest.vertices) left_centre += v / double(moved.lungs[1].rest.vertex_count());
  for (auto& v : moved.lungs[0].rest.vertices) v += 0.5 * (left_centre - right_centre);
  EXPECT_THROW(pneuma::model::check_no_fold(moved, first.scales), pneuma::UnsupportedError);
  EXPECT_THROW(pneuma::model::check_no_fold(moved, first.scales, {kept, {}}), pneuma::UnsupportedError);
}

// `phantom: both` runs the demo (quiet-breathing.yaml, every output it asks for, PNG frames
// included) at a coarse edge, and the shipped two-lung scenario runs on its CT case.
TEST(TwoLungs, TheDemoAndTheShippedScenarioRunWithBothLungs) {
  TempDir dir;
  std::string demo = pneuma::test::read_text(pneuma::test::source_dir() / "scenarios/quiet-breathing.yaml");
  const std::string one =
      "  phantom: right\n  edge: 4 mm\n  share: 55 %               # the right lung takes about 55 % of each breath\n";
  ASSERT_NE(demo.find(one), std::string::npos);
  demo.replace(demo.find(one), one.size(), "  phantom: both\n  edge: 4 mm\n");
  const auto scenario = dir.write("demo.yaml", demo);
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "demo").string(), "--edge", "15mm", "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* file :
       {"breathing.glb", "series.h5", "series.xdmf", "series-right.xdmf", "series-left.xdmf", "physiology.csv",
        "motion.csv", "report.html", "png/frame_00000.png", "png/frame_01800.png", "field-right.h5", "field-left.h5"})
    EXPECT_TRUE(std::filesystem::exists(dir / "demo" / file)) << file;

  const auto shipped = pneuma::test::source_dir() / "scenarios/both-lungs-from-labels.yaml";
  const auto data =
      shipped.parent_path() / "../../shared/data/ct-lobes/case004_lobes.nii.gz";  // as the scenario names it
  if (!std::filesystem::exists(data)) GTEST_SKIP() << "no " << data << " for " << shipped.filename();
  const auto ct = run_pneuma({"run", shipped.string(), "-o", (dir / "ct").string(), "--edge", "12mm", "--quiet"});
  ASSERT_EQ(ct.exit_code, 0) << ct.err;
  const auto manifest = nlohmann::json::parse(pneuma::test::read_text(dir / "ct/manifest.json"));
  EXPECT_EQ(fact(manifest, "lungs.right.share"), 0.55);
  EXPECT_EQ(fact(manifest, "lungs.left.share"), 0.45);
}

// The two lungs are compiled side by side (model/compile.cpp): at one thread one after the other,
// at two on two threads at once. Every file of a run with the lungs' insides, the voxel outputs
// and report.html's slices is the same byte for byte at both counts (manifest.json aside: its
// stage times), and the manifest still names each lung's stages in lung order.
TEST(TwoLungs, TheLungsMadeSideBySideGiveTheSameFilesAtOneAndTwoThreads) {
  TempDir dir;
  std::string text = kBoth;
  const std::string outputs = "  phases: true\n";
  text.replace(text.find(outputs), outputs.size(),
               "  report: true\n  voxels: {at: [end_inspiration], spacing: 6 mm}\n");
  text.replace(text.find("duration: 9 s"), 13, "duration: 4 s");
  const auto scenario = dir.write("s.yaml", text);
  for (const char* threads : {"1", "2"}) {
    const auto r =
        run_pneuma({"--threads", threads, "run", scenario.string(), "-o", (dir / threads).string(), "--quiet"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  std::size_t compared = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir / "1")) {
    if (!entry.is_regular_file() || entry.path().filename() == "manifest.json") continue;
    const auto relative = std::filesystem::relative(entry.path(), dir / "1");
    EXPECT_TRUE(pneuma::test::read_text(entry.path()) == pneuma::test::read_text(dir / "2" / relative)) << relative;
    ++compared;
  }
  EXPECT_GE(compared, std::size_t{10});  // fields, insides, frames, voxels, report
  // In the file's order (ordered_json: a plain json sorts the keys).
  const auto manifest = nlohmann::ordered_json::parse(pneuma::test::read_text(dir / "2/manifest.json"));
  std::vector<std::string> stages;
  for (const auto& [name, seconds] : manifest["timings_s"].items()) stages.push_back(name);
  const auto at = [&](const std::string& name) {
    return std::find(stages.begin(), stages.end(), name) - stages.begin();
  };
  EXPECT_LT(at("mesh and field (right lung)"), at("interior (right lung)"));
  EXPECT_LT(at("interior (right lung)"), at("mesh and field (left lung)"));
  EXPECT_LT(at("mesh and field (left lung)"), at("interior (left lung)"));
  EXPECT_LT(at("interior (left lung)"), static_cast<std::ptrdiff_t>(stages.size()));
}
