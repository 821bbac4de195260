#include "pneuma/mesh/anatomy/regions.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/task_arena.h>

#include "pneuma/core/error.h"
#include "pneuma/core/parallel.h"
#include "pneuma/core/tsan.h"

namespace pneuma::mesh {
namespace {

double smoothstep(double u) {
  u = std::clamp(u, 0.0, 1.0);
  return u * u * (3.0 - 2.0 * u);
}
// 0 below centre - half_width, 1 above centre + half_width, smooth (C1) in between.
double ramp(double x, double centre, double half_width) {
  return smoothstep((x - (centre - half_width)) / (2.0 * half_width));
}

// A regular grid of small vectors (Eigen::Vector3d, or Vector2d for a value and its weight) over
// a box, for splatting and blurring.
template <class Value>
struct VectorGrid {
  Eigen::Vector3d origin;
  double h = 0.0;
  std::array<std::ptrdiff_t, 3> n{};
  std::vector<Value> value;

  std::size_t index(std::ptrdiff_t i, std::ptrdiff_t j, std::ptrdiff_t k) const {
    return static_cast<std::size_t>((k * n[1] + j) * n[0] + i);
  }
  // The cell holding p and the fractional position in it (clamped to the grid).
  void locate(const Eigen::Vector3d& p, std::array<std::ptrdiff_t, 3>& cell, Eigen::Vector3d& frac) const {
    for (int a = 0; a < 3; ++a) {
      const double x =
          std::clamp((p[a] - origin[a]) / h, 0.0, static_cast<double>(n[static_cast<std::size_t>(a)] - 1) - 1e-9);
      const double f = std::floor(x);
      cell[static_cast<std::size_t>(a)] = static_cast<std::ptrdiff_t>(f);
      frac[a] = x - f;
    }
  }
  // Adds v at p, shared by the corners of p's cell (trilinear weights), to the corners whose
  // z index lies in [k_begin, k_end).
  void splat(const Eigen::Vector3d& p, const Value& v, std::ptrdiff_t k_begin = 0,
             std::ptrdiff_t k_end = std::numeric_limits<std::ptrdiff_t>::max()) {
    std::array<std::ptrdiff_t, 3> c{};
    Eigen::Vector3d f;
    locate(p, c, f);
    for (int corner = 0; corner < 8; ++corner) {
      const int di = corner & 1, dj = (corner >> 1) & 1, dk = (corner >> 2) & 1;
      if (c[2] + dk < k_begin || c[2] + dk >= k_end) continue;
      const double w = (di ? f[0] : 1 - f[0]) * (dj ? f[1] : 1 - f[1]) * (dk ? f[2] : 1 - f[2]);
      value[index(c[0] + di, c[1] + dj, c[2] + dk)] += w * v;
    }
  }
  // splat(item(m)) for m = 0, 1, ... count - 1, on every thread with the bits of that serial loop:
  // the grid is cut into slabs of z, each filled by one task from the items that reach it, in
  // item order, so every cell adds its contributions in the same order whatever the slabs.
  // item(m) gives (position, value) and must be a pure function of m.
  template <class Item>
  void splat_all(std::size_t count, const Item& item) {
    // Each item once (its position, value and z cell), then each slab reads the ones that reach it.
    using Entry = decltype(item(std::size_t{0}));
    std::vector<Entry> items(count);
    std::vector<std::int32_t> slab_of(count);  // the z index of each item's cell
    const tsan::Region region;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 4096),
                      region.wrap([&](const tbb::blocked_range<std::size_t>& range) {
                        for (std::size_t m = range.begin(); m < range.end(); ++m) {
                          items[m] = item(m);
                          std::array<std::ptrdiff_t, 3> c{};
                          Eigen::Vector3d f;
                          locate(items[m].first, c, f);
                          slab_of[m] = static_cast<std::int32_t>(c[2]);
                        }
                      }));
    region.join();
    const std::ptrdiff_t slabs = std::clamp<std::ptrdiff_t>(tbb::this_task_arena::max_concurrency(), 1, n[2]);
    const tsan::Region fill;
    tbb::parallel_for(std::ptrdiff_t{0}, slabs, fill.wrap([&](std::ptrdiff_t s) {
      const std::ptrdiff_t k_begin = n[2] * s / slabs, k_end = n[2] * (s + 1) / slabs;
      for (std::size_t m = 0; m < count; ++m) {
        if (slab_of[m] + 1 < k_begin || slab_of[m] >= k_end) continue;  // its corners lie at k and k + 1
        splat(items[m].first, items[m].second, k_begin, k_end);
      }
    }));
    fill.join();
  }
  Value sample(const Eigen::Vector3d& p) const {
    std::array<std::ptrdiff_t, 3> c{};
    Eigen::Vector3d f;
    locate(p, c, f);
    Value out = Value::Zero();
    for (int corner = 0; corner < 8; ++corner) {
      const int di = corner & 1, dj = (corner >> 1) & 1, dk = (corner >> 2) & 1;
      const double w = (di ? f[0] : 1 - f[0]) * (dj ? f[1] : 1 - f[1]) * (dk ? f[2] : 1 - f[2]);
      out += w * value[index(c[0] + di, c[1] + dj, c[2] + dk)];
    }
    return out;
  }
  // Rows are the grid's lines along x (contiguous); row (j, k) is row j + n[1] k. `need` marks
  // rows. The passes below compute the marked rows, each cell by the one sequence of operations
  // of a 1-D convolution (the same bits whichever rows are computed, and at any thread count),
  // leaving out only cells and terms that are zeros (a zero window gives +0, a zero term adds
  // +0): along x within each row, along y and z a row at a time from a copy of the rows it reads
  // (contiguous, so the loops over x vectorise and the cache is used whole).
  std::size_t row(std::ptrdiff_t j, std::ptrdiff_t k) const { return static_cast<std::size_t>(k * n[1] + j); }
  // [first nonzero cell, last nonzero cell + 1) of the row starting at `first`; [0, 0) if none.
  std::pair<std::size_t, std::size_t> nonzero_extent(std::size_t first) const {
    const auto width = static_cast<std::size_t>(n[0]);
    auto zero = [&](std::size_t i) { return (value[first + i].array() == 0.0).all(); };
    std::size_t from = 0, to = width;
    while (from < width && zero(from)) ++from;
    if (from == width) return {0, 0};
    while (zero(to - 1)) --to;
    return {from, to};
  }
  // The convolution along x of every marked row, zero outside the grid.
  void blur_x(const std::vector<double>& kernel, const std::vector<char>& need) {
    const auto radius = static_cast<std::ptrdiff_t>(kernel.size()) - 1;
    const std::ptrdiff_t len = n[0];
    const tsan::Region region;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, need.size()),
                      region.wrap([&](const tbb::blocked_range<std::size_t>& rows) {
                        std::vector<Value> line(static_cast<std::size_t>(len));
                        std::vector<std::ptrdiff_t> nonzero(static_cast<std::size_t>(len) + 1);  // before t
                        for (std::size_t w = rows.begin(); w < rows.end(); ++w) {
                          const std::size_t first = w * static_cast<std::size_t>(len);
                          if (!need[w]) continue;
                          for (std::ptrdiff_t t = 0; t < len; ++t) {
                            const auto ut = static_cast<std::size_t>(t);
                            line[ut] = value[first + ut];
                            nonzero[ut + 1] = nonzero[ut] + ((line[ut].array() != 0.0).any() ? 1 : 0);
                          }
                          for (std::ptrdiff_t t = 0; t < len; ++t) {
                            const auto lo = static_cast<std::size_t>(std::max<std::ptrdiff_t>(t - radius, 0));
                            const auto hi = static_cast<std::size_t>(std::min(t + radius + 1, len));
                            if (nonzero[hi] == nonzero[lo]) continue;  // zeros blur to zeros
                            Value sum = kernel[0] * line[static_cast<std::size_t>(t)];
                            for (std::ptrdiff_t r = 1; r <= radius; ++r) {
                              const double k = kernel[static_cast<std::size_t>(r)];
                              if (t - r >= 0) sum += k * line[static_cast<std::size_t>(t - r)];
                              if (t + r < len) sum += k * line[static_cast<std::size_t>(t + r)];
                            }
                            value[first + static_cast<std::size_t>(t)] = sum;
                          }
                        }
                      }));
    region.join();
  }
  // The convolution along axis a (1: y, 2: z) of every marked row: per plane across that axis
  // (z = const for y, y = const for z), its rows copied, then each marked output row summed over
  // x in the order of blur_x's cells.
  void blur_across(std::size_t a, const std::vector<double>& kernel, const std::vector<char>& need) {
    const auto radius = static_cast<std::ptrdiff_t>(kernel.size()) - 1;
    const std::ptrdiff_t len = n[a], planes = n[a == 1 ? 2 : 1];
    const auto width = static_cast<std::size_t>(n[0]);
    auto row_at = [&](std::ptrdiff_t t, std::ptrdiff_t plane) { return a == 1 ? row(t, plane) : row(plane, t); };
    const tsan::Region region;
    tbb::parallel_for(
        tbb::blocked_range<std::ptrdiff_t>(0, planes), region.wrap([&](const tbb::blocked_range<std::ptrdiff_t>& ps) {
          std::vector<Value> copy(static_cast<std::size_t>(len) * width);
          std::vector<std::ptrdiff_t> nonzero(static_cast<std::size_t>(len) + 1);  // nonzero rows before t
          std::vector<std::ptrdiff_t> needed(static_cast<std::size_t>(len) + 1);   // needed rows before t
          std::vector<std::pair<std::size_t, std::size_t>> extent(static_cast<std::size_t>(len));  // its nonzeros
          for (std::ptrdiff_t plane = ps.begin(); plane < ps.end(); ++plane) {
            for (std::ptrdiff_t t = 0; t < len; ++t)
              needed[static_cast<std::size_t>(t) + 1] = needed[static_cast<std::size_t>(t)] + need[row_at(t, plane)];
            if (needed[static_cast<std::size_t>(len)] == 0) continue;
            nonzero[0] = 0;
            for (std::ptrdiff_t t = 0; t < len; ++t) {
              const auto ut = static_cast<std::size_t>(t);
              const std::size_t first = row_at(t, plane) * width;
              // A row no needed output reads (none needed within the radius) counts as zero.
              const auto lo = static_cast<std::size_t>(std::max<std::ptrdiff_t>(t - radius, 0));
              const auto hi = static_cast<std::size_t>(std::min(t + radius + 1, len));
              extent[ut] = needed[hi] == needed[lo] ? std::pair<std::size_t, std::size_t>{0, 0} : nonzero_extent(first);
              const bool zero = extent[ut].first == extent[ut].second;
              nonzero[ut + 1] = nonzero[ut] + (zero ? 0 : 1);
              if (!zero)
                std::copy(value.begin() + static_cast<std::ptrdiff_t>(first + extent[ut].first),
                          value.begin() + static_cast<std::ptrdiff_t>(first + extent[ut].second),
                          copy.begin() + static_cast<std::ptrdiff_t>(ut * width + extent[ut].first));
            }
            for (std::ptrdiff_t t = 0; t < len; ++t) {
              const auto lo = static_cast<std::size_t>(std::max<std::ptrdiff_t>(t - radius, 0));
              const auto hi = static_cast<std::size_t>(std::min(t + radius + 1, len));
              if (!need[row_at(t, plane)] || nonzero[hi] == nonzero[lo]) continue;  // zeros blur to zeros
              auto in = [&](std::ptrdiff_t u) {
                const bool zero = nonzero[static_cast<std::size_t>(u) + 1] == nonzero[static_cast<std::size_t>(u)];
                return zero ? nullptr : copy.data() + static_cast<std::size_t>(u) * width;
              };
              // Only the cells in the span of the window's nonzeros can be nonzero; the rest of
              // the row is zero already (its own input lies in that span).
              std::size_t begin = width, end = 0;
              for (std::size_t u = lo; u < hi; ++u) {
                if (extent[u].first == extent[u].second) continue;
                begin = std::min(begin, extent[u].first);
                end = std::max(end, extent[u].second);
              }
              Value* out = value.data() + row_at(t, plane) * width;
              const Value* centre = in(t);
              auto inside = [&](std::ptrdiff_t u, std::size_t i) {  // row u's copy holds cell i
                return extent[static_cast<std::size_t>(u)].first <= i && i < extent[static_cast<std::size_t>(u)].second;
              };
              for (std::size_t i = begin; i < end; ++i)
                out[i] = centre && inside(t, i) ? Value(kernel[0] * centre[i]) : Value(kernel[0] * Value::Zero());
              for (std::ptrdiff_t r = 1; r <= radius; ++r) {
                const double k = kernel[static_cast<std::size_t>(r)];
                // A zero row, or a row's cells outside its nonzeros, add k * 0 = +0: leaving them
                // out gives the same bits.
                for (const std::ptrdiff_t u : {t - r, t + r}) {
                  if (u < 0 || u >= len) continue;
                  if (const Value* row_in = in(u)) {
                    const auto& [from, to] = extent[static_cast<std::size_t>(u)];
                    for (std::size_t i = from; i < to; ++i) out[i] += k * row_in[i];
                  }
                }
              }
            }
          }
        }));
    region.join();
  }
  // The marked rows dilated by `radius` rows along axis a (1: y, 2: z).
  std::vector<char> dilated(const std::vector<char>& marked, std::size_t a, std::ptrdiff_t radius) const {
    std::vector<char> out(marked.size(), 0);
    for (std::ptrdiff_t k = 0; k < n[2]; ++k) {
      for (std::ptrdiff_t j = 0; j < n[1]; ++j) {
        if (!marked[row(j, k)]) continue;
        const std::ptrdiff_t at = a == 1 ? j : k;
        for (std::ptrdiff_t t = std::max<std::ptrdiff_t>(at - radius, 0); t <= std::min(at + radius, n[a] - 1); ++t)
          out[a == 1 ? row(t, k) : row(j, t)] = 1;
      }
    }
    return out;
  }
  // A Gaussian of standard deviation sigma (truncated at 3 sigma), separably along x, y and z,
  // exact at the corners of the cells holding `points` (sample() there reads only those);
  // elsewhere the grid holds what those needed on the way. Each pass computes only the rows the
  // passes after it read: the last the rows of those corners, the one before those rows
  // dilated along z, the first those dilated along y.
  void gaussian_blur(double sigma, const std::vector<Eigen::Vector3d>& points) {
    const auto radius = static_cast<std::size_t>(std::ceil(3.0 * sigma / h));
    std::vector<double> kernel(radius + 1);
    for (std::size_t r = 0; r <= radius; ++r) {
      const double x = static_cast<double>(r) * h / sigma;
      kernel[r] = std::exp(-0.5 * x * x);
    }
    std::vector<char> corners(static_cast<std::size_t>(n[1] * n[2]), 0);
    for (const Eigen::Vector3d& p : points) {
      std::array<std::ptrdiff_t, 3> c{};
      Eigen::Vector3d f;
      locate(p, c, f);
      for (std::ptrdiff_t dk = 0; dk < 2; ++dk) {
        for (std::ptrdiff_t dj = 0; dj < 2; ++dj) corners[row(c[1] + dj, c[2] + dk)] = 1;
      }
    }
    const auto r = static_cast<std::ptrdiff_t>(radius);
    const std::vector<char> before_z = dilated(corners, 2, r), before_y = dilated(before_z, 1, r);
    blur_x(kernel, before_y);
    blur_across(1, kernel, before_z);
    blur_across(2, kernel, corners);
  }
};

