#include "pneuma/field/deflation.h"

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <atomic>
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

  // The grid of `points` with cells of `size` (keys that collide only put more points in a cell),
  // or of 2^-20 of the points' extent where `size` is smaller: an index then stays far inside the
  // key's range, and larger cells only put more candidates before each distance test.
  static Grid of(const std::vector<Eigen::Vector3d>& points, double size) {
    Grid grid;
    grid.origin = points.front();
    Eigen::Vector3d top = points.front();
    for (const Eigen::Vector3d& p : points) {
      grid.origin = grid.origin.cwiseMin(p);
      top = top.cwiseMax(p);
    }
    grid.cell = std::max(size, std::ldexp((top - grid.origin).maxCoeff(), -20));
    for (std::uint32_t v = 0; v < points.size(); ++v) {
      const auto [i, j, k] = grid.index(points[v]);
      grid.cells[key(i, j, k)].push_back(v);
    }
    return grid;
  }
};

void require_sizes(const char* what, std::size_t fields, std::size_t points) {
  if (fields != points) throw ValueError(fmt::format("{}: {} displacements for {} points", what, fields, points));
}

// Points and displacements must be finite: a NaN would drop its pairs from every comparison.
void require_finite(const char* what, const std::vector<Eigen::Vector3d>& points,
                    const std::vector<Eigen::Vector3d>& d) {
  for (std::size_t v = 0; v < points.size(); ++v) {
    if (!points[v].allFinite() || !d[v].allFinite())
      throw ValueError(fmt::format("{}: point {} or its displacement is not finite", what, v));
  }
}

// Calls visit(w) for every point w in the grid's 27 cells around x's (in ascending order of cell
// and index: a sum taken in it is the same at any thread count) until it returns false; false then.
template <typename Visit>
bool visit_cells_around(const Grid& grid, const Eigen::Vector3d& x, Visit&& visit) {
  const auto [ci, cj, ck] = grid.index(x);
  for (std::int64_t i = ci - 1; i <= ci + 1; ++i) {
    for (std::int64_t j = cj - 1; j <= cj + 1; ++j) {
      for (std::int64_t k = ck - 1; k <= ck + 1; ++k) {
        const auto cell = grid.cells.find(Grid::key(i, j, k));
        if (cell == grid.cells.end()) continue;
        for (const std::uint32_t w : cell->second) {
          if (!visit(w)) return false;
        }
      }
    }
  }
  return true;
}

// Calls visit(w, |x_w - x_v|^2) for every point w > v of the grid's cells around v's (each pair
// once) until it returns false; false then.
template <typename Visit>
bool visit_later_neighbours(const Grid& grid, const std::vector<Eigen::Vector3d>& points, std::size_t v,
                            Visit&& visit) {
  const Eigen::Vector3d& x = points[v];
  return visit_cells_around(grid, x,
                            [&](std::uint32_t w) { return w <= v || visit(w, (points[w] - x).squaredNorm()); });
}

}  // namespace

std::vector<Eigen::Vector3d> smooth_field_in_space(const mesh::TriangleMesh& rest,
                                                   const std::vector<Eigen::Vector3d>& u, double sigma_m) {
  if (u.size() != rest.vertices.size())
    throw ValueError(
        fmt::format("smooth_field_in_space: {} displacements for {} vertices", u.size(), rest.vertices.size()));
  if (!(sigma_m > 0.0) || rest.vertices.empty()) return u;
  const std::vector<double> area = mesh::vertex_areas(rest);  // a third of each triangle to its corners
  // Cells of the kernel's reach: exp(-8) of the centre weight beyond it.
  const Grid grid = Grid::of(rest.vertices, 4.0 * sigma_m);
  const double reach2 = grid.cell * grid.cell;
  const double inv_two_sigma2 = 1.0 / (2.0 * sigma_m * sigma_m);
  std::vector<Eigen::Vector3d> out(u.size());
  const tsan::Region region;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, u.size(), 256),
                    region.wrap([&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t v = r.begin(); v != r.end(); ++v) {
                        const Eigen::Vector3d& x = rest.vertices[v];
                        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
                        double weight = 0.0;
                        visit_cells_around(grid, x, [&](std::uint32_t w) {
                          const double d2 = (rest.vertices[w] - x).squaredNorm();
                          if (d2 <= reach2) {
                            const double kw = area[w] * std::exp(-d2 * inv_two_sigma2);
                            sum += kw * u[w];
                            weight += kw;
                          }
                          return true;
                        });
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

double steepest_pair_slope(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& d,
                           double radius_m) {
  require_sizes("steepest_pair_slope", d.size(), points.size());
  require_finite("steepest_pair_slope", points, d);
  if (!(radius_m > 0.0) || points.size() < 2) return 0.0;
  const Grid grid = Grid::of(points, radius_m);
  const double reach2 = radius_m * radius_m;
  const tsan::Region region;
  // A maximum does not depend on the order it is taken in: the same answer at any thread count.
  const double steepest =
      tbb::parallel_reduce(tbb::blocked_range<std::size_t>(0, points.size(), 128), 0.0,
                           region.wrap([&](const tbb::blocked_range<std::size_t>& r, double most) {
                             for (std::size_t v = r.begin(); v != r.end(); ++v) {
                               visit_later_neighbours(grid, points, v, [&](std::uint32_t w, double d2) {
                                 // Every pair's own ratio (no shortcut whose rounding could depend on the order).
                                 if (d2 <= reach2 && d2 > 0.0)
                                   most = std::max(most, std::sqrt((d[w] - d[v]).squaredNorm() / d2));
                                 return true;
                               });
                             }
                             return most;
                           }),
                           [](double a, double b) { return std::max(a, b); });
  region.join();
  return steepest;
}

bool is_contraction(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& d) {
  require_sizes("is_contraction", d.size(), points.size());
  require_finite("is_contraction", points, d);
  double largest = 0.0;
  for (const Eigen::Vector3d& v : d) largest = std::max(largest, v.norm());
  if (!(largest > 0.0) || points.size() < 2) return true;
  // |d_v - d_w| <= |d_v| + largest: a pair farther apart than that cannot fail, so each point
  // visits the cells within 2 largest and tests only the pairs within its own bound.
  const Grid grid = Grid::of(points, 2.0 * largest);
  std::atomic<bool> stretched{false};  // the answer, whichever pair finds it first
  const tsan::Region region;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 64),
                    region.wrap([&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t v = r.begin(); v != r.end(); ++v) {
                        if (stretched.load(std::memory_order_relaxed)) return;
                        const double bound = d[v].norm() + largest;
                        const bool contracts = visit_later_neighbours(grid, points, v, [&](std::uint32_t w, double d2) {
                          return !(d2 <= bound * bound && d2 > 0.0) || (d[w] - d[v]).squaredNorm() < d2;
                        });
                        if (!contracts) stretched.store(true, std::memory_order_relaxed);
                      }
                    }));
  region.join();
  return !stretched.load();
}

}  // namespace pneuma::field
