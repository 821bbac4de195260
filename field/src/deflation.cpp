#include "pneuma/field/deflation.h"

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <unordered_map>

#include "pneuma/core/error.h"
#include "pneuma/core/tsan.h"
#include "pneuma/mesh/anatomy/regions.h"

namespace pneuma::field {
namespace {

// Cells of a uniform grid, each listing its vertices in ascending order.
struct Grid {
  double cell = 1.0;
  Eigen::Vector3d origin;
  std::unordered_map<std::int64_t, std::vector<std::uint32_t>> cells;

  std::array<std::int64_t, 3> index(const Eigen::Vector3d& p) const {
    const Eigen::Vector3d q = (p - origin) / cell;
    return {static_cast<std::int64_t>(std::floor(q.x())), static_cast<std::int64_t>(std::floor(q.y())),
            static_cast<std::int64_t>(std::floor(q.z()))};
  }
  static std::int64_t key(std::int64_t i, std::int64_t j, std::int64_t k) { return (i * 4096 + j) * 4096 + k; }
};

}  // namespace

std::vector<Eigen::Vector3d> smooth_field_in_space(const mesh::TriangleMesh& rest,
                                                   const std::vector<Eigen::Vector3d>& u, double sigma_m) {
  if (u.size() != rest.vertices.size())
    throw ValueError(
        fmt::format("smooth_field_in_space: {} displacements for {} vertices", u.size(), rest.vertices.size()));
  if (!(sigma_m > 0.0) || rest.vertices.empty()) return u;
  const std::vector<double> area = mesh::vertex_areas(rest);  // a third of each triangle to its corners
  Grid grid;
  grid.cell = 4.0 * sigma_m;  // the kernel's reach: exp(-8) of the centre weight beyond it
  grid.origin = rest.vertices.front();
  for (const Eigen::Vector3d& p : rest.vertices) grid.origin = grid.origin.cwiseMin(p);
  for (std::uint32_t v = 0; v < rest.vertices.size(); ++v) {
    const auto [i, j, k] = grid.index(rest.vertices[v]);
    grid.cells[Grid::key(i, j, k)].push_back(v);
  }
  const double reach2 = grid.cell * grid.cell;
  const double inv_two_sigma2 = 1.0 / (2.0 * sigma_m * sigma_m);
  std::vector<Eigen::Vector3d> out(u.size());
  const tsan::Region region;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, u.size(), 256),
                    region.wrap([&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t v = r.begin(); v != r.end(); ++v) {
                        const Eigen::Vector3d& x = rest.vertices[v];
                        const auto [ci, cj, ck] = grid.index(x);
                        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
                        double weight = 0.0;
                        for (std::int64_t i = ci - 1; i <= ci + 1; ++i) {
                          for (std::int64_t j = cj - 1; j <= cj + 1; ++j) {
                            for (std::int64_t k = ck - 1; k <= ck + 1; ++k) {
                              const auto cell = grid.cells.find(Grid::key(i, j, k));
                              if (cell == grid.cells.end()) continue;
                              for (const std::uint32_t w : cell->second) {
                                const double d2 = (rest.vertices[w] - x).squaredNorm();
                                if (d2 > reach2) continue;
                                const double kw = area[w] * std::exp(-d2 * inv_two_sigma2);
                                sum += kw * u[w];
                                weight += kw;
                              }
                            }
                          }
                        }
                        out[v] = sum / weight;  // the vertex itself is within reach: weight > 0
                      }
                    }));
  region.join();
  // Keep the area unit: s means the same first-order area change as before.
  const std::vector<Eigen::Vector3d> g = mesh::area_gradient(rest);
  double before = 0.0, after = 0.0;
  for (std::size_t v = 0; v < u.size(); ++v) {
    before += g[v].dot(u[v]);
    after += g[v].dot(out[v]);
  }
  if (!(after > 0.0) || !(before > 0.0))
    throw ValueError(fmt::format("smooth_field_in_space: the field smoothed at {:.3g} mm does not enlarge the surface",
                                 sigma_m * 1e3));
  for (Eigen::Vector3d& d : out) d *= before / after;
  return out;
}

}  // namespace pneuma::field
