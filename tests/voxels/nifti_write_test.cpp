// NIfTI written from memory (voxels/src/nifti_write.h, #50). Oracles: ITK 5.2's own NIfTI writer
// (NiftiImageIO, what pneuma used before) writes the same image, and the two headers must agree
// field for field and the data byte for byte; Python's gzip module inflates each .nii.gz into the
// plain .nii's bytes; nibabel reads a field of more than one 64 MiB batch against the formula
// that made it (numpy's, not pneuma's).
// clang-format off
#include "itk_clang.h"  // first: Debian's ITK headers under clang
// clang-format on
#include <itkNiftiImageIO.h>

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstring>
#include <fstream>

#include "pneuma/core/error.h"
#include "pneuma/voxels/gzip.h"
#include "pneuma/voxels/voxel_io.h"
#include "pneuma/voxels/write_queue.h"
#include "test_support.h"
#include "tet_fixtures.h"

namespace pneuma::voxels {
namespace {
namespace fs = std::filesystem;
using pneuma::test::CommandResult;
using pneuma::test::run_program;
using pneuma::test::TempDir;

const fs::path kPython = "/usr/bin/python3";

// `buffer` (component fastest, as ITK's images hold it) written as .nii by ITK 5.2's NIfTI writer,
// on `grid` as pneuma maps a grid to ITK (origin, spacing and direction in LPS mm).
void itk_write_nii(const fs::path& path, const Grid& grid, itk::IOComponentEnum component, unsigned components,
                   const void* buffer) {
  auto io = itk::NiftiImageIO::New();
  io->SetNumberOfDimensions(3);
  itk::ImageIORegion region(3);
  const Eigen::Vector3d spacing_m = grid.spacing_m();
  for (unsigned a = 0; a < 3; ++a) {
    const auto ai = static_cast<Eigen::Index>(a);
    io->SetDimensions(a, static_cast<unsigned>(grid.size[a]));
    io->SetSpacing(a, spacing_m[ai] * 1e3);
    io->SetOrigin(a, grid.ijk_to_lps(ai, 3) * 1e3);
    std::vector<double> axis(3);
    for (unsigned r = 0; r < 3; ++r) axis[r] = grid.ijk_to_lps(static_cast<Eigen::Index>(r), ai) / spacing_m[ai];
    io->SetDirection(a, axis);
    region.SetIndex(a, 0);
    region.SetSize(a, grid.size[a]);
  }
  io->SetIORegion(region);
  io->SetPixelType(components == 1 ? itk::IOPixelEnum::SCALAR : itk::IOPixelEnum::VECTOR);
  io->SetComponentType(component);
  io->SetNumberOfComponents(components);
  io->SetUseCompression(false);
  io->SetFileName(path.string());
  io->WriteImageInformation();
  io->Write(buffer);
}

std::string bytes_of(const fs::path& path) { return pneuma::test::read_text(path); }

// The bytes where two NIfTI-1 files differ, as "offset" ranges; `descrip` (148-227) is left
// out when asked (ITK 5.2 writes none).
std::string differences(const std::string& a, const std::string& b, bool skip_descrip) {
  if (a.size() != b.size()) return "sizes " + std::to_string(a.size()) + " and " + std::to_string(b.size());
  std::string out;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (skip_descrip && i >= 148 && i < 228) continue;
    if (a[i] != b[i]) out += std::to_string(i) + " ";
    if (out.size() > 200) break;
  }
  return out;
}

// A grid that is neither axis-aligned nor isotropic (the qform's quaternion and the sform differ
// from the identity in every entry), its origin off zero.
Grid oblique_grid(std::size_t nx, std::size_t ny, std::size_t nz) {
  Grid g;
  g.size = {nx, ny, nz};
  const Eigen::Matrix3d rotation =
      (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitX())).matrix();
  g.ijk_to_lps.topLeftCorner<3, 3>() = rotation * Eigen::Vector3d(0.7e-3, 0.9e-3, 1.5e-3).asDiagonal();
  g.ijk_to_lps.topRightCorner<3, 1>() = Eigen::Vector3d(-0.12, 0.05, 0.31);
  return g;
}

