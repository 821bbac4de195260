// Voxel files written past the page cache and hashed as they are written (voxels/src/direct_file.h,
// voxels/written_digest.h; #50). Oracles: the file's bytes after the header are the image's own
// float bytes (the input), its length is the header's 352 bytes plus 4 a voxel, and its digest is
// the one coreutils' sha256sum computes from the file on disk; the same on tmpfs (/dev/shm), which
// refuses O_DIRECT, and for a .nii.gz (compressed members: unaligned pieces gathered).
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cstring>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <vector>

#include "pneuma/voxels/voxel_io.h"
#include "pneuma/voxels/written_digest.h"
#include "test_support.h"

namespace pneuma::voxels {
namespace {
namespace fs = std::filesystem;
using pneuma::test::run_program;
using pneuma::test::TempDir;

// An image of nx x ny x nz voxels with values that tell each voxel apart.
Image numbered_image(std::size_t nx, std::size_t ny, std::size_t nz) {
  Image image;
  image.grid.size = {nx, ny, nz};
  image.grid.ijk_to_lps = Eigen::Matrix4d::Identity();
  image.grid.ijk_to_lps.block<3, 3>(0, 0) *= 1e-3;
  image.values.resize(image.grid.voxel_count());
  for (std::size_t v = 0; v < image.values.size(); ++v) image.values[v] = 0.25f * static_cast<float>(v) - 7.0f;
  return image;
}

std::string file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::string sha256sum(const fs::path& path) {
  const auto result = run_program("/usr/bin/sha256sum", {path.string()});
  EXPECT_EQ(result.exit_code, 0) << result.err;
  return result.out.substr(0, 64);
}

// Each image (not a whole number of 4 KiB blocks; the largest more than one 4 MiB chunk) as .nii
// and .nii.gz in `folder`: the .nii's data the image's bytes, each file's digest sha256sum's.
void check_files_in(const fs::path& folder) {
  for (const auto& [nx, ny, nz] : {std::array<std::size_t, 3>{7, 5, 3}, std::array<std::size_t, 3>{32, 32, 1},
                                   std::array<std::size_t, 3>{211, 101, 53}}) {
    const Image image = numbered_image(nx, ny, nz);
    for (const std::string extension : {".nii", ".nii.gz"}) {
      const fs::path path = folder / ("image-" + std::to_string(nx) + extension);
      write_image(path, image);
      const std::string bytes = file_bytes(path);
      if (extension == ".nii") {
        ASSERT_EQ(bytes.size(), 352 + 4 * image.values.size()) << path;
        EXPECT_EQ(std::memcmp(bytes.data() + 352, image.values.data(), 4 * image.values.size()), 0) << path;
      }
      const std::optional<std::string> written = written_sha256(path);
      ASSERT_TRUE(written.has_value()) << path;
      EXPECT_EQ(*written, sha256sum(path)) << path;
    }
  }
  // The folder holds the files and nothing else (no temporary left).
  std::size_t files = 0;
  for (const auto& entry : fs::directory_iterator(folder)) files += entry.is_regular_file();
  EXPECT_EQ(files, 6u);
}

TEST(WrittenDigest, EachVoxelFileHoldsItsBytesAndTheDigestSha256sumComputes) {
  const TempDir dir;
  check_files_in(dir.path());
}

TEST(WrittenDigest, OnTmpfsWithoutDirectWritesTheSame) {
  if (!fs::is_directory("/dev/shm")) GTEST_SKIP() << "no /dev/shm";
  const fs::path folder = fs::path("/dev/shm") / ("pneuma-written-digest-" + std::to_string(::getpid()));
  fs::create_directories(folder);
  check_files_in(folder);
  fs::remove_all(folder);
}

TEST(WrittenDigest, NoneForAFileNotWrittenSoOrChangedSince) {
  const TempDir dir;
  const fs::path other = dir.write("other.nii", "not written by the voxel writer");
  EXPECT_FALSE(written_sha256(other).has_value());
  EXPECT_FALSE(written_sha256(dir / "missing.nii").has_value());
  // Appended to: another size.
  const fs::path grown = dir / "grown.nii";
  write_image(grown, numbered_image(7, 5, 3));
  ASSERT_TRUE(written_sha256(grown).has_value());
  std::ofstream(grown, std::ios::binary | std::ios::app) << "x";
  EXPECT_FALSE(written_sha256(grown).has_value());
  // Replaced by another file of the same size (renamed over it): another inode.
  const fs::path replaced = dir / "replaced.nii";
  write_image(replaced, numbered_image(7, 5, 3));
  const fs::path copy = dir / "copy.nii";
  fs::copy_file(replaced, copy);
  fs::rename(copy, replaced);
  EXPECT_FALSE(written_sha256(replaced).has_value());
}

}  // namespace
}  // namespace pneuma::voxels