using core::for_each_index;

// The largest grid (cells) the smoothing may allocate; beyond it the spacing grows.
constexpr double kMaxCells = 8.0e6;
// blurred_in_space's grid spacing over its sigma.
constexpr double kBlurSpacing = 1.0;
// The finest grid spacing of the normals smoothed from a proxy: 3/4 of the 3 mm normals' sigma.
constexpr double kProxyNormalGridM = 2.25e-3;

// A zeroed grid of spacing `spacing` (coarser past kMaxCells) over the points' box padded by 4 sigma.
template <class Value>
VectorGrid<Value> grid_around(const std::vector<Eigen::Vector3d>& points, double sigma, double spacing) {
  const auto box = bounding_box(points);
  const double pad = 4.0 * sigma;
  const Eigen::Vector3d extent = (box[1] - box[0]).array() + 2.0 * pad;
  double h = spacing;
  const double cells = (extent.array() / h + 2.0).prod();
  if (cells > kMaxCells) h *= std::cbrt(cells / kMaxCells);
  VectorGrid<Value> grid;
  grid.origin = box[0].array() - pad;
  grid.h = h;
  for (std::size_t a = 0; a < 3; ++a)
    grid.n[a] = static_cast<std::ptrdiff_t>(std::ceil(extent[static_cast<int>(a)] / h)) + 2;
  grid.value.assign(static_cast<std::size_t>(grid.n[0] * grid.n[1] * grid.n[2]), Value::Zero());
  return grid;
}

}  // namespace

