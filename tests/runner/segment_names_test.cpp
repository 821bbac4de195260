// Lungs picked by segment name (`values: [name, ...]`, `lungs.<side>: [name, ...]`) in a label map
// that names its segments (3D Slicer's .seg.nrrd): the same surfaces as by label value, and a
// name the file does not hold as one line naming the scenario and the key.
#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/image/label_map.h"
#include "pneuma/runner/output_registry.h"
#include "pneuma/runner/runner.h"
#include "pneuma/scenario/scenario.h"
#include "test_support.h"

using pneuma::test::TempDir;

namespace {

// Two ellipsoids side by side on a 3 mm grid, labels 4 (at -x) and 9 (at +x), written as a raw
// .seg.nrrd whose header names them "lung_right" and "lung_left" (Slicer's SegmentN_* keys).
std::filesystem::path write_two_blobs(const TempDir& dir) {
  constexpr int nx = 40, ny = 24, nz = 28;
  std::vector<std::int16_t> labels(static_cast<std::size_t>(nx) * ny * nz, 0);
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        const double y = (j - ny / 2.0) / 9.0, z = (k - nz / 2.0) / 11.0;
        const double right = (i - 10.0) / 7.0, left = (i - 30.0) / 7.0;
        std::int16_t value = 0;
        if (right * right + y * y + z * z < 1.0) value = 4;
        if (left * left + y * y + z * z < 1.0) value = 9;
        labels[static_cast<std::size_t>(i) + nx * (static_cast<std::size_t>(j) + ny * static_cast<std::size_t>(k))] =
            value;
      }
    }
  }
  std::string header =
      "NRRD0004\ntype: short\ndimension: 3\nsizes: " + std::to_string(nx) + " " + std::to_string(ny) + " " +
      std::to_string(nz) + "\nspace: left-posterior-superior\nspace directions: (3,0,0) (0,3,0) (0,0,3)\n" +
      "kinds: domain domain domain\nendian: little\nencoding: raw\nspace origin: (0,0,0)\n" +
      "Segment0_ID:=Segment_1\nSegment0_Name:=lung_right\nSegment0_LabelValue:=4\nSegment0_Layer:=0\n" +
      "Segment1_ID:=Segment_2\nSegment1_Name:=lung_left\nSegment1_LabelValue:=9\nSegment1_Layer:=0\n\n";
  auto path = dir / "blobs.seg.nrrd";
  std::ofstream out(path, std::ios::binary);
  out << header;
  out.write(reinterpret_cast<const char*>(labels.data()), static_cast<std::streamsize>(labels.size() * 2));
  return path;
}

std::string scenario_with(const std::string& mesh) {
  return "name: named\nduration: 2 s\nframes: {rate: 5 Hz}\nmesh: " + mesh +
         "\nfield: {cache: off}\nphysiology: {preset: healthy-adult}\n";
}

// The rest volume of each lung of a scenario, compiled (right then left).
std::vector<double> rest_volumes(const std::filesystem::path& scenario, const std::filesystem::path& out) {
  const auto s = pneuma::runner::load_scenario(scenario);
  const auto drive = pneuma::scenario::simulate_physiology(s, s.frame_rate_hz);
  const auto compiled = pneuma::runner::prepare(s, drive, {.auto_cache_file = out / "field.h5"});
  std::vector<double> volumes;
  for (const auto& lung : compiled.model.lungs) volumes.push_back(lung.volume_map.volume(0.0));
  return volumes;
}

TEST(SegmentNames, PickTheSameLungsAsTheirLabelValues) {
  TempDir dir;
  write_two_blobs(dir);
  const auto by_value = rest_volumes(
      dir.write(
          "values.yaml",
          scenario_with(
              "{labels: blobs.seg.nrrd, lungs: {right: {values: [4], share: 2 %}, left: {values: [9], share: 2 %}}, edge: 6 mm}")),
      dir / "out-values");
  const auto by_name = rest_volumes(
      dir.write(
          "names.yaml",
          scenario_with(
              "{labels: blobs.seg.nrrd, lungs: {right: {values: [lung_right], share: 2 %}, left: {values: [lung_left], share: 2 %}}, edge: 6 mm}")),
      dir / "out-names");
  ASSERT_EQ(by_value.size(), 2u);
  ASSERT_EQ(by_name.size(), 2u);
  EXPECT_EQ(by_name, by_value);  // the same labels: the same surfaces, bit for bit
  // Each blob is an ellipsoid of semi-axes 21, 27 and 33 mm (voxels counted against the formula).
  const double ellipsoid = 4.0 / 3.0 * 3.14159265358979 * 0.021 * 0.027 * 0.033;
  for (double v : by_name) EXPECT_NEAR(v, ellipsoid, 0.08 * ellipsoid);

  const auto one = rest_volumes(
      dir.write("one.yaml", scenario_with("{labels: blobs.seg.nrrd, values: [lung_left], share: 2 %, edge: 6 mm}")),
      dir / "out-one");
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one[0], by_value[1]);
}

