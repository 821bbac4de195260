// level_set_euler_characteristics(): the topology of a smoothed mask's 0.5 level set, counted on
// its samples before any meshing, so that a mask whose surface would have a handle is not meshed
// only to be thrown away (labels.cpp, step 7).
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <cstdint>

#include "pneuma/core/tsan.h"
#include "pneuma/mesh/labels/labels.h"

namespace pneuma::mesh::detail {

LevelSetEuler level_set_euler_characteristics(const ScalarGrid& grid) {
  const auto& n = grid.size;
  if (n[0] < 2 || n[1] < 2 || n[2] < 2) return {};
  // The sampler of labels_cgal.cpp reads the last sample of each axis as background (the crop's
  // border), and everything off the grid: so do the counts here.
  auto inside = [&](std::ptrdiff_t i, std::ptrdiff_t j, std::ptrdiff_t k) {
    return i >= 0 && j >= 0 && k >= 0 && static_cast<std::size_t>(i) + 1 < n[0] &&
           static_cast<std::size_t>(j) + 1 < n[1] && static_cast<std::size_t>(k) + 1 < n[2] &&
           grid.values[static_cast<std::size_t>(i) +
                       n[0] * (static_cast<std::size_t>(j) + n[1] * static_cast<std::size_t>(k))] > 0.5f;
  };
  // One pass over the corners c = (i, j, k), 0 <= c <= n - 1, with the 2 x 2 x 2 samples
  // b[z][y][x] = inside(c - 1 + (x, y, z)). Each cell is counted once, at its lowest corner:
  //   thin (6-connected inside): the samples' grid cells (vertex, edges, squares, cube at c)
  //     whose every corner is inside, i.e. the lattice between samples b[1][*][*]...b[1][1][1];
  //   thick (26-connected inside): closed voxel cubes around the inside samples; a cell of their
  //     lattice (a vertex, edge, face at the corner between samples) is in it when any sample
  //     whose cube it touches is.
  // Integer sums: any split of the slabs gives the same totals.
  const tsan::Region region;
  const LevelSetEuler chi = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, n[2]), LevelSetEuler{},
      region.wrap([&](const tbb::blocked_range<std::size_t>& slabs, LevelSetEuler sum) {
        for (std::size_t kk = slabs.begin(); kk < slabs.end(); ++kk) {
          const auto k = static_cast<std::ptrdiff_t>(kk);
          for (std::ptrdiff_t j = 0; j < static_cast<std::ptrdiff_t>(n[1]); ++j) {
            for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(n[0]); ++i) {
              bool b[2][2][2];
              bool any = false;
              for (int z = 0; z < 2; ++z)
                for (int y = 0; y < 2; ++y)
                  for (int x = 0; x < 2; ++x) any |= b[z][y][x] = inside(i - 1 + x, j - 1 + y, k - 1 + z);
              if (!any) continue;
              // Thin: the sample at c (b[1][1][1]) with its neighbours at c + 1 along each axis.
              if (b[1][1][1]) {
                const bool x = inside(i + 1, j, k), y = inside(i, j + 1, k), z = inside(i, j, k + 1);
                const bool xy = x && y && inside(i + 1, j + 1, k), xz = x && z && inside(i + 1, j, k + 1),
                           yz = y && z && inside(i, j + 1, k + 1);
                const bool xyz = xy && xz && yz && inside(i + 1, j + 1, k + 1);
                sum.thin += 1 - (x + y + z) + (xy + xz + yz) - xyz;
              }
              // Thick: the corner below-behind-left of sample c, its three edges and faces
              // towards c, and the cube of c.
              const bool ex = b[0][0][1] || b[0][1][1] || b[1][0][1] || b[1][1][1];
              const bool ey = b[0][1][0] || b[0][1][1] || b[1][1][0] || b[1][1][1];
              const bool ez = b[1][0][0] || b[1][0][1] || b[1][1][0] || b[1][1][1];
              const bool fxy = b[0][1][1] || b[1][1][1], fxz = b[1][0][1] || b[1][1][1], fyz = b[1][1][0] || b[1][1][1];
              sum.thick += 1 - (ex + ey + ez) + (fxy + fxz + fyz) - b[1][1][1];
            }
          }
        }
        return sum;
      }),
      region.wrap([](LevelSetEuler a, const LevelSetEuler& b) {
        a.thin += b.thin;
        a.thick += b.thick;
        return a;
      }));
  region.join();
  return chi;
}

}  // namespace pneuma::mesh::detail