std::string_view region_name(Region region) {
  switch (region) {
    case Region::apex: return "apex";
    case Region::costal: return "costal";
    case Region::diaphragmatic: return "diaphragmatic";
    case Region::mediastinal: return "mediastinal";
  }
  return "costal";
}

std::optional<Region> region_from_name(std::string_view name) {
  for (Region r : kRegions) {
    if (region_name(r) == name) return r;
  }
  return std::nullopt;
}

std::vector<double> vertex_areas(const TriangleMesh& mesh) {
  std::vector<double> area(mesh.vertices.size(), 0.0);
  const auto& p = mesh.vertices;
  for (const Triangle& t : mesh.triangles) {
    const double a = triangle_area(p[t[0]], p[t[1]], p[t[2]]);
    for (std::uint32_t v : t) area[v] += a / 3.0;
  }
  return area;
}

std::vector<double> mean_curvature(const TriangleMesh& mesh) {
  const auto& p = mesh.vertices;
  std::vector<Eigen::Vector3d> laplacian(p.size(), Eigen::Vector3d::Zero());
  for (const Triangle& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t c = t[static_cast<std::size_t>(k)], a = t[static_cast<std::size_t>((k + 1) % 3)],
                          b = t[static_cast<std::size_t>((k + 2) % 3)];
      const Eigen::Vector3d ea = p[a] - p[c], eb = p[b] - p[c];
      const double sine = ea.cross(eb).norm();
      if (sine == 0.0) continue;
      const double half_cot = 0.5 * ea.dot(eb) / sine;  // the angle at c faces the edge (a, b)
      laplacian[a] += half_cot * (p[b] - p[a]);
      laplacian[b] += half_cot * (p[a] - p[b]);
    }
  }
  const std::vector<double> area = vertex_areas(mesh);
  const std::vector<Eigen::Vector3d> normal = vertex_normals(mesh);
  std::vector<double> h(p.size(), 0.0);
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (area[i] > 0.0) h[i] = -0.5 * laplacian[i].dot(normal[i]) / area[i];
  }
  return h;
}

