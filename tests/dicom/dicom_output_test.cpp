// DICOM out (outputs.voxels.dicom; docs/formats.md, "DICOM"), checked by tools independent of
// pneuma: dciodvfy (dicom3tools) finds no error in any file, dcmdump reads each, plastimatch reads
// each phase's CT series (HU within 1 of pneuma's NIfTI, voxel centres within 0.01 mm) and
// RTSTRUCT (each structure's mask against pneuma's warped label map: Dice >= 0.95), pydicom finds
// one study and frame of reference over all phases (the input series' when the CT was DICOM, UIDs
// made under 2.25 otherwise) and the RTSTRUCTs referencing their series' slices
// (tests/dicom/check_dicom_outputs.py). A second run at one thread writes the same bytes.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include <Eigen/LU>

#include "pneuma/image/label_map.h"
#include "pneuma/image/scalar_image.h"
#include "test_support.h"

namespace fs = std::filesystem;
using pneuma::test::run_program;
using pneuma::test::TempDir;

namespace {

constexpr const char* kStructures =
    R"({"lung_right": [3, 4, 5], "lung_left": [1, 2], "label_1": [1], "label_2": [2], "label_3": [3], )"
    R"("label_4": [4], "label_5": [5]})";

std::string scenario_text(const std::string& image) {
  return fmt::format(R"(name: dicom-phases
duration: 8 s
frames: {{rate: 5 Hz}}
mesh:
  labels: {}
  lungs: {{right: [3, 4, 5], left: [1, 2]}}
  edge: 8 mm
field:
  tissue: healthy-supine
  interior: {{edge: 8 mm, mesher: lattice, unfold: 1 L}}
physiology: {{preset: healthy-adult}}
outputs:
  gltf: false
  hdf5: false
  report: false
  phases: {{bins: 4}}
  voxels: {{at: [phases], spacing: 5 mm, image: {}, dicom: true, jacobian: false}}
)",
                     (pneuma::test::ct_lobes_dir() / "case004_lobes.nii.gz").string(), image);
}

