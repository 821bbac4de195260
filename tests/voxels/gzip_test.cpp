// The .nii.gz writer's gzip members (gzip.h). Oracles: zlib's inflate over every member and GNU
// gzip (`gzip -dc`, `gzip -t`) give back the input; the same bytes at one and two threads (the
// members are cut at fixed offsets); files of several members read back by ITK (pneuma's reader)
// and by nibabel with the values written.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <fstream>

#include "pneuma/core/error.h"
#include "pneuma/voxels/gzip.h"
#include "pneuma/voxels/voxel_io.h"
#include "test_support.h"

namespace pneuma::voxels {
namespace {
namespace fs = std::filesystem;
using pneuma::test::run_program;
using pneuma::test::TempDir;

// A smooth float field with noise in its low bits, as a DVF is: 10.5 MiB, three members of 4 MiB.
std::vector<std::uint8_t> field_bytes() {
  std::vector<float> v((std::size_t{21} << 20) / 8);
  std::uint32_t seed = 12345;
  for (std::size_t i = 0; i < v.size(); ++i) {
    seed = seed * 1664525u + 1013904223u;
    v[i] = static_cast<float>(std::sin(static_cast<double>(i) * 1e-4) * 12.0) + static_cast<float>(seed >> 24) * 1e-6f;
  }
  const auto* p = reinterpret_cast<const std::uint8_t*>(v.data());
  return {p, p + v.size() * sizeof(float)};
}

// zlib's inflate over each member in turn (pneuma::test::gunzip); the members' count.
std::vector<std::uint8_t> gunzip(const std::vector<std::uint8_t>& gz, int& members) {
  const std::string out =
      pneuma::test::gunzip(std::string_view(reinterpret_cast<const char*>(gz.data()), gz.size()), &members);
  return {out.begin(), out.end()};
}

TEST(GzipMembers, ZlibAndGnuGzipGiveBackTheInputOfEveryKind) {
  const std::vector<std::uint8_t> data = field_bytes();
  const TempDir dir;
  for (const GzipSettings settings :
       {GzipSettings{GzipLibrary::zlib, 6, 0}, GzipSettings{GzipLibrary::zlib, 1, 4 << 20},
        GzipSettings{GzipLibrary::libdeflate, 1, 4 << 20}, GzipSettings{GzipLibrary::libdeflate, 12, 0}, kVoxelGzip}) {
    const std::vector<std::uint8_t> gz = gzip_bytes(data, settings);
    int members = 0;
    EXPECT_EQ(gunzip(gz, members), data);
    EXPECT_EQ(members, settings.member_bytes == 0 ? 1 : 3);  // 10.5 MiB in 4 MiB pieces
    EXPECT_LT(gz.size(), data.size());
    const fs::path file = dir.path() / "a.gz";
    std::ofstream(file, std::ios::binary).write(reinterpret_cast<const char*>(gz.data()), static_cast<long>(gz.size()));
    EXPECT_EQ(run_program("/bin/gzip", {"-t", file.string()}).exit_code, 0);
    std::ofstream(dir.path() / "raw", std::ios::binary)
        .write(reinterpret_cast<const char*>(data.data()), static_cast<long>(data.size()));
    EXPECT_EQ(run_program("/bin/sh",
                          {"-c", "gzip -dc '" + file.string() + "' | cmp - '" + (dir.path() / "raw").string() + "'"})
                  .exit_code,
              0);
  }
}

TEST(GzipMembers, SameBytesAtOneAndTwoThreads) {
  const std::vector<std::uint8_t> data = field_bytes();
  std::vector<std::uint8_t> one, two;
  {
    const tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 1);
    one = gzip_bytes(data);
  }
  {
    const tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 2);
    two = gzip_bytes(data);
  }
  EXPECT_EQ(one, two);
}

