// DICOM CT series in (image::read_scalar_image on a folder; docs/formats.md, "DICOM"). Oracle: a
// series written here by an independent writer (pydicom, tests/dicom/make_ct_series.py) from a
// shared case, with the same voxels written by nibabel as NIfTI: every voxel of the series lands
// on the NIfTI voxel of the same value, and the lungs' surfaces made from either agree, in both
// slice orders and with a tilted orientation. Each bad series is refused with one line naming
// the file and the tag, and a run given one exits 3 without writing anything.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/image/scalar_image.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"
#include "pneuma/mesh/labels/labels.h"
#include "test_support.h"

namespace fs = std::filesystem;
using pneuma::test::TempDir;

namespace {

// Writes the series (folder `name`) and its NIfTI (`name`.nii.gz) from case004, subsampled by 6.
void make_series(const TempDir& dir, const std::string& name, const std::vector<std::string>& extra,
                 const char* step = "6") {
  std::vector<std::string> args = {(pneuma::test::source_dir() / "tests/dicom/make_ct_series.py").string(),
                                   (pneuma::test::ct_lobes_dir() / "case004_lobes.nii.gz").string(),
                                   (dir / name).string(),
                                   (dir / (name + ".nii.gz")).string(),
                                   "--step",
                                   step};
  args.insert(args.end(), extra.begin(), extra.end());
  const auto r = pneuma::test::run_program("/usr/bin/python3", args);
  ASSERT_EQ(r.exit_code, 0) << r.err;
}

bool have_case() { return fs::exists(pneuma::test::ct_lobes_dir() / "case004_lobes.nii.gz"); }

// The lungs (every voxel above air) of a CT as a label map, and their surface.
pneuma::mesh::LabelSurface lung_surface(const pneuma::image::ScalarImage& ct, const std::string& name) {
  pneuma::image::LabelMap map;
  map.size = ct.size;
  map.ijk_to_lps = ct.ijk_to_lps;
  map.transform_source = ct.transform_source;
  map.labels.reserve(ct.values.size());
  for (const float hu : ct.values) map.labels.push_back(hu > -900.0f ? 1 : 0);
  pneuma::mesh::LabelSurfaceOptions options;
  options.edge_length_m = 4e-3;
  return pneuma::mesh::surface_from_labels(map, name, {1}, options);
}

struct Case {
  const char* name;
  std::vector<std::string> options;
};

}  // namespace

class DicomSeries : public ::testing::TestWithParam<Case> {};

TEST_P(DicomSeries, ReadsAsItsNiftiVoxelForVoxelAndGivesTheSameLungs) {
  if (!have_case()) GTEST_SKIP() << "no ../shared/data/ct-lobes";
  TempDir dir;
  make_series(dir, "ct", GetParam().options, "4");
  const auto dicom = pneuma::image::read_scalar_image(dir / "ct");
  const auto nifti = pneuma::image::read_scalar_image(dir / "ct.nii.gz");
  ASSERT_EQ(dicom.voxel_count(), nifti.voxel_count());
  ASSERT_TRUE(dicom.dicom.has_value());
  EXPECT_EQ(dicom.dicom->patient_id, "case004");
  EXPECT_FALSE(dicom.dicom->frame_of_reference_uid.empty());
  EXPECT_FALSE(dicom.dicom->study_instance_uid.empty());
  // Each DICOM voxel centre is a NIfTI voxel centre (to 1e-3 voxel) holding the same HU.
  const Eigen::Matrix4d to_nifti = nifti.ijk_to_lps.inverse() * dicom.ijk_to_lps;
  std::size_t off_grid = 0, differ = 0;
  for (std::size_t k = 0; k < dicom.size[2]; ++k) {
    for (std::size_t j = 0; j < dicom.size[1]; ++j) {
      for (std::size_t i = 0; i < dicom.size[0]; ++i) {
        const Eigen::Vector4d n =
            to_nifti * Eigen::Vector4d(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k), 1.0);
        const Eigen::Vector3d r = n.head<3>().array().round();
        if ((n.head<3>() - r).cwiseAbs().maxCoeff() > 1e-3 || (r.array() < 0.0).any() ||
            r[0] >= static_cast<double>(nifti.size[0]) || r[1] >= static_cast<double>(nifti.size[1]) ||
            r[2] >= static_cast<double>(nifti.size[2])) {
          ++off_grid;
          continue;
        }
        const auto at =
            static_cast<std::size_t>(r[0]) +
            nifti.size[0] * (static_cast<std::size_t>(r[1]) + nifti.size[1] * static_cast<std::size_t>(r[2]));
        differ += dicom.values[i + dicom.size[0] * (j + dicom.size[1] * k)] != nifti.values[at];
      }
    }
  }
  EXPECT_EQ(off_grid, 0u) << dicom.ijk_to_lps << "\n" << nifti.ijk_to_lps;
  EXPECT_EQ(differ, 0u);

  // The lungs' surfaces: volume within 0.5 %, bounding box within half a voxel.
  const auto a = lung_surface(dicom, "dicom"), b = lung_surface(nifti, "nifti");
  const double va = pneuma::mesh::enclosed_volume(a.mesh), vb = pneuma::mesh::enclosed_volume(b.mesh);
  EXPECT_NEAR(va / vb, 1.0, 0.005);
  // The boxes in the NIfTI's voxel frame: within half a voxel along each of its axes (the mesher
  // meets a slice-reversed grid half a slice apart at the apex and base at most).
  const Eigen::Matrix4d to_index = nifti.ijk_to_lps.inverse();
  const auto box = [&](const pneuma::mesh::TriangleMesh& m) {
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
    for (const auto& v : m.vertices) {
      const Eigen::Vector3d x = (to_index * v.homogeneous()).head<3>();
      lo = lo.cwiseMin(x);
      hi = hi.cwiseMax(x);
    }
    return std::pair{lo, hi};
  };
  const auto [alo, ahi] = box(a.mesh);
  const auto [blo, bhi] = box(b.mesh);
  EXPECT_LE((alo - blo).cwiseAbs().maxCoeff(), 0.5 + 1e-3) << alo.transpose() << " vs " << blo.transpose();
  EXPECT_LE((ahi - bhi).cwiseAbs().maxCoeff(), 0.5 + 1e-3) << ahi.transpose() << " vs " << bhi.transpose();
  std::cout << GetParam().name << ": lungs " << va * 1e6 << " mL from DICOM, " << vb * 1e6 << " mL from NIfTI\n";
}

