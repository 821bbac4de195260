// RTSTRUCT contours (voxels::write_rt_struct) on a small hand-made label map with the cases a
// tracer gets wrong: a ring (a hole, joined to its outline by a keyhole), two pixels touching only at a corner, a
// lone pixel, an empty slice; on a grid turned about an oblique axis. Oracle: plastimatch
// rasterises the RTSTRUCT onto the CT series written beside it, and every voxel of each mask is
// the label map's, exactly; plastimatch's CT holds the written HU at the same voxel centres.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cmath>
#include <filesystem>
#include <string>

#include "pneuma/image/label_map.h"
#include "pneuma/image/scalar_image.h"
#include "pneuma/voxels/dicom_io.h"
#include "test_support.h"

namespace fs = std::filesystem;
using pneuma::test::TempDir;

namespace {

// Voxel values of `read` at the voxel centres of `grid` (which must be the same centres, in any
// axis order): -999999 where a centre is not one of read's.
template <typename Value>
std::vector<double> on_grid(const pneuma::voxels::Grid& grid, const Eigen::Matrix4d& read_ijk_to_lps,
                            const std::array<std::size_t, 3>& read_size, const std::vector<Value>& values) {
  const Eigen::Matrix4d to_read = read_ijk_to_lps.inverse() * grid.ijk_to_lps;
  std::vector<double> out;
  for (std::size_t k = 0; k < grid.size[2]; ++k) {
    for (std::size_t j = 0; j < grid.size[1]; ++j) {
      for (std::size_t i = 0; i < grid.size[0]; ++i) {
        const Eigen::Vector3d x =
            (to_read * Eigen::Vector4d(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k), 1.0))
                .head<3>();
        const Eigen::Vector3d r = x.array().round();
        bool ok = (x - r).cwiseAbs().maxCoeff() < 1e-3;
        for (int a = 0; a < 3; ++a)
          ok = ok && r[a] >= 0 && r[a] < static_cast<double>(read_size[static_cast<std::size_t>(a)]);
        if (!ok) {
          out.push_back(-999999.0);
          continue;
        }
        const auto ri = static_cast<std::size_t>(r[0]), rj = static_cast<std::size_t>(r[1]),
                   rk = static_cast<std::size_t>(r[2]);
        out.push_back(static_cast<double>(values[ri + read_size[0] * (rj + read_size[1] * rk)]));
      }
    }
  }
  return out;
}

}  // namespace

TEST(DicomContours, PlastimatchFillsEachContourBackToItsVoxelsExactly) {
  const fs::path plastimatch = pneuma::test::find_program({"plastimatch"});
  PNEUMA_REQUIRE_CLIENT(plastimatch, "plastimatch");
  TempDir dir;
  pneuma::voxels::Grid grid;
  grid.size = {12, 10, 4};
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  grid.ijk_to_lps.block<3, 3>(0, 0) = turn * Eigen::Vector3d(2e-3, 2.5e-3, 3e-3).asDiagonal();
  grid.ijk_to_lps.block<3, 1>(0, 3) = Eigen::Vector3d(-0.0123, 0.0456, -0.0789);
  pneuma::image::LabelMap map;
  map.size = grid.size;
  map.ijk_to_lps = grid.ijk_to_lps;
  map.labels.assign(grid.voxel_count(), 0);
  const auto set = [&](std::size_t i, std::size_t j, std::size_t k, int v) { map.labels[grid.index(i, j, k)] = v; };
  for (std::size_t j = 2; j < 8; ++j) {
    for (std::size_t i = 2; i < 8; ++i) {
      if (i < 4 || i > 5 || j < 4 || j > 5) set(i, j, 0, 1);  // a ring around a 2 x 2 hole
    }
  }
  set(9, 1, 0, 2);  // a lone pixel
  set(1, 1, 1, 2);  // two pixels touching at a corner
  set(2, 2, 1, 2);
  for (std::size_t i = 5; i < 11; ++i) set(i, 6, 1, 1);  // a bar
  // A block with two holes, one above the other (the upper one's keyhole ends on the lower one),
  // and an island in the upper hole; slice 3 stays empty.
  for (std::size_t j = 1; j <= 8; ++j) {
    for (std::size_t i = 1; i <= 9; ++i) {
      const bool upper_hole = i >= 3 && i <= 7 && j >= 4 && j <= 6 && !(i == 5 && j == 5);
      const bool lower_hole = i >= 3 && i <= 4 && j == 2;
      if (!upper_hole && !lower_hole) set(i, j, 2, 1);
    }
  }
  pneuma::voxels::Image ct;
  ct.grid = grid;
  for (const int v : map.labels) ct.values.push_back(-1000.0f + 300.0f * static_cast<float>(v) + 0.25f);

  pneuma::voxels::CtSeriesSpec spec;
  spec.study.patient_name = "Contour^Test";
  spec.study.patient_id = "contours";
  spec.study.study_instance_uid = "2.25.1";
  spec.study.frame_of_reference_uid = "2.25.2";
  spec.study.patient_position = "HFS";
  spec.series_instance_uid = "2.25.3";
  spec.sop_instance_uid_root = "2.25.3";
  spec.series_description = "CT 0%";
  const auto series = pneuma::voxels::write_ct_series(dir / "ct", ct, spec);
  ASSERT_EQ(series.files.size(), 4u);
  pneuma::voxels::RtStructSpec rt;
  rt.study = spec.study;
  rt.series_instance_uid = "2.25.4";
  rt.sop_instance_uid = "2.25.4.1";
  rt.label = "contours";
  const std::size_t contours = pneuma::voxels::write_rt_struct(
      dir / "rtstruct.dcm", map, grid, series, {{"ring_and_bar", {1}, {255, 0, 0}}, {"dots", {2}, {0, 255, 0}}}, rt);
  // Slice 0: the ring with its hole (one keyhole polygon), the lone pixel; slice 1: the bar and
  // the two corner pixels apart; slice 2: the block with both holes, the island.
  EXPECT_EQ(contours, 7u);

  auto r = pneuma::test::run_program(
      plastimatch, {"convert", "--input", (dir / "ct").string(), "--output-img", (dir / "ct.nii.gz").string()});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  r = pneuma::test::run_program(
      plastimatch, {"convert", "--input", (dir / "rtstruct.dcm").string(), "--referenced-ct", (dir / "ct").string(),
                    "--output-prefix", (dir / "ss").string(), "--prefix-format", "nii.gz"});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const auto back = pneuma::image::read_scalar_image(dir / "ct.nii.gz");
  const std::vector<double> hu = on_grid(grid, back.ijk_to_lps, back.size, back.values);
  for (std::size_t v = 0; v < hu.size(); ++v) {
    EXPECT_EQ(hu[v], std::round(ct.values[v])) << "voxel " << v;
  }
  for (const auto& [name, label] : {std::pair{"ring_and_bar", 1}, std::pair{"dots", 2}}) {
    const auto mask = pneuma::image::read_label_map(dir / "ss" / (std::string(name) + ".nii.gz"));
    const std::vector<double> in = on_grid(grid, mask.ijk_to_lps, mask.size, mask.labels);
    std::size_t wrong = 0;
    for (std::size_t v = 0; v < in.size(); ++v) {
      if ((in[v] > 0) != (map.labels[v] == label) && wrong++ < 8)
        ADD_FAILURE() << name << ": voxel " << v << " " << in[v];
    }
    EXPECT_EQ(wrong, 0u) << name;
  }
}