namespace {
// smoothed_normals() of `surface` at `points`; `fallback()` gives the normals to keep where the
// blurred field vanishes (computed only then).
// `spacing`: the grid's, over sigma; the Gaussian on it narrowed so that its variance with the
// trilinear splat's and sample's (h^2 / 6 each) is sigma^2 when `matched`, as blurred_in_space's.
template <class Fallback>
std::vector<Eigen::Vector3d> smoothed_normals_of(const TriangleMesh& surface, double sigma,
                                                 const std::vector<Eigen::Vector3d>& points, const Fallback& fallback,
                                                 double spacing = 0.5, bool matched = false) {
  auto grid = grid_around<Eigen::Vector3d>(points, sigma, spacing * sigma);
  const auto& p = surface.vertices;
  grid.splat_all(surface.triangles.size(), [&](std::size_t m) {
    const Triangle& t = surface.triangles[m];
    const Eigen::Vector3d area_vector = 0.5 * (p[t[1]] - p[t[0]]).cross(p[t[2]] - p[t[0]]);
    return std::pair<Eigen::Vector3d, Eigen::Vector3d>((p[t[0]] + p[t[1]] + p[t[2]]) / 3.0, area_vector);
  });
  grid.gaussian_blur(matched ? std::sqrt(std::max(sigma * sigma - grid.h * grid.h / 3.0, 0.25 * sigma * sigma)) : sigma,
                     points);

  std::vector<Eigen::Vector3d> blurred(points.size());
  for_each_index(points.size(), [&](std::size_t i) { blurred[i] = grid.sample(points[i]); });
  double largest = 0.0;
  for (const Eigen::Vector3d& b : blurred) largest = std::max(largest, b.norm());
  // The fallback only where the blurred field vanishes (rare: computed only then).
  std::vector<char> vanishes(points.size(), 0);
  for_each_index(points.size(), [&](std::size_t i) {
    const double len = blurred[i].norm();
    if (len > 1e-9 * largest) blurred[i] /= len;
    else vanishes[i] = 1;
  });
  if (std::find(vanishes.begin(), vanishes.end(), 1) != vanishes.end()) {
    const std::vector<Eigen::Vector3d> normal = fallback();
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (vanishes[i]) blurred[i] = normal[i];
    }
  }
  return blurred;
}
}  // namespace