TEST(NiftiWrite, TheDvfIsWhatItksNiftiWriterWritesByteForByteButItsDescription) {
  const test::Ball ball = test::make_ball();
  const std::vector<LungMotion> lungs{
      LungMotion{ball.mesh, ball.radial(0.15, Eigen::Vector3d(2.5e-3, -1.5e-3, 3e-3)), 1.0}};
  DisplacementField pull = pullback_dvf(ball.grid, lungs);
  const TempDir dir;
  for (const Grid& grid : {ball.grid, oblique_grid(64, 64, 64)}) {
    pull.grid = grid;
    std::vector<float> mm(3 * pull.displacement_m.size());
    for (std::size_t v = 0; v < pull.displacement_m.size(); ++v)
      for (std::size_t c = 0; c < 3; ++c)
        mm[3 * v + c] = static_cast<float>(pull.displacement_m[v][static_cast<Eigen::Index>(c)] * 1e3);
    itk_write_nii(dir / "itk.nii", grid, itk::IOComponentEnum::FLOAT, 3, mm.data());
    write_dvf(dir / "pneuma.nii", pull);
    const std::string itk = bytes_of(dir / "itk.nii"), ours = bytes_of(dir / "pneuma.nii");
    EXPECT_EQ(differences(itk, ours, true), "");
    EXPECT_EQ(std::string(ours.data() + 148), dvf_description(DvfDirection::pullback, DvfConvention::itk));
  }
}