TEST(SegmentNames, AnUnknownNameIsOneLineNamingTheKey) {
  TempDir dir;
  write_two_blobs(dir);
  const auto scenario =
      dir.write("bad.yaml", scenario_with("{labels: blobs.seg.nrrd, values: [lung_middle], edge: 6 mm}"));
  try {
    rest_volumes(scenario, dir / "out");
    FAIL() << "an unknown segment name was accepted";
  } catch (const pneuma::InputError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    EXPECT_EQ(message.rfind(scenario.string() + ": mesh.values: ", 0), 0u) << message;
    EXPECT_NE(message.find("lung_middle"), std::string::npos) << message;
    EXPECT_NE(message.find("lung_right = 4"), std::string::npos) << message;
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "out"));
}

TEST(SegmentNames, ANameInBothLungsIsRefusedAtItsLine) {
  TempDir dir;
  write_two_blobs(dir);
  const auto scenario = dir.write(
      "both.yaml",
      scenario_with("{labels: blobs.seg.nrrd, lungs: {right: [lung_right], left: [lung_right]}, edge: 6 mm}"));
  try {
    pneuma::runner::load_scenario(scenario);
    FAIL() << "a segment in both lungs was accepted";
  } catch (const pneuma::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("mesh.lungs.left: segment 'lung_right' is in both lungs"), std::string::npos)
        << e.what();
  }
}

// A name that resolves to a value the other lung gives by number: refused once resolved.
TEST(SegmentNames, ANameResolvingToTheOtherLungsLabelIsRefused) {
  TempDir dir;
  write_two_blobs(dir);
  const auto scenario = dir.write(
      "clash.yaml", scenario_with("{labels: blobs.seg.nrrd, lungs: {right: {values: [lung_right], share: 2 %}, "
                                  "left: {values: [4], share: 2 %}}, edge: 6 mm}"));
  try {
    rest_volumes(scenario, dir / "out");
    FAIL() << "a label reached by name from both lungs was accepted";
  } catch (const pneuma::InputError& e) {
    EXPECT_EQ(std::string(e.what()), scenario.string() + ": mesh.lungs: label 4 is in both lungs");
  }
}

// A two-lung run by segment names with the voxel outputs and the report's slices: the label map
// is read once (names resolved, each lung extracted apart from the other, the voxel files and the
// slices warped), where it used to be read four times.
TEST(SegmentNames, ATwoLungVoxelRunReadsItsLabelMapOnce) {
  TempDir dir;
  write_two_blobs(dir);
  const auto scenario =
      dir.write("voxels.yaml", "name: named\nduration: 2 s\nframes: {rate: 5 Hz}\n"
                               "mesh: {labels: blobs.seg.nrrd, lungs: {right: {values: [lung_right], share: 2 %}, "
                               "left: {values: [lung_left], share: 2 %}}, edge: 6 mm}\n"
                               "field: {interior: {edge: 8 mm}}\nphysiology: {preset: healthy-adult}\n"
                               "outputs: {gltf: false, hdf5: false, report: true, voxels: {spacing: 4 mm}}\n");
  const auto s = pneuma::runner::load_scenario(scenario);
  const std::size_t before = pneuma::image::label_map_reads();
  const auto result =
      pneuma::runner::run_scenario(s, {.output_dir = dir / "out", .quiet = true, .edge_override_m = std::nullopt});
  EXPECT_EQ(pneuma::image::label_map_reads() - before, 1u);
  EXPECT_TRUE(std::filesystem::exists(dir / "out/voxels/voxels.csv"));
  EXPECT_EQ(result.lungs.size(), 2u);
}

}  // namespace
