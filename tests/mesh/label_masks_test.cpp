// The label map's mask steps (mesh/labels: the closing, the largest component, the cavities)
// against the definitions they implement, voxel by voxel, on random masks; also in the
// ThreadSanitizer suite (the closing's passes run on every core).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "pneuma/mesh/labels/labels.h"

namespace {

std::vector<std::uint8_t> random_mask(const std::array<std::size_t, 3>& n, double fill, unsigned seed) {
  std::vector<std::uint8_t> mask(n[0] * n[1] * n[2]);
  std::uint64_t state = seed;
  for (auto& m : mask) {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;  // a fixed LCG: the same masks everywhere
    m = static_cast<double>(state >> 11) / 9007199254740992.0 < fill ? 1 : 0;
  }
  return mask;
}

// Closing with a ball: a voxel is in the dilation when a mask voxel lies within r of it, and in
// the closing when it is in the mask or every voxel of the grid within r of it is in the dilation.
TEST(LabelMasks, ClosingIsTheBallClosingVoxelForVoxel) {
  using pneuma::mesh::detail::close_mask;
  const std::array<std::size_t, 3> n{34, 30, 26};
  const Eigen::Vector3d spacing(0.7e-3, 0.8e-3, 1.1e-3);
  for (const double r : {1.5e-3, 3.0e-3, 4.5e-3}) {
    // Offsets within r, none within rounding of r (where float distances could decide either way).
    std::vector<std::array<int, 3>> ball;
    const int reach = 8;
    for (int c = -reach; c <= reach; ++c)
      for (int b = -reach; b <= reach; ++b)
        for (int a = -reach; a <= reach; ++a) {
          const double d2 = Eigen::Vector3d(a, b, c).cwiseProduct(spacing).squaredNorm();
          ASSERT_GT(std::abs(d2 - r * r), 1e-6 * r * r) << "an offset lies on the ball's rim";
          if (d2 <= r * r) ball.push_back({a, b, c});
        }
    for (const double fill : {0.15, 0.5}) {
      std::vector<std::uint8_t> mask = random_mask(n, fill, 7u);
      const std::vector<std::uint8_t> original = mask;
      auto index = [&](long i, long j, long k) -> long {
        if (i < 0 || j < 0 || k < 0 || i >= static_cast<long>(n[0]) || j >= static_cast<long>(n[1]) ||
            k >= static_cast<long>(n[2]))
          return -1;
        return i + static_cast<long>(n[0]) * (j + static_cast<long>(n[1]) * k);
      };
      auto any_within = [&](const std::vector<std::uint8_t>& m, long i, long j, long k, std::uint8_t value) {
        for (const auto& [a, b, c] : ball) {
          const long w = index(i + a, j + b, k + c);
          if (w >= 0 && m[static_cast<std::size_t>(w)] == value) return true;
        }
        return false;
      };
      std::vector<std::uint8_t> dilated(mask.size()), expected(mask.size());
      for (long k = 0; k < static_cast<long>(n[2]); ++k)
        for (long j = 0; j < static_cast<long>(n[1]); ++j)
          for (long i = 0; i < static_cast<long>(n[0]); ++i)
            dilated[static_cast<std::size_t>(index(i, j, k))] = any_within(original, i, j, k, 1) ? 1 : 0;
      std::size_t added = 0;
      for (long k = 0; k < static_cast<long>(n[2]); ++k)
        for (long j = 0; j < static_cast<long>(n[1]); ++j)
          for (long i = 0; i < static_cast<long>(n[0]); ++i) {
            const auto v = static_cast<std::size_t>(index(i, j, k));
            expected[v] = original[v] || !any_within(dilated, i, j, k, 0) ? 1 : 0;
            added += expected[v] && !original[v];
          }
      EXPECT_EQ(close_mask(n, mask, spacing, r), added) << "r " << r << ", fill " << fill;
      EXPECT_EQ(mask, expected) << "r " << r << ", fill " << fill;
      EXPECT_GT(added, 0u) << "r " << r << ", fill " << fill;
    }
  }
}

// Connected components by a plain voxel-by-voxel breadth-first search, the definition.
std::vector<int> components(const std::array<std::size_t, 3>& n, const std::vector<std::uint8_t>& mask,
                            std::uint8_t value, int connectivity, std::vector<std::size_t>& sizes) {
  std::vector<int> id(mask.size(), -1);
  sizes.clear();
  for (std::size_t seed = 0; seed < mask.size(); ++seed) {
    if (mask[seed] != value || id[seed] >= 0) continue;
    const int c = static_cast<int>(sizes.size());
    sizes.push_back(0);
    std::vector<std::size_t> queue{seed};
    id[seed] = c;
    for (std::size_t q = 0; q < queue.size(); ++q) {
      const std::size_t v = queue[q];
      ++sizes.back();
      const long i = static_cast<long>(v % n[0]), j = static_cast<long>((v / n[0]) % n[1]),
                 k = static_cast<long>(v / (n[0] * n[1]));
      for (long dk = -1; dk <= 1; ++dk)
        for (long dj = -1; dj <= 1; ++dj)
          for (long di = -1; di <= 1; ++di) {
            const long steps = std::abs(di) + std::abs(dj) + std::abs(dk);
            if (steps == 0 || (connectivity == 6 && steps > 1)) continue;
            const long a = i + di, b = j + dj, d = k + dk;
            if (a < 0 || b < 0 || d < 0 || a >= static_cast<long>(n[0]) || b >= static_cast<long>(n[1]) ||
                d >= static_cast<long>(n[2]))
              continue;
            const auto w = static_cast<std::size_t>(a + static_cast<long>(n[0]) * (b + static_cast<long>(n[1]) * d));
            if (mask[w] == value && id[w] < 0) id[w] = c, queue.push_back(w);
          }
    }
  }
  return id;
}

TEST(LabelMasks, TheLargestComponentIsKeptAsABreadthFirstSearchFindsIt) {
  using pneuma::mesh::detail::keep_largest_component;
  const std::array<std::size_t, 3> n{31, 27, 23};
  for (const double fill : {0.12, 0.2, 0.3}) {
    std::vector<std::uint8_t> mask = random_mask(n, fill, 11u);
    std::vector<std::size_t> sizes;
    const std::vector<int> id = components(n, mask, 1, 26, sizes);
    ASSERT_GT(sizes.size(), 1u) << fill;
    const auto keep = static_cast<int>(std::max_element(sizes.begin(), sizes.end()) - sizes.begin());
    std::vector<std::uint8_t> expected(mask.size());
    std::size_t dropped = 0;
    for (std::size_t v = 0; v < mask.size(); ++v) {
      expected[v] = id[v] == keep ? 1 : 0;
      dropped += mask[v] && id[v] != keep;
    }
    const auto [components_dropped, voxels_dropped] = keep_largest_component(n, mask);
    EXPECT_EQ(components_dropped, sizes.size() - 1) << fill;
    EXPECT_EQ(voxels_dropped, dropped) << fill;
    EXPECT_EQ(mask, expected) << fill;
  }
  // A tie: two equal blocks; the one with the lower first voxel stays.
  std::vector<std::uint8_t> two(n[0] * n[1] * n[2], 0);
  for (std::size_t k = 2; k < 5; ++k)
    for (std::size_t j = 2; j < 5; ++j)
      for (std::size_t i : {2u, 3u, 20u, 21u}) two[i + n[0] * (j + n[1] * k)] = 1;
  EXPECT_EQ(keep_largest_component(n, two), (std::pair<std::size_t, std::size_t>{1, 18}));
  EXPECT_EQ(two[2 + n[0] * (2 + n[1] * 2)], 1);
  EXPECT_EQ(two[20 + n[0] * (2 + n[1] * 2)], 0);
}

TEST(LabelMasks, CavitiesAreTheBackgroundComponentsOffTheBorder) {
  using pneuma::mesh::detail::fill_cavities;
  const std::array<std::size_t, 3> n{29, 25, 21};
  for (const double fill : {0.55, 0.65, 0.75}) {
    std::vector<std::uint8_t> mask = random_mask(n, fill, 5u);
    std::vector<std::size_t> sizes;
    const std::vector<int> id = components(n, mask, 0, 6, sizes);
    std::vector<bool> outside(sizes.size(), false);
    for (std::size_t v = 0; v < mask.size(); ++v) {
      const std::size_t i = v % n[0], j = (v / n[0]) % n[1], k = v / (n[0] * n[1]);
      const bool border = i == 0 || j == 0 || k == 0 || i + 1 == n[0] || j + 1 == n[1] || k + 1 == n[2];
      if (border && id[v] >= 0) outside[static_cast<std::size_t>(id[v])] = true;
    }
    std::size_t cavities = 0, filled = 0;
    for (std::size_t c = 0; c < sizes.size(); ++c)
      if (!outside[c]) ++cavities, filled += sizes[c];
    std::vector<std::uint8_t> expected(mask.size());
    for (std::size_t v = 0; v < mask.size(); ++v)
      expected[v] = mask[v] || !outside[static_cast<std::size_t>(id[v])] ? 1 : 0;
    ASSERT_GT(cavities, 0u) << fill;
    EXPECT_EQ(fill_cavities(n, mask), (std::pair<std::size_t, std::size_t>{cavities, filled})) << fill;
    EXPECT_EQ(mask, expected) << fill;
  }
}

}  // namespace