std::vector<Eigen::Vector3d> smoothed_normals(const TriangleMesh& mesh, double sigma) {
  if (!(sigma > 0.0) || !std::isfinite(sigma)) throw ValueError("smoothed_normals: sigma must be positive");
  if (mesh.vertices.empty() || mesh.triangles.empty()) return vertex_normals(mesh);
  return smoothed_normals_of(mesh, sigma, mesh.vertices, [&] { return vertex_normals(mesh); });
}

std::vector<Eigen::Vector3d> smoothed_normals(const TriangleMesh& mesh, const SurfaceProxy* proxy, double sigma) {
  if (!proxy) return smoothed_normals(mesh, sigma);
  if (!(sigma > 0.0) || !std::isfinite(sigma)) throw ValueError("smoothed_normals: sigma must be positive");
  if (proxy->group.size() != mesh.vertices.size()) throw ValueError("smoothed_normals: a proxy of another mesh");
  if (proxy->mesh.triangles.empty()) return vertex_normals(mesh);
  // The grid no finer than kProxyNormalGridM (the proxy's triangles are 2-3 mm wide: a finer grid
  // resolves nothing more of them), with the variance matched where that is coarser than
  // sigma / 2: the 3 mm normals' grid has a third of its cells (it was a fifth of the tissue's
  // cost at 85k vertices); at 10 and 20 mm the grid of smoothed_normals().
  const double h = std::max(0.5 * sigma, kProxyNormalGridM);
  return smoothed_normals_of(
      proxy->mesh, sigma, mesh.vertices, [&] { return vertex_normals(mesh); }, h / sigma, h > 0.5 * sigma);
}

namespace {
// Each column of `value` (a value per vertex) blurred in space at `sigma`, weighted by `area`:
// one grid of (area x value..., area). The column sums are those of a grid of (area x value,
// area) per column, to the bit: the same splat order and weights, and the blur leaves out the
// same zero cells (a cell is zero where its area is, whatever the values).
template <int K>
std::vector<Eigen::Matrix<double, K, 1>> blurred_columns(const TriangleMesh& mesh, const std::vector<double>& area,
                                                         const std::vector<Eigen::Matrix<double, K, 1>>& value,
                                                         double sigma) {
  if (!(sigma > 0.0) || !std::isfinite(sigma)) throw ValueError("blurred_in_space: sigma must be positive");
  if (value.size() != mesh.vertices.size()) throw ValueError("blurred_in_space: one value per vertex");
  if (area.size() != mesh.vertices.size()) throw ValueError("blurred_in_space: one area per vertex");
  if (value.empty()) return {};
  using Weighted = Eigen::Matrix<double, K + 1, 1>;
  // A grid of spacing sigma, and a narrower Gaussian on it: the trilinear splat and the trilinear
  // sample each add h^2 / 6 to the variance on average, so a Gaussian of variance
  // sigma^2 - h^2 / 3 gives sigma^2 in all. On the grid of spacing sigma / 2 the same sum cost
  // 8x the cells and 2x the taps per cell, the largest fixed cost of the realistic tissue (#50).
  auto grid = grid_around<Weighted>(mesh.vertices, sigma, kBlurSpacing * sigma);
  grid.splat_all(value.size(), [&](std::size_t i) {
    Weighted weighted;
    for (int c = 0; c < K; ++c) weighted[c] = area[i] * value[i][c];
    weighted[K] = area[i];
    return std::pair<Eigen::Vector3d, Weighted>(mesh.vertices[i], weighted);
  });
  grid.gaussian_blur(std::sqrt(std::max(sigma * sigma - grid.h * grid.h / 3.0, 0.25 * sigma * sigma)), mesh.vertices);
  std::vector<Eigen::Matrix<double, K, 1>> out(value.size());
  for_each_index(value.size(), [&](std::size_t i) {
    const Weighted s = grid.sample(mesh.vertices[i]);
    for (int c = 0; c < K; ++c) out[i][c] = s[K] > 0.0 ? s[c] / s[K] : value[i][c];
  });
  return out;
}
}  // namespace

