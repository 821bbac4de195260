// The rest lungs' mask kept between runs (rest_lungs_cache.h): what is read back is always the
// mask rasterised afresh for the grid and meshes at hand (the oracle: voxels::rest_lungs), and a
// changed grid, a moved node or a damaged file is never served from the file.
#include "pneuma/voxels/rest_lungs_cache.h"

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/voxels/dvf.h"
#include "test_support.h"
#include "tet_fixtures.h"

namespace pneuma::voxels {
namespace {

// Two lungs on the ball's grid: the ball (values 1) and a cube of 3 x 3 x 3 cells of 3 mm in a
// corner of the grid, apart from it (values 2).
struct TwoLungs {
  test::Ball ball = test::make_ball();
  mesh::TetMesh cube = test::cube_cells(ball.grid.centre_m(2, 2, 2), 3e-3, 3);
  std::vector<Eigen::Vector3d> ball_u = ball.radial(0.1), cube_u = std::vector<Eigen::Vector3d>(cube.nodes.size());
  std::vector<LungMotion> lungs() const { return {{ball.mesh, ball_u, 0.0}, {cube, cube_u, 0.0}}; }
};

std::string file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
void write_bytes(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

TEST(RestLungsCache, RunsGiveTheMaskBack) {
  const TwoLungs two;
  const std::vector<std::uint8_t> mask = rest_lungs(two.ball.grid, two.lungs());
  std::size_t changes = 0, ones = 0, twos = 0;
  for (std::size_t v = 0; v < mask.size(); ++v) {
    changes += v > 0 && mask[v] != mask[v - 1];
    ones += mask[v] == 1;
    twos += mask[v] == 2;
  }
  ASSERT_GT(ones, 10000u);  // both lungs are there
  ASSERT_GT(twos, 100u);
  const MaskRuns runs = mask_runs(mask);
  EXPECT_EQ(runs.values.size(), changes + 1);  // a run per change of value
  EXPECT_EQ(mask_of_runs(runs, mask.size()), mask);
  EXPECT_TRUE(mask_runs(std::vector<std::uint8_t>{}).values.empty());
  EXPECT_TRUE(mask_of_runs({}, 0).empty());
  // Runs that do not cover the grid exactly are refused.
  EXPECT_THROW(mask_of_runs(runs, mask.size() + 1), ValueError);
  EXPECT_THROW(mask_of_runs(runs, mask.size() - 1), ValueError);
  EXPECT_THROW(mask_of_runs({{1}, {~std::uint64_t{0}}}, 5), ValueError);
}

TEST(RestLungsCache, AKeptMaskIsTheMaskRasterisedAfresh) {
  const pneuma::test::TempDir dir;
  const TwoLungs two;
  const RestLungsCache cache{dir / "before" / "rest-lungs.cache", dir / "after" / "rest-lungs.cache"};
  const std::vector<std::uint8_t> fresh = rest_lungs(two.ball.grid, two.lungs());
  // No file yet: rasterised, and kept where asked.
  const RestLungsLookup first = cached_rest_lungs(two.ball.grid, two.lungs(), cache);
  EXPECT_FALSE(first.reused);
  EXPECT_TRUE(first.discarded.empty());
  EXPECT_EQ(first.mask, fresh);
  ASSERT_TRUE(std::filesystem::exists(cache.save_to));
  // The next run looks where this one kept it: read back, and copied into its own stage.
  std::filesystem::create_directories(cache.lookup.parent_path());
  std::filesystem::rename(cache.save_to, cache.lookup);
  const RestLungsLookup second = cached_rest_lungs(two.ball.grid, two.lungs(), cache);
  EXPECT_TRUE(second.reused);
  EXPECT_EQ(second.mask, fresh);
  EXPECT_EQ(file_bytes(cache.save_to), file_bytes(cache.lookup));
  // Without a cache: rasterised, nothing written.
  const RestLungsLookup none = cached_rest_lungs(two.ball.grid, two.lungs(), {});
  EXPECT_FALSE(none.reused);
  EXPECT_EQ(none.mask, fresh);
}

// The oracle of each case: rest_lungs() of the changed inputs, which differs from the kept mask
// (so a stale file read back would fail the test).
TEST(RestLungsCache, AChangedGridOrMeshIsRasterisedAfresh) {
  const pneuma::test::TempDir dir;
  TwoLungs two;
  const std::filesystem::path kept = dir / "rest-lungs.cache";
  save_rest_lungs(kept, rest_lungs_key(two.ball.grid, two.lungs()), rest_lungs(two.ball.grid, two.lungs()));
  const std::vector<std::uint8_t> before = rest_lungs(two.ball.grid, two.lungs());
  const RestLungsCache cache{kept, {}};
  ASSERT_TRUE(cached_rest_lungs(two.ball.grid, two.lungs(), cache).reused);

  // The grid moved by a third of a voxel along i.
  Grid shifted = two.ball.grid;
  shifted.ijk_to_lps(0, 3) += 0.33e-3;
  const RestLungsLookup on_shifted = cached_rest_lungs(shifted, two.lungs(), cache);
  EXPECT_FALSE(on_shifted.reused);
  EXPECT_TRUE(on_shifted.discarded.empty());  // another grid: not a damaged file
  EXPECT_EQ(on_shifted.mask, rest_lungs(shifted, two.lungs()));
  EXPECT_NE(on_shifted.mask, before);

  // One node of the cube (the second lung) moved 2 mm outwards: its corner voxels change.
  two.cube.nodes.back() += Eigen::Vector3d::Constant(2e-3);
  const RestLungsLookup moved = cached_rest_lungs(two.ball.grid, two.lungs(), cache);
  EXPECT_FALSE(moved.reused);
  EXPECT_EQ(moved.mask, rest_lungs(two.ball.grid, two.lungs()));
  EXPECT_NE(moved.mask, before);

  // The lungs in the other order (their values swap).
  two.cube.nodes.back() -= Eigen::Vector3d::Constant(2e-3);
  const std::vector<LungMotion> forward = two.lungs();
  const std::vector<LungMotion> swapped{forward[1], forward[0]};
  const RestLungsLookup other_order = cached_rest_lungs(two.ball.grid, swapped, cache);
  EXPECT_FALSE(other_order.reused);
  EXPECT_EQ(other_order.mask, rest_lungs(two.ball.grid, swapped));
  EXPECT_NE(other_order.mask, before);

  // Back to the inputs it was kept for: read back again.
  EXPECT_TRUE(cached_rest_lungs(two.ball.grid, two.lungs(), cache).reused);
}

TEST(RestLungsCache, ADamagedFileIsNeverUsed) {
  const pneuma::test::TempDir dir;
  const TwoLungs two;
  const Grid& grid = two.ball.grid;
  const std::vector<std::uint8_t> fresh = rest_lungs(grid, two.lungs());
  const std::string key = rest_lungs_key(grid, two.lungs());
  const std::filesystem::path kept = dir / "rest-lungs.cache";
  save_rest_lungs(kept, key, fresh);
  const std::string good = file_bytes(kept);
  std::string why;
  ASSERT_TRUE(load_rest_lungs(kept, key, grid.voxel_count(), why));
  EXPECT_TRUE(why.empty());

  // One length's byte changed (the runs still add up to something), a file cut short, a foreign file.
  std::string edited = good;
  edited[edited.size() - 5] = static_cast<char>(edited[edited.size() - 5] ^ 0x01);
  const std::vector<std::pair<std::string, std::string>> damaged{
      {edited, "SHA-256"},
      {good.substr(0, good.size() - 3), "bytes after its header"},
      {"something else\n", "first line"},
      {"", "first line"}};
  for (const auto& [bytes, reason] : damaged) {
    write_bytes(kept, bytes);
    EXPECT_FALSE(load_rest_lungs(kept, key, grid.voxel_count(), why));
    EXPECT_NE(why.find(kept.string() + ": not a pneuma-rest-lungs 1 file: "), std::string::npos) << why;
    EXPECT_NE(why.find(reason), std::string::npos) << why;
    // Rasterised afresh and the file replaced by a good one.
    const RestLungsLookup again = cached_rest_lungs(grid, two.lungs(), {kept, kept});
    EXPECT_FALSE(again.reused);
    EXPECT_FALSE(again.discarded.empty());
    EXPECT_EQ(again.mask, fresh);
    EXPECT_EQ(file_bytes(kept), good);
  }
  // Runs that do not fill the grid under the right key (a forged file) are refused, not misread.
  EXPECT_FALSE(load_rest_lungs(kept, key, grid.voxel_count() + 1, why));
  EXPECT_NE(why.find("the runs hold"), std::string::npos) << why;
  save_rest_lungs(kept, key, std::vector<std::uint8_t>(7, 1));
  EXPECT_FALSE(load_rest_lungs(kept, key, grid.voxel_count(), why));
  EXPECT_NE(why.find("the runs hold 7 voxels"), std::string::npos) << why;
  EXPECT_EQ(cached_rest_lungs(grid, two.lungs(), {kept, kept}).mask, fresh);
}

}  // namespace
}  // namespace pneuma::voxels