TEST(NiftiWrite, LabelMapsAndImagesAreWhatItksNiftiWriterWrites) {
  const TempDir dir;
  const Grid grid = oblique_grid(31, 17, 9);  // odd sizes
  image::LabelMap map;
  map.size = grid.size;
  map.ijk_to_lps = grid.ijk_to_lps;
  map.labels.resize(grid.voxel_count());
  Image image{grid, std::vector<float>(grid.voxel_count())};
  for (std::size_t v = 0; v < grid.voxel_count(); ++v) {
    map.labels[v] = static_cast<std::int32_t>(v % 7);
    image.values[v] = -1000.0f + 0.37f * static_cast<float>(v);
  }
  const std::vector<std::uint8_t> u8(map.labels.begin(), map.labels.end());
  itk_write_nii(dir / "itk-u8.nii", grid, itk::IOComponentEnum::UCHAR, 1, u8.data());
  write_label_map(dir / "u8.nii", map);
  EXPECT_EQ(differences(bytes_of(dir / "itk-u8.nii"), bytes_of(dir / "u8.nii"), false), "");
  for (std::size_t v = 0; v < grid.voxel_count(); ++v) map.labels[v] = static_cast<std::int32_t>(v % 7) * 100 - 300;
  const std::vector<std::int16_t> i16(map.labels.begin(), map.labels.end());
  itk_write_nii(dir / "itk-i16.nii", grid, itk::IOComponentEnum::SHORT, 1, i16.data());
  write_label_map(dir / "i16.nii", map);
  EXPECT_EQ(differences(bytes_of(dir / "itk-i16.nii"), bytes_of(dir / "i16.nii"), false), "");
  map.labels[5] = 70000;
  itk_write_nii(dir / "itk-i32.nii", grid, itk::IOComponentEnum::INT, 1, map.labels.data());
  write_label_map(dir / "i32.nii", map);
  EXPECT_EQ(differences(bytes_of(dir / "itk-i32.nii"), bytes_of(dir / "i32.nii"), false), "");
  itk_write_nii(dir / "itk-f32.nii", grid, itk::IOComponentEnum::FLOAT, 1, image.values.data());
  write_image(dir / "f32.nii", image);
  EXPECT_EQ(differences(bytes_of(dir / "itk-f32.nii"), bytes_of(dir / "f32.nii"), false), "");
  // The .nii.gz: Python's gzip inflates it into the plain file's bytes.
  write_image(dir / "f32.nii.gz", image);
  const CommandResult r =
      run_program(kPython, {"-c",
                            "import gzip, sys\n"
                            "print(gzip.open(sys.argv[1]).read() == open(sys.argv[2], 'rb').read())",
                            (dir / "f32.nii.gz").string(), (dir / "f32.nii").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "True\n");
}

// A DVF of 6.3M voxels (76 MB of float32: two 64 MiB batches, the second starting inside the third
// component's volume): nibabel reads every value equal to the formula numpy computes on its own.
TEST(NiftiWrite, AFieldOfSeveralBatchesIsReadBackByNibabelAsTheFormulaMadeIt) {
  if (run_program(kPython, {"-c", "import nibabel, numpy"}).exit_code != 0)
    GTEST_SKIP() << "nibabel is not importable by /usr/bin/python3 (install-deps: python3-nibabel)";
  DisplacementField field;
  field.grid = oblique_grid(200, 181, 175);
  const Grid& g = field.grid;
  field.displacement_m.resize(g.voxel_count());
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i)
        field.displacement_m[g.index(i, j, k)] =
            1e-3 * Eigen::Vector3d(static_cast<double>(i) + 0.25, -static_cast<double>(j) * 0.5,
                                   static_cast<double>(k) * 2.0 - 1.0)
                       .cast<float>();
  const TempDir dir;
  for (const std::string name : {"dvf.nii.gz", "dvf.nii"}) {
    write_dvf(dir / name, field);
    const CommandResult r = run_program(
        kPython, {"-c",
                  "import sys, nibabel, numpy as np\n"
                  "d = np.asarray(nibabel.load(sys.argv[1]).dataobj)\n"
                  "i, j, k = np.meshgrid(*(np.arange(n) for n in d.shape[:3]), indexing='ij')\n"
                  "want = np.stack([i + 0.25, -j * 0.5, k * 2.0 - 1.0], axis=-1).astype(np.float32)\n"
                  "print(d.shape, float(np.abs(d.reshape(want.shape) - want).max() / np.abs(want).max()) < 2.4e-7)",
                  (dir / name).string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.out, "(200, 181, 175, 1, 3) True\n") << name;  // two float32 roundings (m, then mm)
  }
}

// The .nii.gz is filled, compressed and written by a pipeline, a member at a time (#50): its bytes
// are the plain .nii's cut into 4 MiB members from the file's start and each compressed on its own
// (gzip_bytes, the members' own function, over the whole plain file: the oracle; GNU gzip gives
// the plain file back), the same at one and two threads. 12.6 MB: four members, the last short.
TEST(NiftiWrite, TheNiftiGzIsThePlainFileInMembersAtAnyThreadCount) {
  DisplacementField field;
  field.grid = oblique_grid(100, 90, 117);
  const Grid& g = field.grid;
  field.displacement_m.resize(g.voxel_count());
  for (std::size_t v = 0; v < field.displacement_m.size(); ++v) {
    const auto x = static_cast<double>(v);
    field.displacement_m[v] = Eigen::Vector3d(std::sin(x * 1e-4), std::cos(x * 3e-5), 1e-7 * x).cast<float>() * 0.01f;
  }
  const TempDir dir;
  std::string one, two;
  for (const int threads : {1, 2}) {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
    write_dvf(dir / "dvf.nii.gz", field);
    (threads == 1 ? one : two) = bytes_of(dir / "dvf.nii.gz");
  }
  EXPECT_EQ(one, two);
  write_dvf(dir / "dvf.nii", field);
  const std::string plain = bytes_of(dir / "dvf.nii");
  ASSERT_EQ(plain.size(), 352 + 12 * g.voxel_count());
  ASSERT_GT(plain.size(), 3 * kVoxelGzip.member_bytes);
  const std::vector<std::uint8_t> members =
      gzip_bytes(std::span(reinterpret_cast<const std::uint8_t*>(plain.data()), plain.size()));
  EXPECT_TRUE(one == std::string(members.begin(), members.end())) << one.size() << " against " << members.size();
  EXPECT_EQ(run_program("/bin/sh", {"-c", "gzip -dc '" + (dir / "dvf.nii.gz").string() + "' | cmp - '" +
                                              (dir / "dvf.nii").string() + "'"})
                .exit_code,
            0);
}

// A write's error reaches the caller at wait(), the writes queued after it are not run, and the
// queue works again afterwards; writes run in the order queued.
TEST(WriteQueue, WritesRunInOrderAndTheFirstErrorReachesWait) {
  for (const int threads : {1, 2}) {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
    WriteQueue queue;
    std::vector<int> done;
    for (int i = 0; i < 5; ++i) queue.add([&done, i] { done.push_back(i); });
    queue.wait();
    EXPECT_EQ(done, (std::vector<int>{0, 1, 2, 3, 4}));
    if (threads == 1) {
      EXPECT_THROW(queue.add([] { throw IoError("disk full"); }), IoError);  // at once on one thread
    } else {
      queue.add([] { throw IoError("disk full"); });
      queue.add([&done] { done.push_back(99); });
      EXPECT_THROW(queue.wait(), IoError);
      EXPECT_EQ(done.size(), 5u);
    }
    queue.add([&done] { done.push_back(5); });
    queue.wait();
    EXPECT_EQ(done.back(), 5);
  }
}

TEST(NiftiWrite, ANiftiSideOfMoreThan32767VoxelsIsRefusedAndLeavesNoFile) {
  const TempDir dir;
  Image image{oblique_grid(40000, 1, 1), std::vector<float>(40000)};
  EXPECT_THROW(write_image(dir / "wide.nii.gz", image), ValueError);
  EXPECT_TRUE(dir.files().empty());
}

}  // namespace
}  // namespace pneuma::voxels