std::vector<double> blurred_in_space(const TriangleMesh& mesh, const std::vector<double>& value, double sigma) {
  if (!(sigma > 0.0) || !std::isfinite(sigma)) throw ValueError("blurred_in_space: sigma must be positive");
  if (value.size() != mesh.vertices.size()) throw ValueError("blurred_in_space: one value per vertex");
  std::vector<Eigen::Matrix<double, 1, 1>> column(value.size());
  for (std::size_t i = 0; i < value.size(); ++i) column[i][0] = value[i];
  const auto blurred = blurred_columns<1>(mesh, vertex_areas(mesh), column, sigma);
  std::vector<double> out(value.size());
  for (std::size_t i = 0; i < value.size(); ++i) out[i] = blurred[i][0];
  return out;
}

std::vector<Eigen::Vector2d> blurred_in_space(const TriangleMesh& mesh, const std::vector<double>& area,
                                              const std::vector<Eigen::Vector2d>& value, double sigma) {
  return blurred_columns<2>(mesh, area, value, sigma);
}

std::vector<Eigen::Vector3d> blurred_in_space(const TriangleMesh& mesh, const std::vector<double>& area,
                                              const std::vector<Eigen::Vector3d>& value, double sigma) {
  return blurred_columns<3>(mesh, area, value, sigma);
}

std::vector<Eigen::Vector3d> hull_proxy_points(const std::vector<Eigen::Vector3d>& points, double cell) {
  if (!(cell > 0.0) || points.empty()) return points;
  const auto box = bounding_box(points);
  const Eigen::Vector3d extent = box[1] - box[0];
  constexpr double kMaxProxyCells = 2.0e6;  // 32 MB of grid at most
  double h = cell;
  const double cells = (extent.array() / h + 1.0).prod();
  if (cells > kMaxProxyCells) h *= std::cbrt(cells / kMaxProxyCells);
  std::array<std::size_t, 3> n{};
  for (std::size_t a = 0; a < 3; ++a) n[a] = static_cast<std::size_t>(extent[static_cast<int>(a)] / h) + 1;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  // Per cell the index of its farthest point (4 bytes a cell: the grid is the cost at 10^5 points).
  constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
  if (points.size() >= kNone) throw ValueError("hull_proxy_points: too many points");
  std::vector<std::uint32_t> best(n[0] * n[1] * n[2], kNone);
  for (std::size_t i = 0; i < points.size(); ++i) {
    std::array<std::size_t, 3> c{};
    for (std::size_t a = 0; a < 3; ++a) {
      const auto ia = static_cast<int>(a);
      c[a] = std::min(n[a] - 1, static_cast<std::size_t>((points[i][ia] - box[0][ia]) / h));
    }
    const std::size_t k = (c[2] * n[1] + c[1]) * n[0] + c[0];
    // strictly: the lowest index keeps a tie
    if (best[k] == kNone || (points[i] - mean).squaredNorm() > (points[best[k]] - mean).squaredNorm())
      best[k] = static_cast<std::uint32_t>(i);
  }
  std::vector<Eigen::Vector3d> kept;
  for (const std::uint32_t k : best) {
    if (k != kNone) kept.push_back(points[k]);
  }
  return kept;
}

