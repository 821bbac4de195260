// level_set_euler_characteristics(): the topology of a smoothed mask's 0.5 level set, counted on
// its samples before any meshing, so that a mask whose surface would have a handle is not meshed
// only to be thrown away (labels.cpp, step 7).
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <array>
#include <cstdint>
#include <vector>

#include "pneuma/core/tsan.h"
#include "pneuma/mesh/labels/labels.h"

namespace pneuma::mesh::detail {

LevelSetEuler level_set_euler_characteristics(const ScalarGrid& grid) {
  const auto& n = grid.size;
  if (n[0] < 2 || n[1] < 2 || n[2] < 2) return {};
  // The inside samples with a layer of background before each axis: sample (i, j, k) at
  // (i + 1, j + 1, k + 1). The sampler of labels_cgal.cpp reads the last sample of each axis as
  // background (the crop's border), and everything off the grid: so does this.
  const std::array<std::size_t, 3> m{n[0] + 1, n[1] + 1, n[2] + 1};
  const std::size_t sy = m[0], sz = m[0] * m[1];
  std::vector<std::uint8_t> in(m[0] * m[1] * m[2], 0);
  for (std::size_t k = 0; k + 1 < n[2]; ++k)
    for (std::size_t j = 0; j + 1 < n[1]; ++j)
      for (std::size_t i = 0; i + 1 < n[0]; ++i)
        in[(i + 1) + sy * (j + 1) + sz * (k + 1)] = grid.values[i + n[0] * (j + n[1] * k)] > 0.5f ? 1 : 0;
  // One pass over the corners c = (i, j, k), 0 <= c <= n - 1, with the 2 x 2 x 2 samples
  // b[z][y][x] at c - 1 + (x, y, z). Each cell is counted once, at its lowest corner:
  //   thin (6-connected inside): the samples' grid cells (vertex, edges, squares, cube at sample
  //     c) whose every corner is inside;
  //   thick (26-connected inside): the closed voxel cubes around the inside samples; a cell of
  //     their lattice (the corner before sample c, its edges and faces towards c, the cube of c)
  //     is in it when the cube of any sample it touches is.
  // Integer sums: any split of the slabs gives the same totals.
  const tsan::Region region;
  const LevelSetEuler chi = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, n[2]), LevelSetEuler{},
      region.wrap([&](const tbb::blocked_range<std::size_t>& slabs, LevelSetEuler sum) {
        for (std::size_t k = slabs.begin(); k < slabs.end(); ++k) {
          for (std::size_t j = 0; j < n[1]; ++j) {
            const std::uint8_t* row = in.data() + sy * j + sz * k;  // b[0][0][0] of corner (0, j, k)
            for (std::size_t i = 0; i < n[0]; ++i) {
              const std::uint8_t* p = row + i;
              const bool b000 = p[0], b001 = p[1], b010 = p[sy], b011 = p[sy + 1];
              const bool b100 = p[sz], b101 = p[sz + 1], b110 = p[sz + sy], b111 = p[sz + sy + 1];
              if (!(b000 || b001 || b010 || b011 || b100 || b101 || b110 || b111)) continue;
              if (b111) {  // sample c and its neighbours at c + 1 along each axis
                const std::uint8_t* c = p + sz + sy + 1;
                const bool x = c[1], y = c[sy], z = c[sz];
                const bool xy = x && y && c[sy + 1], xz = x && z && c[sz + 1], yz = y && z && c[sz + sy];
                const bool xyz = xy && xz && yz && c[sz + sy + 1];
                sum.thin += 1 - (x + y + z) + (xy + xz + yz) - xyz;
              }
              const bool ex = b001 || b011 || b101 || b111, ey = b010 || b011 || b110 || b111,
                         ez = b100 || b101 || b110 || b111;
              const bool fxy = b011 || b111, fxz = b101 || b111, fyz = b110 || b111;
              sum.thick += 1 - (ex + ey + ez) + (fxy + fxz + fyz) - b111;
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
