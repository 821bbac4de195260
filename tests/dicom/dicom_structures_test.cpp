// RT Structure Sets in (image::read_label_map on a folder holding a CT series and an RTSTRUCT;
// docs/formats.md, "DICOM"). Oracle: shapes drawn by pydicom (tests/dicom/make_rtstruct.py) on a
// series it wrote, whose voxels are counted here from the geometry alone: rectangles in the
// slices' frame hold exactly the voxel centres inside them, a hole drawn as a second contour is
// left out, a 128-gon of radius 30 mm covers pi r^2 within 2 %; ROI names become segments and
// resolve_labels picks them by name. A structure set in another frame of reference, or with
// contours between the CT's slices, is refused with one line naming the file and tag.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <numbers>
#include <string>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/image/label_map.h"
#include "test_support.h"

namespace fs = std::filesystem;
using pneuma::test::TempDir;

namespace {

bool have_case() { return fs::exists(pneuma::test::ct_lobes_dir() / "case004_lobes.nii.gz"); }

void make(const TempDir& dir, const std::vector<std::string>& options) {
  auto r = pneuma::test::run_program(
      "/usr/bin/python3", {(pneuma::test::source_dir() / "tests/dicom/make_ct_series.py").string(),
                           (pneuma::test::ct_lobes_dir() / "case004_lobes.nii.gz").string(), (dir / "ct").string(),
                           (dir / "ct.nii.gz").string(), "--step", "6", "--oblique", "20"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::vector<std::string> args = {(pneuma::test::source_dir() / "tests/dicom/make_rtstruct.py").string(),
                                   (dir / "ct").string()};
  args.insert(args.end(), options.begin(), options.end());
  r = pneuma::test::run_program("/usr/bin/python3", args);
  ASSERT_EQ(r.exit_code, 0) << r.err;
}

// Voxel centres u = i * dx with lo <= u - c < hi (c = the middle pixel's offset, in mm).
std::size_t centres_in(double lo, double hi, double spacing) {
  std::size_t n = 0;
  for (int i = -1000; i <= 1000; ++i)
    n += static_cast<double>(i) * spacing >= lo && static_cast<double>(i) * spacing < hi;
  return n;
}

}  // namespace

TEST(DicomStructures, ShapesDrawnByPydicomFillTheirVoxels) {
  if (!have_case()) GTEST_SKIP() << "no ../shared/data/ct-lobes";
  TempDir dir;
  make(dir, {});
  const auto map = pneuma::image::read_label_map(dir / "ct");
  ASSERT_EQ(map.segments.size(), 3u);
  EXPECT_EQ(map.segments[0].name, "square");
  EXPECT_EQ(map.segments[1].name, "frame");
  EXPECT_EQ(map.segments[2].name, "disc");
  const Eigen::Vector3d spacing = map.spacing_m() * 1e3;  // i along a row (column spacing), j down
  // The rectangles are in the slice frame about the middle pixel: offsets i - columns/2, j - rows/2.
  const std::size_t square = centres_in(-20.3, 20.9, spacing[0]) * centres_in(-18.1, 22.6, spacing[1]);
  const std::size_t hole = centres_in(-8.2, 9.1, spacing[0]) * centres_in(-7.7, 8.8, spacing[1]);
  std::array<std::size_t, 4> count{0, 0, 0, 0};
  for (const auto v : map.labels) ++count[static_cast<std::size_t>(v)];
  // "frame" (smaller than "square") takes its voxels on slices 10 and 11: the square less the hole.
  EXPECT_EQ(count[2], 2 * (square - hole));
  EXPECT_EQ(count[1], 4 * square - count[2]);
  const double disc_mm3 = static_cast<double>(count[3]) * spacing.prod();
  EXPECT_NEAR(disc_mm3 / (4 * std::numbers::pi * 30.0 * 30.0 * spacing[2]), 1.0, 0.02);
  std::cout << "disc: " << disc_mm3 / (4 * std::numbers::pi * 30.0 * 30.0 * spacing[2]) << " of pi r^2\n";
  EXPECT_EQ(pneuma::image::resolve_labels(map, "ct", {"disc", "frame"}), (std::vector<int>{3, 2}));
  // The folder is still a CT where a CT is read: the structure set is passed over.
  EXPECT_NO_THROW(pneuma::image::read_label_map(dir / "ct"));
}

TEST(DicomStructures, AnotherFrameOfReferenceOrAContourBetweenSlicesIsRefused) {
  if (!have_case()) GTEST_SKIP() << "no ../shared/data/ct-lobes";
  for (const auto& [option, says] : {std::pair{"--wrong-frame", "(0020,0052) FrameOfReferenceUID"},
                                     std::pair{"--between-slices", "ROI 'disc' contour 1 (3006,0050) ContourData"}}) {
    TempDir dir;
    make(dir, {option});
    try {
      pneuma::image::read_label_map(dir / "ct");
      ADD_FAILURE() << option << " was read";
    } catch (const pneuma::InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find((dir / "ct" / "rtstruct.dcm").string() + ": "), std::string::npos) << what;
      EXPECT_NE(what.find(says), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
}
