#include "pneuma/mesh/geometry/triangle_mesh.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace pneuma::mesh {

double surface_area(const std::vector<Eigen::Vector3d>& p, const std::vector<Triangle>& triangles) {
  double area = 0.0;
  for (const Triangle& t : triangles) area += triangle_area(p[t[0]], p[t[1]], p[t[2]]);
  return area;
}

double surface_area(const TriangleMesh& mesh) { return surface_area(mesh.vertices, mesh.triangles); }

double vertex_count_at_edge(double area_m2, double edge_m) {
  return 2.0 * area_m2 / (std::sqrt(3.0) * edge_m * edge_m);
}

double enclosed_volume(const std::vector<Eigen::Vector3d>& p, const std::vector<Triangle>& triangles) {
  double six_volume = 0.0;
  for (const Triangle& t : triangles) six_volume += p[t[0]].dot(p[t[1]].cross(p[t[2]]));
  return six_volume / 6.0;
}

double enclosed_volume(const TriangleMesh& mesh) { return enclosed_volume(mesh.vertices, mesh.triangles); }

std::vector<Eigen::Vector3d> volume_gradient(const TriangleMesh& mesh) {
  std::vector<Eigen::Vector3d> g(mesh.vertices.size(), Eigen::Vector3d::Zero());
  const auto& p = mesh.vertices;
  for (const Triangle& t : mesh.triangles) {
    const Eigen::Vector3d cross = (p[t[1]] - p[t[0]]).cross(p[t[2]] - p[t[0]]);
    for (std::uint32_t v : t) g[v] += cross / 6.0;
  }
  return g;
}

std::vector<Eigen::Vector3d> area_gradient(const TriangleMesh& mesh) {
  std::vector<Eigen::Vector3d> g(mesh.vertices.size(), Eigen::Vector3d::Zero());
  const auto& p = mesh.vertices;
  for (const Triangle& t : mesh.triangles) {
    const Eigen::Vector3d cross = (p[t[1]] - p[t[0]]).cross(p[t[2]] - p[t[0]]);
    const double norm = cross.norm();
    if (norm == 0.0) continue;  // a degenerate triangle has no gradient direction
    const Eigen::Vector3d unit = cross / norm;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d& next = p[t[(k + 1) % 3]];
      const Eigen::Vector3d& prev = p[t[(k + 2) % 3]];
      g[t[k]] += 0.5 * unit.cross(prev - next);
    }
  }
  return g;
}

std::vector<Eigen::Vector3d> vertex_normals(const TriangleMesh& mesh) {
  std::vector<Eigen::Vector3d> n = volume_gradient(mesh);
  for (auto& v : n) {
    const double len = v.norm();
    if (len > 0.0) v /= len;
  }
  return n;
}

std::vector<std::array<std::uint32_t, 2>> unique_edges(const std::vector<Triangle>& triangles) {
  std::vector<std::array<std::uint32_t, 2>> edges;
  edges.reserve(triangles.size() * 3);
  for (const Triangle& t : triangles) {
    for (int i = 0; i < 3; ++i) {
      const std::uint32_t a = t[i], b = t[(i + 1) % 3];
      edges.push_back({std::min(a, b), std::max(a, b)});
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  return edges;
}

std::array<Eigen::Vector3d, 2> bounding_box(const std::vector<Eigen::Vector3d>& positions) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const auto& p : positions) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return {lo, hi};
}

TriangleMesh make_icosphere(double radius, int subdivisions) {
  const double phi = (1.0 + std::sqrt(5.0)) / 2.0;
  TriangleMesh m;
  m.vertices = {{-1, phi, 0},  {1, phi, 0},  {-1, -phi, 0}, {1, -phi, 0}, {0, -1, phi},  {0, 1, phi},
                {0, -1, -phi}, {0, 1, -phi}, {phi, 0, -1},  {phi, 0, 1},  {-phi, 0, -1}, {-phi, 0, 1}};
  m.triangles = {{0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                 {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                 {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (auto& v : m.vertices) v = v.normalized();
  for (int level = 0; level < subdivisions; ++level) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> midpoint;
    auto middle = [&](std::uint32_t a, std::uint32_t b) {
      const auto key = std::make_pair(std::min(a, b), std::max(a, b));
      if (auto it = midpoint.find(key); it != midpoint.end()) return it->second;
      m.vertices.push_back((m.vertices[a] + m.vertices[b]).normalized());
      const auto index = static_cast<std::uint32_t>(m.vertices.size() - 1);
      midpoint.emplace(key, index);
      return index;
    };
    std::vector<Triangle> next;
    next.reserve(m.triangles.size() * 4);
    for (const Triangle& t : m.triangles) {
      const std::uint32_t ab = middle(t[0], t[1]), bc = middle(t[1], t[2]), ca = middle(t[2], t[0]);
      next.push_back({t[0], ab, ca});
      next.push_back({t[1], bc, ab});
      next.push_back({t[2], ca, bc});
      next.push_back({ab, bc, ca});
    }
    m.triangles = std::move(next);
  }
  for (auto& v : m.vertices) v *= radius;
  return m;
}

std::size_t face_components(const TriangleMesh& mesh, std::vector<std::uint32_t>& component_of_face) {
  std::vector<std::uint32_t> parent(mesh.vertex_count());
  for (std::size_t v = 0; v < parent.size(); ++v) parent[v] = static_cast<std::uint32_t>(v);
  auto find = [&](std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (const Triangle& t : mesh.triangles) {
    for (std::size_t c = 1; c < 3; ++c) {
      const std::uint32_t a = find(t[0]), b = find(t[c]);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
  }
  constexpr std::uint32_t kNone = ~std::uint32_t{0};
  std::vector<std::uint32_t> number(mesh.vertex_count(), kNone);
  std::uint32_t count = 0;
  component_of_face.resize(mesh.triangle_count());
  for (std::size_t f = 0; f < mesh.triangle_count(); ++f) {
    std::uint32_t& n = number[find(mesh.triangles[f][0])];
    if (n == kNone) n = count++;
    component_of_face[f] = n;
  }
  return count;
}

void renumber_vertices_by_first_use(TriangleMesh& mesh) {
  constexpr std::uint32_t unused = ~std::uint32_t{0};
  std::vector<std::uint32_t> new_index(mesh.vertices.size(), unused);
  std::vector<Eigen::Vector3d> vertices;
  vertices.reserve(mesh.vertices.size());
  for (Triangle& t : mesh.triangles) {
    for (std::uint32_t& v : t) {
      if (new_index[v] == unused) {
        new_index[v] = static_cast<std::uint32_t>(vertices.size());
        vertices.push_back(mesh.vertices[v]);
      }
      v = new_index[v];
    }
  }
  mesh.vertices = std::move(vertices);
}

}  // namespace pneuma::mesh