// The CT of case004 (lungs -850 + 10 label HU, air -1000) as a DICOM series and as NIfTI.
void make_ct(const TempDir& dir) {
  const auto r =
      run_program("/usr/bin/python3", {(pneuma::test::source_dir() / "tests/dicom/make_ct_series.py").string(),
                                       (pneuma::test::ct_lobes_dir() / "case004_lobes.nii.gz").string(),
                                       (dir / "ct").string(), (dir / "ct.nii.gz").string(), "--step", "4"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
}

std::vector<fs::path> dicom_files(const fs::path& run) {
  std::vector<fs::path> files;
  for (const auto& e : fs::recursive_directory_iterator(run / "dicom")) {
    if (e.is_regular_file()) files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

// dciodvfy's errors (lines "Error - ...") and dcmdump's exit status, file by file.
void expect_valid_dicom(const std::vector<fs::path>& files) {
  const fs::path dciodvfy = pneuma::test::find_program({"dciodvfy"}), dcmdump = pneuma::test::find_program({"dcmdump"});
  ASSERT_FALSE(dciodvfy.empty()) << "dciodvfy (dicom3tools) not found";
  ASSERT_FALSE(dcmdump.empty()) << "dcmdump (dcmtk) not found";
  std::size_t errors = 0;
  for (const fs::path& file : files) {
    const auto check = run_program(dciodvfy, {file.string()});
    const std::string text = check.out + check.err;
    if (text.find("Error") != std::string::npos && errors++ < 3) ADD_FAILURE() << file << ":\n" << text;
    EXPECT_EQ(run_program(dcmdump, {file.string()}).exit_code, 0) << file;
  }
  EXPECT_EQ(errors, 0u);
}

}  // namespace

TEST(DicomOutputs, EveryPhaseReadsBackInPlastimatchAndPydicomInTheInputsStudy) {
  if (!fs::exists(pneuma::test::ct_lobes_dir() / "case004_lobes.nii.gz")) GTEST_SKIP() << "no ../shared/data/ct-lobes";
  const fs::path plastimatch = pneuma::test::find_program({"plastimatch"});
  PNEUMA_REQUIRE_CLIENT(plastimatch, "plastimatch");
  TempDir dir;
  make_ct(dir);
  const auto scenario = dir.write("s.yaml", scenario_text("ct/"));
  const auto r = pneuma::test::run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::vector<fs::path> files = dicom_files(dir / "out");
  ASSERT_GT(files.size(), 4u);
  expect_valid_dicom(files);
  // The input's study and frame of reference, as pneuma's reader found them (checked against
  // pydicom's writer in dicom_read_test).
  const auto input = pneuma::image::read_scalar_image(dir / "ct");
  ASSERT_TRUE(input.dicom.has_value());
  const auto check = run_program("/usr/bin/python3",
                                 {(pneuma::test::source_dir() / "tests/dicom/check_dicom_outputs.py").string(),
                                  (dir / "out").string(), (dir / "work").string(), kStructures, "--study",
                                  input.dicom->study_instance_uid, "--frame", input.dicom->frame_of_reference_uid});
  EXPECT_EQ(check.exit_code, 0) << check.out << check.err;
  std::cout << check.out;

  // A phase's CT series and RTSTRUCT in one folder read back as a label map (the reader, checked
  // against pydicom's shapes in dicom_structures_test): each lobe's voxels are the warped label
  // map's (a lobe, smaller than its lung, takes the voxels both hold).
  fs::create_directories(dir / "phase");
  for (const auto& e : fs::directory_iterator(dir / "out/dicom/ct-bin_01")) fs::copy(e.path(), dir / "phase");
  fs::copy(dir / "out/dicom/rtstruct-bin_01.dcm", dir / "phase");
  const auto read = pneuma::image::read_label_map(dir / "phase");
  const auto warped = pneuma::image::read_label_map(dir / "out/voxels/labels-bin_01.nii.gz");
  ASSERT_EQ(read.voxel_count(), warped.voxel_count());
  const Eigen::Matrix4d to_warped = warped.ijk_to_lps.inverse() * read.ijk_to_lps;
  std::size_t differ = 0;
  for (std::size_t k = 0; k < read.size[2]; ++k) {
    for (std::size_t j = 0; j < read.size[1]; ++j) {
      for (std::size_t i = 0; i < read.size[0]; ++i) {
        const Eigen::Vector3d x =
            (to_warped * Eigen::Vector4d(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k), 1.0))
                .head<3>()
                .array()
                .round();
        const auto w = warped.labels[static_cast<std::size_t>(x[0]) +
                                     warped.size[0] * (static_cast<std::size_t>(x[1]) +
                                                       warped.size[1] * static_cast<std::size_t>(x[2]))];
        const auto label = read.labels[i + read.size[0] * (j + read.size[1] * k)];
        const std::string name = label == 0 ? "" : read.segments[static_cast<std::size_t>(label - 1)].name;
        differ += name != (w == 0 ? std::string() : "label_" + std::to_string(w));
      }
    }
  }
  EXPECT_EQ(differ, 0u);
  // ... and as a run's label source, its lobes picked by ROI name: the warped lungs keep the
  // physiology's volume (voxels.csv's error, counted by the run against the rest label map).
  const auto from_rtstruct = dir.write("from-rtstruct.yaml", R"(name: from-rtstruct
duration: 4 s
frames: {rate: 5 Hz}
mesh:
  labels: phase/
  lungs: {right: [label_3, label_4, label_5], left: [label_1, label_2]}
  edge: 8 mm
field:
  tissue: healthy-supine
  interior: {edge: 8 mm, mesher: lattice, unfold: 1 L}
physiology: {preset: healthy-adult}
outputs: {gltf: false, hdf5: false, report: false, voxels: {at: [end_inspiration], spacing: 6 mm}}
)");
  const auto labelled =
      pneuma::test::run_pneuma({"run", from_rtstruct.string(), "-o", (dir / "labelled").string(), "--quiet"});
  ASSERT_EQ(labelled.exit_code, 0) << labelled.err;
  const std::string csv = pneuma::test::read_text(dir / "labelled/voxels/voxels.csv");
  const std::string row = csv.substr(csv.find('\n') + 1);
  std::vector<std::string> cells;
  for (std::size_t at = 0, next = 0; next != std::string::npos; at = next + 1) {
    next = row.find(',', at);
    cells.push_back(row.substr(at, next == std::string::npos ? std::string::npos : next - at));
  }
  ASSERT_GE(cells.size(), 8u) << csv;
  EXPECT_LT(std::abs(std::stod(cells[7])), 5.0) << csv;  // volume_error_percent

  // The same run at one thread: the same DICOM bytes (UIDs included).
  const auto again =
      pneuma::test::run_pneuma({"--threads", "1", "run", scenario.string(), "-o", (dir / "again").string(), "--quiet"});
  ASSERT_EQ(again.exit_code, 0) << again.err;
  const std::vector<fs::path> second = dicom_files(dir / "again");
  ASSERT_EQ(second.size(), files.size());
  for (std::size_t f = 0; f < files.size(); ++f) {
    EXPECT_EQ(fs::relative(files[f], dir / "out"), fs::relative(second[f], dir / "again"));
    EXPECT_TRUE(pneuma::test::read_text(files[f]) == pneuma::test::read_text(second[f])) << files[f];
  }
}

TEST(DicomOutputs, ANiftiCtGetsOneStudyMadeForTheRun) {
  if (!fs::exists(pneuma::test::ct_lobes_dir() / "case004_lobes.nii.gz")) GTEST_SKIP() << "no ../shared/data/ct-lobes";
  const fs::path plastimatch = pneuma::test::find_program({"plastimatch"});
  PNEUMA_REQUIRE_CLIENT(plastimatch, "plastimatch");
  TempDir dir;
  make_ct(dir);
  const auto scenario = dir.write("s.yaml", scenario_text("ct.nii.gz"));
  const auto r = pneuma::test::run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::vector<fs::path> files = dicom_files(dir / "out");
  expect_valid_dicom(files);
  const auto check =
      run_program("/usr/bin/python3", {(pneuma::test::source_dir() / "tests/dicom/check_dicom_outputs.py").string(),
                                       (dir / "out").string(), (dir / "work").string(), kStructures});
  EXPECT_EQ(check.exit_code, 0) << check.out << check.err;
  // A made study: its UIDs under 2.25 (UUID-derived), not the input's.
  EXPECT_NE(check.out.find("study {'2.25."), std::string::npos) << check.out;
  EXPECT_NE(check.out.find("frame of reference {'2.25."), std::string::npos) << check.out;
}

TEST(DicomOutputs, DicomWithoutACtIsRefusedWithOneLine) {
  TempDir dir;
  const auto scenario = dir.write("s.yaml", R"(name: dicom
duration: 2 s
mesh: {phantom: right, edge: 8 mm}
physiology: {preset: healthy-adult}
outputs: {voxels: {dicom: true}}
)");
  const auto r = pneuma::test::run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("outputs.voxels.dicom: expected `image`"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out"));
}
