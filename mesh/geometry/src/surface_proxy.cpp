#include "pneuma/mesh/geometry/surface_proxy.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>

#include "pneuma/core/error.h"
#include "pneuma/core/parallel.h"
#include "pneuma/mesh/geometry/vertex_neighbours.h"

namespace pneuma::mesh {
namespace {

// The direction a unit normal faces most: 0..5 for +x, -x, +y, -y, +z, -z (0 for a zero normal).
std::uint32_t facing(const Eigen::Vector3d& n) {
  Eigen::Index axis = 0;
  n.cwiseAbs().maxCoeff(&axis);
  return static_cast<std::uint32_t>(2 * axis) + (n[axis] < 0.0 ? 1U : 0U);
}

// The triangle turned so that its lowest corner comes first (the same orientation): two
// triangles of the same corners and orientation compare equal.
Triangle turned_lowest_first(const Triangle& t) {
  const std::size_t k = t[0] < t[1] ? (t[0] < t[2] ? 0 : 2) : (t[1] < t[2] ? 1 : 2);
  return {t[k], t[(k + 1) % 3], t[(k + 2) % 3]};
}

}  // namespace

double mean_edge_length(const TriangleMesh& mesh) {
  if (mesh.triangles.empty()) return 0.0;
  const auto& p = mesh.vertices;
  double sum = 0.0;
  for (const Triangle& t : mesh.triangles)
    sum += (p[t[0]] - p[t[1]]).norm() + (p[t[1]] - p[t[2]]).norm() + (p[t[2]] - p[t[0]]).norm();
  return sum / (3.0 * static_cast<double>(mesh.triangles.size()));
}

SurfaceProxy surface_proxy(const TriangleMesh& mesh, double cell_m) {
  if (!(cell_m > 0.0) || !std::isfinite(cell_m)) throw ValueError("surface_proxy: the cell must be positive");
  if (mesh.vertices.empty() || mesh.triangles.empty()) throw ValueError("surface_proxy: empty mesh");
  const std::size_t n = mesh.vertices.size();
  const auto box = bounding_box(mesh.vertices);
  const Eigen::Vector3d extent = box[1] - box[0];
  constexpr double kMaxCells = 16777216.0;  // 2^24: 64 MB of group ids with the six facings
  double h = cell_m;
  const double cells = (extent.array() / h + 1.0).prod();
  if (cells > kMaxCells) h *= std::cbrt(cells / kMaxCells);
  std::array<std::size_t, 3> count{};
  for (std::size_t a = 0; a < 3; ++a) count[a] = static_cast<std::size_t>(extent[static_cast<int>(a)] / h) + 1;
  const std::vector<Eigen::Vector3d> normal = vertex_normals(mesh);
  // Each vertex's key (cell, facing), on every thread; then the groups numbered serially in vertex order.
  std::vector<std::uint32_t> key(n);
  core::for_each_index(n, [&](std::size_t i) {
    std::array<std::size_t, 3> c{};
    for (std::size_t a = 0; a < 3; ++a) {
      const auto ia = static_cast<int>(a);
      c[a] = std::min(count[a] - 1, static_cast<std::size_t>((mesh.vertices[i][ia] - box[0][ia]) / h));
    }
    key[i] = static_cast<std::uint32_t>(((c[2] * count[1] + c[1]) * count[0] + c[0]) * 6 + facing(normal[i]));
  });
  constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> group_of_key(count[0] * count[1] * count[2] * 6, kNone);
  SurfaceProxy proxy;
  proxy.cell_m = h;
  proxy.group.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint32_t& g = group_of_key[key[i]];
    if (g == kNone) {
      g = static_cast<std::uint32_t>(proxy.fine_vertex.size());
      proxy.fine_vertex.push_back(static_cast<std::uint32_t>(i));
      proxy.mesh.vertices.push_back(mesh.vertices[i]);
    }
    proxy.group[i] = g;
  }
  // The triangles between three groups, each (corners and orientation) once, in triangle order.
  std::vector<std::pair<Triangle, std::uint32_t>> kept;  // (turned lowest first, first triangle)
  for (std::size_t m = 0; m < mesh.triangles.size(); ++m) {
    const Triangle& t = mesh.triangles[m];
    const Triangle g{proxy.group[t[0]], proxy.group[t[1]], proxy.group[t[2]]};
    if (g[0] == g[1] || g[1] == g[2] || g[2] == g[0]) continue;
    kept.emplace_back(turned_lowest_first(g), static_cast<std::uint32_t>(m));
  }
  std::sort(kept.begin(), kept.end());
  kept.erase(std::unique(kept.begin(), kept.end(), [](const auto& a, const auto& b) { return a.first == b.first; }),
             kept.end());
  std::sort(kept.begin(), kept.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
  proxy.mesh.triangles.reserve(kept.size());
  for (const auto& [t, m] : kept) {
    const Triangle& fine = mesh.triangles[m];
    proxy.mesh.triangles.push_back({proxy.group[fine[0]], proxy.group[fine[1]], proxy.group[fine[2]]});
  }
  return proxy;
}

std::shared_ptr<const SurfaceProxy> proxy_for(const TriangleMesh& mesh) {
  if (mesh.triangles.empty() || !(mean_edge_length(mesh) < kProxyBelowEdgeM)) return nullptr;
  return std::make_shared<const SurfaceProxy>(surface_proxy(mesh, kProxyCellM));
}

std::vector<Eigen::Vector3d> transferred_to_fine(const TriangleMesh& fine, const SurfaceProxy& proxy,
                                                 const std::vector<Eigen::Vector3d>& on_proxy) {
  if (on_proxy.size() != proxy.mesh.vertices.size())
    throw ValueError("transferred_to_fine: one value per proxy vertex");
  if (proxy.group.size() != fine.vertices.size()) throw ValueError("transferred_to_fine: a proxy of another mesh");
  const VertexNeighbours around(proxy.mesh);
  // (1 - d^2 / R^2)^2 within R = 2 cells (a group's vertex lies within a cell's diagonal, 1.7
  // cells): a bell of about a cell's width without an exponential per neighbour (the Gaussian's
  // exp was 2.4 % of the realistic field at 1M vertices).
  const double inverse = 1.0 / (4.0 * proxy.cell_m * proxy.cell_m);
  auto bell = [inverse](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    const double t = std::max(0.0, 1.0 - (a - b).squaredNorm() * inverse);
    return t * t;
  };
  std::vector<Eigen::Vector3d> out(fine.vertices.size());
  core::for_each_index(out.size(), [&](std::size_t i) {
    const Eigen::Vector3d& x = fine.vertices[i];
    const std::uint32_t g = proxy.group[i];
    double weight = bell(proxy.mesh.vertices[g], x);
    Eigen::Vector3d sum = weight * on_proxy[g];
    for (const std::uint32_t j : around(g)) {
      const double w = bell(proxy.mesh.vertices[j], x);
      sum += w * on_proxy[j];
      weight += w;
    }
    out[i] = weight > 0.0 ? Eigen::Vector3d(sum / weight) : on_proxy[g];
  });
  return out;
}

}  // namespace pneuma::mesh
