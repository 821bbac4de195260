// The files, read back by independent clients: nibabel (the DVF's shape, intent, affine and
// millimetres), pneuma's own label-map reader, and plastimatch warping with pneuma's pull-back
// DVF (Dice against pneuma's warp).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "pneuma/core/error.h"
#include "pneuma/voxels/time_point.h"
#include "pneuma/voxels/voxel_io.h"
#include "test_support.h"
#include "tet_fixtures.h"

namespace pneuma::voxels {
namespace {
namespace fs = std::filesystem;
using pneuma::test::CommandResult;
using pneuma::test::run_program;
using pneuma::test::TempDir;

const fs::path kPython = "/usr/bin/python3";

bool have_nibabel() {
  return fs::exists(kPython) && run_program(kPython, {"-c", "import nibabel, numpy"}).exit_code == 0;
}

// The ball dilated and shifted (the shift tells LPS from RAS: a flipped x or y moves it wrongly).
struct Moved {
  test::Ball ball = test::make_ball();
  std::vector<Eigen::Vector3d> u = ball.radial(0.15, Eigen::Vector3d(2.5e-3, -1.5e-3, 3e-3));
  std::vector<LungMotion> lungs() const { return {LungMotion{ball.mesh, u, 1.0}}; }
};

// nibabel's view of a NIfTI file: shape, intent code, affine (row by row), then the data as
// float64 in pneuma's order (component fastest, then i, j, k) written to `raw`.
CommandResult nibabel_dump(const fs::path& file, const fs::path& raw) {
  const std::string script = "import sys, nibabel, numpy as np\n"
                             "img = nibabel.load(sys.argv[1])\n"
                             "h = img.header\n"
                             "print(' '.join(str(d) for d in img.shape))\n"
                             "print(int(h['intent_code']), int(h['qform_code']), int(h['sform_code']))\n"
                             "print(' '.join(repr(float(x)) for x in img.affine.flatten()))\n"
                             "d = np.asarray(img.dataobj, dtype=np.float64)\n"
                             "n = d.shape[:3]\n"
                             "d = d.reshape(n + (-1,))\n"
                             "np.transpose(d, (2, 1, 0, 3)).astype('<f8').tofile(sys.argv[2])\n";
  return run_program(kPython, {"-c", script, file.string(), raw.string()});
}

std::vector<double> read_raw(const fs::path& raw) {
  std::ifstream in(raw, std::ios::binary);
  std::vector<double> out(fs::file_size(raw) / 8);
  in.read(reinterpret_cast<char*>(out.data()), static_cast<std::streamsize>(out.size() * 8));
  return out;
}

void expect_affine(std::istringstream& lines, const Grid& grid) {
  std::string line;
  std::getline(lines, line);
  std::istringstream a(line);
  Eigen::Matrix4d affine;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) a >> affine(r, c);
  Eigen::Matrix4d expected = grid.ijk_to_lps;
  expected.topRows(3) *= 1e3;  // mm
  expected.row(0) *= -1.0;     // LPS -> RAS
  expected.row(1) *= -1.0;
  EXPECT_LE((affine - expected).cwiseAbs().maxCoeff(), 1e-4) << "nibabel's affine\n"
                                                             << affine << "\nexpected\n"
                                                             << expected;
}

TEST(VoxelFiles, NibabelReadsTheDvfAsAVectorImageInLpsMillimetres) {
  if (!have_nibabel()) GTEST_SKIP() << "nibabel is not importable by /usr/bin/python3 (install-deps: python3-nibabel)";
  const Moved m;
  const DisplacementField pull = pullback_dvf(m.ball.grid, m.lungs());
  const TempDir dir;
  write_dvf(dir / "pull.nii.gz", pull);
  EXPECT_EQ(dir.files(), std::vector<std::string>{"pull.nii.gz"});  // no temporary left
  write_dvf(dir / "again.nii.gz", pullback_dvf(m.ball.grid, m.lungs()));
  EXPECT_EQ(pneuma::test::read_text(dir / "again.nii.gz"), pneuma::test::read_text(dir / "pull.nii.gz"));  // same bytes
  const CommandResult r = nibabel_dump(dir / "pull.nii.gz", dir / "raw");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::printf("nibabel: %s", r.out.c_str());  // shape; intent, qform and sform codes; affine
  std::istringstream lines(r.out);
  std::string line;
  std::getline(lines, line);
  EXPECT_TRUE(line == "64 64 64 1 3" || line == "64 64 64 3") << line;
  std::getline(lines, line);
  int intent = 0, qform = 0, sform = 0;
  std::istringstream(line) >> intent >> qform >> sform;
  EXPECT_EQ(intent, 1007);  // NIFTI_INTENT_VECTOR
  EXPECT_GT(qform + sform, 0);
  expect_affine(lines, pull.grid);
  const std::vector<double> mm = read_raw(dir / "raw");
  ASSERT_EQ(mm.size(), 3 * pull.displacement_m.size());
  double worst = 0.0;
  for (std::size_t v = 0; v < pull.displacement_m.size(); ++v)
    for (std::size_t c = 0; c < 3; ++c)
      worst = std::max(worst, std::abs(mm[3 * v + c] - pull.displacement_m[v][static_cast<Eigen::Index>(c)] * 1e3));
  EXPECT_LE(worst, 1e-5);  // float32 of a few mm
}

// The NIfTI standard's DVF (DvfConvention::nifti): intent 1006 (NIFTI_INTENT_DISPVECT), the
// components in RAS (x and y negated), the same geometry; each file's descrip says which it is, and
// the patched, gzipped file is the same bytes each time.
TEST(VoxelFiles, NibabelReadsTheNiftiStandardsDvfInRasWithItsDescription) {
  if (!have_nibabel()) GTEST_SKIP() << "nibabel is not importable by /usr/bin/python3 (install-deps: python3-nibabel)";
  const Moved m;
  const DisplacementField forward = forward_dvf(m.ball.grid, m.lungs());
  const TempDir dir;
  for (const std::string name : {"ras.nii.gz", "ras.nii"})
    write_dvf(dir / name, forward, DvfDirection::forward, DvfConvention::nifti);
  write_dvf(dir / "again.nii.gz", forward, DvfDirection::forward, DvfConvention::nifti);
  EXPECT_EQ(pneuma::test::read_text(dir / "again.nii.gz"), pneuma::test::read_text(dir / "ras.nii.gz"));
  std::vector<std::string> files = dir.files();
  std::sort(files.begin(), files.end());
  EXPECT_EQ(files, (std::vector<std::string>{"again.nii.gz", "ras.nii", "ras.nii.gz"}));  // no temporary left
  for (const std::string name : {"ras.nii.gz", "ras.nii"}) {
    const CommandResult r = nibabel_dump(dir / name, dir / "raw");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    std::istringstream lines(r.out);
    std::string line;
    std::getline(lines, line);
    std::getline(lines, line);
    EXPECT_EQ(line.substr(0, 5), "1006 ") << line;  // NIFTI_INTENT_DISPVECT
    expect_affine(lines, forward.grid);
    const std::vector<double> mm = read_raw(dir / "raw");
    ASSERT_EQ(mm.size(), 3 * forward.displacement_m.size());
    double worst = 0.0;
    for (std::size_t v = 0; v < forward.displacement_m.size(); ++v)
      for (std::size_t c = 0; c < 3; ++c) {
        const double ras = (c < 2 ? -1e3 : 1e3) * forward.displacement_m[v][static_cast<Eigen::Index>(c)];
        worst = std::max(worst, std::abs(mm[3 * v + c] - ras));
      }
    EXPECT_LE(worst, 1e-5) << name;
  }
  const std::string script =
      "import sys, nibabel\n"
      "for f in sys.argv[1:]: print(nibabel.load(f).header['descrip'].tobytes().rstrip(b'\\0').decode())";
  write_dvf(dir / "lps.nii.gz", forward, DvfDirection::forward);
  write_dvf(dir / "pull.nii", pullback_dvf(m.ball.grid, m.lungs()));
  const CommandResult r = run_program(kPython, {"-c", script, (dir / "ras.nii.gz").string(),
                                                (dir / "lps.nii.gz").string(), (dir / "pull.nii").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "pneuma forward DVF x->x+u(x), RAS mm, NIfTI DISPVECT, jumps at pleura\n"
                   "pneuma forward DVF x->x+u(x), LPS mm, ITK<=5.2 layout, jumps at pleura\n"
                   "pneuma pull-back DVF out(x)=in(x+v), LPS mm, ITK<=5.2 layout, jumps at pleura\n");
  // Only NIfTI has the two conventions.
  EXPECT_THROW(write_dvf(dir / "ras.mha", forward, DvfDirection::forward, DvfConvention::nifti), ValueError);
  EXPECT_THROW(write_dvf(dir / "ras.nrrd", forward, DvfDirection::forward, DvfConvention::nifti), ValueError);
}

TEST(VoxelFiles, LabelMapAndCtReadBackOnTheSameGeometry) {
  const Moved m;
  TimePointInputs inputs;
  inputs.labels = &m.ball.labels;
  Image ct;
  ct.grid = m.ball.grid;
  ct.values.resize(ct.grid.voxel_count());
  for (std::size_t v = 0; v < ct.values.size(); ++v) ct.values[v] = static_cast<float>(v % 1000) - 500.0f;
  inputs.ct = &ct;
  const TimePoint point = compute_time_point(m.ball.grid, m.lungs(), inputs);
  const TempDir dir;
  for (const std::string extension : {".nii.gz", ".mha", ".nrrd"}) {
    const TimePointFiles files = write_time_point(dir.path(), "0.500s", point, extension);
    EXPECT_EQ(files.forward.filename().string(), "dvf-forward-0.500s" + extension);
    EXPECT_EQ(files.pullback.filename().string(), "dvf-pullback-0.500s" + extension);
    const image::LabelMap labels = image::read_label_map(files.labels);
    EXPECT_EQ(labels.size, point.labels->size);
    EXPECT_EQ(labels.labels, point.labels->labels);
    EXPECT_LE((labels.ijk_to_lps - point.labels->ijk_to_lps).cwiseAbs().maxCoeff(), 1e-9);
    const Image back = read_image(files.ct);
    EXPECT_EQ(back.grid.size, point.ct->grid.size);
    EXPECT_EQ(back.values, point.ct->values);
    EXPECT_LE((back.grid.ijk_to_lps - point.ct->grid.ijk_to_lps).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_EQ(files.jacobian.filename().string(), "jacobian-0.500s" + extension);
    EXPECT_EQ(read_image(files.jacobian).values, point.jacobian_map->values);
  }
  EXPECT_EQ(dir.files().size(), 15u);  // per format: two DVFs, the labels, the CT, the Jacobian
  // Into the buffers of another time point: the same values.
  TimePoint reused = compute_time_point(m.ball.grid, std::vector<LungMotion>{LungMotion{m.ball.mesh, m.u, 0.3}});
  compute_time_point(m.ball.grid, m.lungs(), inputs, reused);
  EXPECT_EQ(reused.pullback.displacement_m, point.pullback.displacement_m);
  EXPECT_EQ(reused.forward.lung, point.forward.lung);
  EXPECT_EQ(reused.labels->labels, point.labels->labels);
  EXPECT_EQ(reused.ct->values, point.ct->values);
  EXPECT_EQ(reused.jacobian_map->values, point.jacobian_map->values);
}

TEST(VoxelFiles, NotAnImageIsOneLineNamingTheFile) {
  const TempDir dir;
  const fs::path bad = dir.write("ct.nii.gz", "this is not an image\n");
  try {
    read_image(bad);
    FAIL() << "no error";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(bad.string() + ": ", 0), 0u) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
  EXPECT_THROW(read_image(dir.write("ct.txt", "x")), InputError);
  // A CT cut short: refused before ITK reads it (ITK 5.2 would fill the rest with anything).
  Image ct;
  ct.grid.size = {40, 30, 20};
  ct.values.assign(ct.grid.voxel_count(), 1.5f);
  write_image(dir / "whole.nii", ct);
  const std::string bytes = pneuma::test::read_text(dir / "whole.nii");
  const fs::path cut = dir.write("cut.nii", bytes.substr(0, bytes.size() / 2));
  try {
    read_image(cut);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              cut.string() + ": truncated or corrupt: expected 40 x 30 x 20 voxels of FLOAT32 (96000 bytes of data)");
  }
  EXPECT_EQ(read_image(dir / "whole.nii").values, ct.values);
  EXPECT_THROW(read_image(dir / "missing.nii.gz"), IoError);
  EXPECT_THROW(write_dvf(dir / "dvf.vtk", DisplacementField{}), ValueError);
}

// docs/formats.md's nibabel/scipy example, word for word: it must warp a CT as pneuma does.
const char* const kDocsScipyExample = R"(import nibabel as nib, numpy as np, scipy.ndimage as ndi
from nibabel.affines import apply_affine
ct, v = nib.load("ct.nii.gz"), nib.load("dvf-pullback-1.500s.nii.gz")
y = apply_affine(v.affine, np.moveaxis(np.indices(v.shape[:3]), 0, -1)) + v.get_fdata().reshape(v.shape[:3] + (3,)) * [-1, -1, 1]
ijk = np.moveaxis(apply_affine(np.linalg.inv(ct.affine), y), -1, 0)
nib.save(nib.Nifti1Image(ndi.map_coordinates(ct.get_fdata(), ijk, order=1, cval=-1024).astype("float32"), v.affine), "ct-1.500s.nii.gz")
)";

TEST(VoxelFiles, TheDocsScipyExampleWarpsTheCtAsPneumaDoes) {
  if (!have_nibabel() || run_program(kPython, {"-c", "import scipy.ndimage"}).exit_code != 0) {
    GTEST_SKIP()
        << "nibabel or scipy is not importable by /usr/bin/python3 (install-deps: python3-nibabel python3-scipy)";
  }
  const Moved m;
  Image ct;
  ct.grid = m.ball.grid;
  ct.values.resize(ct.grid.voxel_count());
  for (std::size_t v = 0; v < ct.values.size(); ++v) {
    const Eigen::Vector3d x = ct.grid.centre_m(v % 64, (v / 64) % 64, v / 4096) - m.ball.centre_m;
    ct.values[v] = static_cast<float>(40.0 + 2e4 * x.x() - 1e4 * x.y() + 3e4 * x.z() + 1e6 * x.squaredNorm());
  }
  const DisplacementField pull = pullback_dvf(m.ball.grid, m.lungs());
  const Image ours = warp_image(ct, pull);
  const TempDir dir;
  write_image(dir / "ct.nii.gz", ct);
  write_dvf(dir / "dvf-pullback-1.500s.nii.gz", pull);
  const CommandResult r = run_program(kPython, {"-c", kDocsScipyExample}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Image theirs = read_image(dir / "ct-1.500s.nii.gz");
  ASSERT_EQ(theirs.values.size(), ours.values.size());
  double worst_hu = 0.0;
  for (std::size_t v = 0; v < ours.values.size(); ++v) {
    worst_hu = std::max(worst_hu, static_cast<double>(std::abs(ours.values[v] - theirs.values[v])));
  }
  EXPECT_LE(worst_hu, 0.05);  // float32 displacements (in the file) against pneuma's doubles
}

double dice(const image::LabelMap& a, const image::LabelMap& b, std::int32_t label) {
  std::size_t na = 0, nb = 0, both = 0;
  for (std::size_t v = 0; v < a.labels.size(); ++v) {
    na += a.labels[v] == label;
    nb += b.labels[v] == label;
    both += a.labels[v] == label && b.labels[v] == label;
  }
  return 2.0 * static_cast<double>(both) / static_cast<double>(na + nb);
}

// plastimatch reads the NIfTI vector components as LPS millimetres and warps out(x) = in(x + v(x)).
TEST(VoxelFiles, PlastimatchWarpsLikePneuma) {
  const fs::path plastimatch = "/usr/bin/plastimatch";
  if (!fs::exists(plastimatch)) GTEST_SKIP() << "plastimatch is not installed (install-deps: plastimatch)";
  const Moved m;
  const DisplacementField pull = pullback_dvf(m.ball.grid, m.lungs());
  const image::LabelMap ours = warp_labels(m.ball.labels, pull);
  const TempDir dir;
  write_label_map(dir / "labels.nii.gz", m.ball.labels);
  write_dvf(dir / "pull.nii.gz", pull);
  const CommandResult r = run_program(
      plastimatch, {"warp", "--input", (dir / "labels.nii.gz").string(), "--output-img", (dir / "out.nii.gz").string(),
                    "--xf", (dir / "pull.nii.gz").string(), "--interpolation", "nn"});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const image::LabelMap theirs = image::read_label_map(dir / "out.nii.gz");
  ASSERT_EQ(theirs.size, ours.size);
  EXPECT_LE((theirs.ijk_to_lps - ours.ijk_to_lps).cwiseAbs().maxCoeff(), 1e-9);
  for (const std::int32_t label : {1, 2, 7}) {
    const double d = dice(ours, theirs, label);
    std::printf("plastimatch Dice, label %d: %.5f\n", label, d);
    EXPECT_GE(d, 0.99) << "label " << label;
  }
}

}  // namespace
}  // namespace pneuma::voxels