SurfaceRegions find_regions(const TriangleMesh& mesh, const RegionOptions& o, const SurfaceProxy* proxy) {
  if (mesh.vertices.empty() || mesh.triangles.empty()) throw ValueError("find_regions: empty mesh");
  if (!(o.axes.up.norm() > 0.0 && o.axes.anterior.norm() > 0.0) ||
      std::abs(o.axes.up.normalized().dot(o.axes.anterior.normalized())) > 1e-6)
    throw ValueError("find_regions: up and anterior must be non-zero and at right angles");
  SurfaceRegions r;
  r.axes.up = o.axes.up.normalized();
  r.axes.anterior = o.axes.anterior.normalized();
  const Eigen::Vector3d up = r.axes.up, left = r.axes.left();
  const std::size_t n = mesh.vertices.size();
  // The side's hull (below) needs only the vertices: it is built beside the smoothed normals.
  std::vector<Eigen::Vector3d> normal;
  std::unique_ptr<ConvexHullDepth> hull;
  {
    const tsan::Region region;
    tbb::parallel_invoke(
        region.wrap([&] { normal = smoothed_normals(mesh, proxy, o.classification_length_m); }), region.wrap([&] {
          hull = std::make_unique<ConvexHullDepth>(hull_proxy_points(mesh.vertices, o.hull_proxy_cell_m));
        }));
    region.join();
  }

  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const auto& v : mesh.vertices) {
    lo = std::min(lo, v.dot(up));
    hi = std::max(hi, v.dot(up));
  }
  r.height.resize(n);
  for (std::size_t i = 0; i < n; ++i) r.height[i] = hi > lo ? (mesh.vertices[i].dot(up) - lo) / (hi - lo) : 0.0;

  // The side: the mean depth below the convex hull of the face toward the patient's left and of
  // the face toward the right (steep faces only: |n.left| > 0.5 and |n.up| < 0.7), in the middle
  // of the height (the base's dome is concave on both sides). The deeper, concave one is medial.
  // A mean needs no more than a sample: at most options.side_sample of those vertices, every k-th in index
  // order (a depth query deep inside costs 10-80 us; 20,000 of them were a third of the tissue's
  // cost, and the margins are 15 mm on CT lungs, 0.16 mm against 0 on the phantom). The hull is
  // the hull of a coarse proxy of the surface (options.hull_proxy_cell_m): on a fine mesh nearly
  // every vertex is a hull corner, and quickhull over 10^6 of them took seconds.
  std::vector<std::size_t> steep;
  for (std::size_t i = 0; i < n; ++i) {
    if (std::abs(normal[i].dot(up)) < 0.7 && r.height[i] >= 0.25 && r.height[i] <= 0.85 &&
        std::abs(normal[i].dot(left)) > 0.5)
      steep.push_back(i);
  }
  const std::size_t stride = (steep.size() + o.side_sample - 1) / std::max<std::size_t>(o.side_sample, 1);
  std::vector<std::size_t> sample;
  std::vector<Eigen::Vector3d> queries;
  for (std::size_t k = 0; k < steep.size(); k += std::max<std::size_t>(stride, 1)) {
    sample.push_back(steep[k]);
    queries.push_back(mesh.vertices[steep[k]]);
  }
  const std::vector<double> depth = hull->depth(queries);
  const std::vector<double> area = vertex_areas(mesh);
  double sum_left = 0.0, area_left = 0.0, sum_right = 0.0, area_right = 0.0;
  for (std::size_t k = 0; k < sample.size(); ++k) {
    const std::size_t i = sample[k];
    if (normal[i].dot(left) > 0.5) {
      sum_left += depth[k] * area[i];
      area_left += area[i];
    } else {
      sum_right += depth[k] * area[i];
      area_right += area[i];
    }
  }
  r.left_face_depth = area_left > 0.0 ? sum_left / area_left : 0.0;
  r.right_face_depth = area_right > 0.0 ? sum_right / area_right : 0.0;
  // A right lung's medial face looks to the patient's left.
  r.side = o.side.value_or(r.left_face_depth > r.right_face_depth ? Lung::right : Lung::left);
  r.medial = r.side == Lung::right ? left : Eigen::Vector3d(-left);

  r.normal = normal;
  r.weight.resize(n);
  r.label.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double down = -normal[i].dot(up);
    const double wd =
        ramp(down, o.diaphragm_cos, o.transition) * (1.0 - ramp(r.height[i], o.diaphragm_height, o.height_transition));
    const double wa = (1.0 - wd) * ramp(r.height[i], o.apex_height, o.height_transition);
    const double wm = (1.0 - wd - wa) * ramp(normal[i].dot(r.medial), o.medial_cos, o.transition);
    const double wc = std::max(0.0, 1.0 - wd - wa - wm);
    auto& w = r.weight[i];
    w[static_cast<std::size_t>(Region::apex)] = wa;
    w[static_cast<std::size_t>(Region::costal)] = wc;
    w[static_cast<std::size_t>(Region::diaphragmatic)] = wd;
    w[static_cast<std::size_t>(Region::mediastinal)] = wm;
    std::size_t best = 0;
    for (std::size_t k = 1; k < kRegionCount; ++k) {
      if (w[k] > w[best]) best = k;
    }
    r.label[i] = static_cast<Region>(best);
  }
  return r;
}

void require_regions_of(const SurfaceRegions& regions, const TriangleMesh& mesh, const BodyAxes& frame,
                        const char* who) {
  if (regions.label.size() != mesh.vertices.size() || regions.weight.size() != mesh.vertices.size() ||
      !regions.axes.up.isApprox(frame.up.normalized()) || !regions.axes.anterior.isApprox(frame.anterior.normalized()))
    throw ValueError(std::string(who) + ": the regions given are of another surface or body frame");
}

std::vector<bool> dome_top_vertices(const TriangleMesh& mesh, const SurfaceRegions& regions, double depth_m) {
  constexpr double kDomeCos = 0.8660254037844387;  // cos 30 degrees
  const std::size_t n = mesh.vertices.size();
  if (regions.label.size() != n) throw ValueError("dome_top_vertices: one region label per vertex");
  const Eigen::Vector3d up = regions.axes.up;
  auto on_dome = [&](std::size_t i) {
    return regions.label[i] == Region::diaphragmatic &&
           (regions.normal.size() != n || -regions.normal[i].dot(up) >= kDomeCos);
  };
  double top = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < n; ++i) {
    if (on_dome(i)) top = std::max(top, mesh.vertices[i].dot(up));
  }
  std::vector<bool> on_top(n, false);
  for (std::size_t i = 0; i < n; ++i) on_top[i] = on_dome(i) && mesh.vertices[i].dot(up) >= top - depth_m;
  return on_top;
}

