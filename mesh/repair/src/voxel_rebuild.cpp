// rebuild_through_voxels(): even-odd scan conversion of a closed surface, then the label-map
// pipeline. Plain C++ (no CGAL here; Mesh_3 runs inside surface_from_labels).
#include "voxel_rebuild.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "pneuma/core/tsan.h"

namespace pneuma::mesh::detail {
namespace {

constexpr double kMaxVoxels = 40e6;
// Ray offsets, in voxels: small, and far from any ratio a mesh built on a grid would have.
constexpr double kRowOffsetY = 1e-4 * 0.3183098861837907, kRowOffsetZ = 1e-4 * 0.5772156649015329;

}  // namespace

double rebuild_edge_for(const TriangleMesh& mesh) {
  const auto edges = unique_edges(mesh.triangles);
  double total = 0.0;
  for (const auto& e : edges) total += (mesh.vertices[e[1]] - mesh.vertices[e[0]]).norm();
  const double mean = edges.empty() ? 0.0 : total / static_cast<double>(edges.size());
  const auto box = bounding_box(mesh.vertices);
  return std::min(mean, (box[1] - box[0]).norm() / 32.0);
}

VoxelRebuild rebuild_through_voxels(const TriangleMesh& mesh, const std::string& name, double edge_m) {
  VoxelRebuild out;
  if (mesh.triangles.empty() || !(edge_m > 0.0)) return out;
  const auto box = bounding_box(mesh.vertices);
  const Eigen::Vector3d extent = box[1] - box[0];
  double h = edge_m / 2.0;
  std::array<std::size_t, 3> n{};
  for (;; h *= 1.25) {  // coarsen until the grid fits
    for (int a = 0; a < 3; ++a) n[static_cast<std::size_t>(a)] = static_cast<std::size_t>(std::ceil(extent[a] / h)) + 4;
    if (static_cast<double>(n[0]) * static_cast<double>(n[1]) * static_cast<double>(n[2]) <= kMaxVoxels) break;
  }
  out.voxel_m = h;
  out.edge_m = std::max(edge_m, 2.0 * h);
  // Voxel (0,0,0)'s centre: centres half a voxel off the bounding box's planes, where the flat
  // faces of a surface built on a grid lie.
  const Eigen::Vector3d origin = box[0] - Eigen::Vector3d::Constant(1.5 * h);

  // Each triangle is listed under the rows (j, k) whose ray its y-z bounds may contain.
  const std::size_t row_count = n[1] * n[2];
  auto row_of = [&](double coordinate, double offset, int axis) {
    return (coordinate - origin[axis]) / h - offset;  // in row units
  };
  std::vector<std::size_t> first(row_count + 1, 0);
  std::vector<std::array<std::size_t, 4>> spans(mesh.triangle_count());  // j0, j1, k0, k1 (inclusive, or empty)
  for (std::size_t f = 0; f < mesh.triangle_count(); ++f) {
    constexpr double inf = std::numeric_limits<double>::infinity();
    double lo[2] = {inf, inf}, hi[2] = {-inf, -inf};
    for (std::uint32_t v : mesh.triangles[f]) {
      for (int a = 0; a < 2; ++a) {
        const double r = row_of(mesh.vertices[v][a + 1], a == 0 ? kRowOffsetY : kRowOffsetZ, a + 1);
        lo[a] = std::min(lo[a], r);
        hi[a] = std::max(hi[a], r);
      }
    }
    // Row indices as doubles, clamped to the grid (the grid holds the whole surface anyway).
    const double j0 = std::max(0.0, std::ceil(lo[0])), j1 = std::min(static_cast<double>(n[1] - 1), std::floor(hi[0]));
    const double k0 = std::max(0.0, std::ceil(lo[1])), k1 = std::min(static_cast<double>(n[2] - 1), std::floor(hi[1]));
    if (!(j0 <= j1 && k0 <= k1)) {
      spans[f] = {1, 0, 1, 0};  // empty
      continue;
    }
    spans[f] = {static_cast<std::size_t>(j0), static_cast<std::size_t>(j1), static_cast<std::size_t>(k0),
                static_cast<std::size_t>(k1)};
    for (std::size_t k = spans[f][2]; k <= spans[f][3]; ++k)
      for (std::size_t j = spans[f][0]; j <= spans[f][1]; ++j) ++first[j + n[1] * k + 1];
  }
  for (std::size_t r = 0; r < row_count; ++r) first[r + 1] += first[r];
  std::vector<std::uint32_t> listed(first.back());
  {
    std::vector<std::size_t> next(first.begin(), first.end() - 1);
    for (std::size_t f = 0; f < mesh.triangle_count(); ++f) {
      const auto [j0, j1, k0, k1] = spans[f];
      if (j0 > j1 || k0 > k1) continue;
      for (std::size_t k = k0; k <= k1; ++k)
        for (std::size_t j = j0; j <= j1; ++j) listed[next[j + n[1] * k]++] = static_cast<std::uint32_t>(f);
    }
  }

  image::LabelMap map;
  map.size = n;
  map.transform_source = "voxelized surface";
  map.ijk_to_lps.topLeftCorner<3, 3>() = Eigen::Matrix3d::Identity() * h;
  map.ijk_to_lps.topRightCorner<3, 1>() = origin;
  map.labels.assign(map.voxel_count(), 0);
  std::vector<char> row_meets(row_count, 0), row_odd(row_count, 0);
  // Rows are independent and each writes its own voxels: the same bits at any thread count.
  const tsan::Region region;
  tbb::parallel_for(std::size_t{0}, row_count, region.wrap([&](std::size_t r) {
    const std::size_t j = r % n[1], k = r / n[1];
    const double y = origin.y() + (static_cast<double>(j) + kRowOffsetY) * h;
    const double z = origin.z() + (static_cast<double>(k) + kRowOffsetZ) * h;
    std::vector<double> crossings;
    for (std::size_t at = first[r]; at < first[r + 1]; ++at) {
      const Triangle& t = mesh.triangles[listed[at]];
      const Eigen::Vector3d &a = mesh.vertices[t[0]], &b = mesh.vertices[t[1]], &c = mesh.vertices[t[2]];
      // Barycentric coordinates of (y, z) in the triangle's projection on the y-z plane.
      const double d = (b.y() - a.y()) * (c.z() - a.z()) - (c.y() - a.y()) * (b.z() - a.z());
      if (d == 0.0) continue;  // seen edge-on: the ray grazes it (measure zero after the offset)
      const double wb = ((y - a.y()) * (c.z() - a.z()) - (c.y() - a.y()) * (z - a.z())) / d;
      const double wc = ((b.y() - a.y()) * (z - a.z()) - (y - a.y()) * (b.z() - a.z())) / d;
      const double wa = 1.0 - wb - wc;
      if (wa < 0.0 || wb < 0.0 || wc < 0.0) continue;
      crossings.push_back(wa * a.x() + wb * b.x() + wc * c.x());
    }
    if (crossings.empty()) return;
    row_meets[r] = 1;
    if (crossings.size() % 2 != 0) {
      row_odd[r] = 1;
      return;
    }
    std::sort(crossings.begin(), crossings.end());
    std::int32_t* row = map.labels.data() + n[0] * r;
    for (std::size_t m = 0; m + 1 < crossings.size(); m += 2) {
      // Voxel centres x_i = origin.x + i h strictly between an entry and its exit.
      const double from = std::ceil((crossings[m] - origin.x()) / h),
                   to = std::floor((crossings[m + 1] - origin.x()) / h);
      for (double i = std::max(from, 0.0); i <= std::min(to, static_cast<double>(n[0] - 1)); i += 1.0)
        row[static_cast<std::size_t>(i)] = 1;
    }
  }));
  region.join();
  out.rows = static_cast<std::size_t>(std::count(row_meets.begin(), row_meets.end(), 1));
  out.odd_rows = static_cast<std::size_t>(std::count(row_odd.begin(), row_odd.end(), 1));
  if (out.rows == 0 || static_cast<double>(out.odd_rows) > 0.01 * static_cast<double>(out.rows)) return out;
  if (std::find(map.labels.begin(), map.labels.end(), 1) == map.labels.end()) return out;

  LabelSurfaceOptions options;
  options.edge_length_m = out.edge_m;
  options.smoothing_m = h;  // one voxel: the staircase goes, features of a few voxels stay
  options.closing_radius_m = 1.5 * h;
  options.max_closing_radius_m = std::max(options.max_closing_radius_m, 8.0 * h);
  LabelSurface surface = surface_from_labels(map, name, {1}, options);
  out.mesh = std::move(surface.mesh);
  out.report = std::move(surface.report);
  return out;
}

namespace {

// Vertex-connected components: each one's triangles, in input order.
std::vector<std::vector<std::size_t>> components_of(const TriangleMesh& mesh) {
  std::vector<std::uint32_t> component;
  std::vector<std::vector<std::size_t>> groups(face_components(mesh, component));
  for (std::size_t f = 0; f < component.size(); ++f) groups[component[f]].push_back(f);
  return groups;
}

TriangleMesh submesh(const TriangleMesh& mesh, const std::vector<std::size_t>& faces) {
  TriangleMesh out;
  std::vector<std::uint32_t> index(mesh.vertex_count(), ~std::uint32_t{0});
  for (std::size_t f : faces) {
    Triangle t = mesh.triangles[f];
    for (auto& v : t) {
      if (index[v] == ~std::uint32_t{0}) {
        index[v] = static_cast<std::uint32_t>(out.vertices.size());
        out.vertices.push_back(mesh.vertices[v]);
      }
      v = index[v];
    }
    out.triangles.push_back(t);
  }
  return out;
}

// 1 - (V - E + F) / 2 of one component: its genus when it is closed and manifold.
int euler_genus(const TriangleMesh& component) {
  const auto chi = static_cast<long long>(component.vertex_count()) -
                   static_cast<long long>(unique_edges(component.triangles).size()) +
                   static_cast<long long>(component.triangle_count());
  return static_cast<int>((2 - chi) / 2);
}

void append(TriangleMesh& to, const TriangleMesh& part) {
  const auto offset = static_cast<std::uint32_t>(to.vertices.size());
  to.vertices.insert(to.vertices.end(), part.vertices.begin(), part.vertices.end());
  for (Triangle t : part.triangles) {
    for (auto& v : t) v += offset;
    to.triangles.push_back(t);
  }
}

}  // namespace

ComponentsRebuild rebuild_components(const TriangleMesh& mesh, const std::string& name, double edge_m,
                                     bool only_with_handles) {
  ComponentsRebuild out;
  const auto groups = components_of(mesh);
  out.components = groups.size();
  std::vector<TriangleMesh> parts;
  for (const auto& faces : groups) {
    TriangleMesh part = submesh(mesh, faces);
    const int genus = euler_genus(part);
    if (only_with_handles && genus <= 0) {
      parts.push_back(std::move(part));
      continue;
    }
    VoxelRebuild rebuilt = rebuild_through_voxels(part, name, edge_m);
    if (rebuilt.mesh.triangles.empty()) {
      out.open = true;
      return out;
    }
    ++out.rebuilt;
    out.genus_before += std::max(genus, 0);
    out.genus_after += rebuilt.report.genus;
    out.voxel_m = rebuilt.voxel_m;
    out.edge_m = rebuilt.edge_m;
    out.volume_before_m3 += std::abs(enclosed_volume(part));
    out.volume_after_m3 += enclosed_volume(rebuilt.mesh);
    parts.push_back(std::move(rebuilt.mesh));
  }
  for (const auto& part : parts) append(out.mesh, part);
  return out;
}

}  // namespace pneuma::mesh::detail