INSTANTIATE_TEST_SUITE_P(Orders, DicomSeries,
                         ::testing::Values(Case{"ascending", {}}, Case{"descending", {"--descending"}},
                                           Case{"oblique", {"--oblique", "25"}},
                                           Case{"oblique_descending", {"--oblique", "25", "--descending"}}),
                         [](const auto& param_info) { return std::string(param_info.param.name); });

// Each bad series: one line naming the file and the tag.
struct BadCase {
  const char* damage;
  const char* file;  // the file the message names (empty: the folder)
  const char* says;
};

class BadDicomSeries : public ::testing::TestWithParam<BadCase> {};

TEST_P(BadDicomSeries, IsRefusedWithOneLineNamingTheFileAndTag) {
  if (!have_case()) GTEST_SKIP() << "no ../shared/data/ct-lobes";
  TempDir dir;
  make_series(dir, "ct", {"--damage", GetParam().damage});
  try {
    pneuma::image::read_scalar_image(dir / "ct");
    FAIL() << "a series with " << GetParam().damage << " was read";
  } catch (const pneuma::InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    const std::string file = (dir / "ct").string() + (*GetParam().file ? "/" : ":") + GetParam().file;
    EXPECT_NE(what.find(file), std::string::npos) << what;
    EXPECT_NE(what.find(GetParam().says), std::string::npos) << what;
  }
}

// The middle slice is slice0022 (case004 subsampled by 6: 45 slices, numbered from the top down,
// inferior last: sorted along the slice normal, which points down, slice0021 follows slice0023).
INSTANTIATE_TEST_SUITE_P(
    Damages, BadDicomSeries,
    ::testing::Values(
        BadCase{
            "missing_slice", "slice0021.dcm",
            "(0020,0032) ImagePositionPatient: 12 mm from slice0023.dcm where the series steps 6 mm: a missing slice"},
        BadCase{"mixed_series", "", "(0020,000E) SeriesInstanceUID: 2 series"},
        BadCase{"not_ct", "slice0022.dcm", "(0008,0060) Modality: 'MR': expected a CT series"},
        BadCase{"truncated", "slice0022.dcm", "(7FE0,0010) PixelData: truncated"},
        BadCase{"no_pixels", "slice0022.dcm", "(7FE0,0010) PixelData: missing"},
        BadCase{"gantry_tilt", "slice0001.dcm", "(0018,1120) GantryDetectorTilt: 15 degrees"},
        BadCase{"uneven", "slice0022.dcm", "expected evenly spaced slices"}),
    [](const auto& param_info) { return std::string(param_info.param.damage); });

// Through a run: exit 3, the one line, and no output folder.
TEST(DicomSeriesRun, ABadSeriesStopsTheRunBeforeAnythingIsWritten) {
  if (!have_case()) GTEST_SKIP() << "no ../shared/data/ct-lobes";
  TempDir dir;
  make_series(dir, "ct", {"--damage", "not_ct"});
  const auto scenario = dir.write("s.yaml", R"(name: dicom
duration: 2 s
frames: {rate: 5 Hz}
mesh: {phantom: right, edge: 8 mm}
field: {tissue: healthy-upright, interior: {edge: 8 mm}}
physiology: {preset: healthy-adult}
outputs: {gltf: false, hdf5: false, report: false, voxels: {at: [end_inspiration], spacing: 4 mm, image: ct/}}
)");
  const auto r = pneuma::test::run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("(0008,0060) Modality"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("voxels.image"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out"));
}