namespace {
// The horizontal distance from the dome's centre within which the diaphragm (vertex area times
// its diaphragmatic weight) covers `target_m2`; infinite when the whole diaphragm is smaller.
template <class Distance>
double dome_radius_for_area(std::size_t n, const std::vector<double>& area, const SurfaceRegions& regions,
                            const Distance& distance, double target_m2) {
  constexpr auto kDiaphragm = static_cast<std::size_t>(Region::diaphragmatic);
  std::vector<std::pair<double, double>> by_distance;  // (distance, diaphragmatic area)
  for (std::size_t i = 0; i < n; ++i) {
    const double a = area[i] * regions.weight[i][kDiaphragm];
    if (a > 0.0) by_distance.emplace_back(distance(i), a);
  }
  std::sort(by_distance.begin(), by_distance.end());
  double covered = 0.0;
  for (const auto& [d, a] : by_distance) {
    covered += a;
    if (covered >= target_m2) return d;
  }
  return std::numeric_limits<double>::infinity();
}
}  // namespace

std::vector<double> regional_load(const TriangleMesh& mesh, const SurfaceRegions& regions,
                                  const std::array<double, kRegionCount>& load, const DomeLoad& dome) {
  if (!(dome.radius_m >= 0.0)) throw ValueError("regional_load: the dome radius must be >= 0");
  if (!(dome.area_m2 >= 0.0)) throw ValueError("regional_load: the dome area must be >= 0");
  if (!(dome.falloff_m > 0.0)) throw ValueError("regional_load: the dome's falloff must be > 0");
  if (!(dome.rim >= 0.0 && dome.rim <= 1.0)) throw ValueError("regional_load: the dome rim factor must lie in [0, 1]");
  const std::size_t n = regions.weight.size();
  if (mesh.vertices.size() != n) throw ValueError("regional_load: one region weight per vertex");
  const Eigen::Vector3d up = regions.axes.up;
  constexpr auto kDiaphragm = static_cast<std::size_t>(Region::diaphragmatic);
  // The diaphragm's drive before the dome profile: its weight times how far its normal points down.
  std::vector<double> drive(n);
  for (std::size_t i = 0; i < n; ++i)
    drive[i] = regions.weight[i][kDiaphragm] * std::max(0.0, -regions.normal[i].dot(up));
  if (dome.radius_m > 0.0 || dome.area_m2 > 0.0) {
    const std::vector<bool> on_top = dome_top_vertices(mesh, regions);
    const std::vector<double> area = vertex_areas(mesh);
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    double top_area = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      if (!on_top[i]) continue;
      centre += area[i] * mesh.vertices[i];
      top_area += area[i];
    }
    if (top_area > 0.0) centre /= top_area;
    auto horizontal_distance = [&](std::size_t i) {
      const Eigen::Vector3d r = mesh.vertices[i] - centre;
      return (r - r.dot(up) * up).norm();
    };
    const double radius = dome.area_m2 > 0.0 && top_area > 0.0
                              ? dome_radius_for_area(n, area, regions, horizontal_distance, dome.area_m2)
                              : dome.radius_m;
    if (top_area > 0.0 && std::isfinite(radius)) {
      // The profile moves the drive toward the dome and keeps its total (so the diaphragm's share
      // of the volume stays what the regional loads make it).
      double before = 0.0, after = 0.0;
      for (std::size_t i = 0; i < n; ++i) {
        const double profile =
            dome.rim + (1.0 - dome.rim) * (1.0 - ramp(horizontal_distance(i), radius, dome.falloff_m));
        before += area[i] * drive[i];
        drive[i] *= profile;
        after += area[i] * drive[i];
      }
      if (after > 0.0) {
        for (double& d : drive) d *= before / after;
      }
    }
  }
  std::vector<double> f(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t k = 0; k < kRegionCount; ++k)
      f[i] += load[k] * (k == kDiaphragm ? drive[i] : regions.weight[i][k]);
  }
  return f;
}

std::vector<Eigen::Vector3d> anatomical_directions(const TriangleMesh& mesh, const SurfaceRegions& regions,
                                                   double sigma) {
  return anatomical_directions(mesh, regions, smoothed_normals(mesh, sigma));
}

std::vector<Eigen::Vector3d> anatomical_directions(const TriangleMesh& mesh, const SurfaceRegions& regions,
                                                   const std::vector<Eigen::Vector3d>& normal) {
  if (normal.size() != mesh.vertices.size() || regions.weight.size() != mesh.vertices.size())
    throw ValueError("anatomical_directions: one smoothed normal and one region weight per vertex");
  const Eigen::Vector3d up = regions.axes.up;
  std::vector<Eigen::Vector3d> d(normal.size());
  for (std::size_t i = 0; i < normal.size(); ++i) {
    const auto& w = regions.weight[i];
    Eigen::Vector3d horizontal = normal[i] - normal[i].dot(up) * up;
    const double len = horizontal.norm();
    horizontal = len > 1e-6 ? Eigen::Vector3d(horizontal / len) : normal[i];
    Eigen::Vector3d v =
        (w[static_cast<std::size_t>(Region::apex)] + w[static_cast<std::size_t>(Region::mediastinal)]) * normal[i] +
        w[static_cast<std::size_t>(Region::costal)] * horizontal -
        w[static_cast<std::size_t>(Region::diaphragmatic)] * up;
    const double vl = v.norm();
    d[i] = vl > 1e-9 ? Eigen::Vector3d(v / vl) : normal[i];
  }
  return d;
}

}  // namespace pneuma::mesh