TEST(GzipMembers, LevelOutOfRangeIsOneLine) {
  const std::vector<std::uint8_t> data(10, 0);
  EXPECT_THROW(gzip_bytes(data, {GzipLibrary::zlib, 10, 0}), ValueError);
  EXPECT_THROW(gzip_bytes(data, {GzipLibrary::libdeflate, 0, 0}), ValueError);
  int members = 0;
  EXPECT_EQ(gunzip(gzip_bytes(std::vector<std::uint8_t>{}), members), std::vector<std::uint8_t>{});
  EXPECT_EQ(members, 1);  // an empty input is one empty member, a valid gzip file
}

// A DVF of 24 MB (6 members) and a CT of 8 MB (2 members) written as .nii.gz: ITK (pneuma's
// reader) and nibabel read the values written; the same file bytes at one and two threads.
TEST(GzipMembers, NiftiOfSeveralMembersReadsBackInItkAndNibabel) {
  Grid grid;
  grid.size = {200, 200, 50};
  grid.ijk_to_lps.block<3, 3>(0, 0) = Eigen::Vector3d(1.5e-3, 1.5e-3, 2e-3).asDiagonal();
  Image ct{grid, std::vector<float>(grid.voxel_count())};
  DisplacementField dvf{grid, std::vector<Eigen::Vector3f>(grid.voxel_count()), {}};
  for (std::size_t v = 0; v < ct.values.size(); ++v) {
    ct.values[v] = static_cast<float>(v % 2000) - 1000.0f;
    const double t = static_cast<double>(v) * 1e-5;
    dvf.displacement_m[v] = (Eigen::Vector3d(std::sin(t), std::cos(t), t) * 1e-3).cast<float>();
  }
  const TempDir dir;
  std::string bytes[2];
  for (const int threads : {1, 2}) {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
    write_image(dir.path() / ("ct" + std::to_string(threads) + ".nii.gz"), ct);
    write_dvf(dir.path() / ("dvf" + std::to_string(threads) + ".nii.gz"), dvf);
  }
  for (const std::string name : {"ct", "dvf"}) {
    std::ifstream a(dir.path() / (name + "1.nii.gz"), std::ios::binary),
        b(dir.path() / (name + "2.nii.gz"), std::ios::binary);
    const std::string sa{std::istreambuf_iterator<char>(a), {}}, sb{std::istreambuf_iterator<char>(b), {}};
    EXPECT_EQ(sa, sb) << name;
  }
  EXPECT_EQ(read_image(dir.path() / "ct2.nii.gz").values, ct.values);
  if (run_program("/usr/bin/python3", {"-c", "import nibabel, numpy"}).exit_code != 0)
    GTEST_SKIP() << "nibabel is not importable by /usr/bin/python3 (install-deps: python3-nibabel)";
  // nibabel: the DVF's components in mm (LPS), i fastest, against the same numbers from Python.
  const std::string script =
      "import sys, nibabel, numpy as np\n"
      "ct = np.asarray(nibabel.load(sys.argv[1]).dataobj)\n"
      "v = np.arange(ct.size)\n"
      "assert np.array_equal(ct.transpose(2, 1, 0).ravel(), (v % 2000 - 1000).astype(np.float32)), 'ct'\n"
      "d = np.asarray(nibabel.load(sys.argv[2]).dataobj).reshape(200, 200, 50, 3)\n"
      "t = v * 1e-5\n"
      "want = (np.stack([np.sin(t), np.cos(t), t], 1) * 1e-3 * 1e3).astype(np.float32)\n"
      "got = d.transpose(2, 1, 0, 3).reshape(-1, 3)\n"
      "assert np.abs(got - want).max() <= 2.4e-7 * np.abs(want).max(), np.abs(got - want).max()\n";  // float32 m, then
                                                                                                     // mm
  const auto r = run_program(
      "/usr/bin/python3", {"-c", script, (dir.path() / "ct2.nii.gz").string(), (dir.path() / "dvf2.nii.gz").string()});
  EXPECT_EQ(r.exit_code, 0) << r.err;
}

}  // namespace
}  // namespace pneuma::voxels
