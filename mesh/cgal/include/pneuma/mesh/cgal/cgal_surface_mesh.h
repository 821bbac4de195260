#pragma once
// Private to pneuma_mesh and included only by the CGAL translation units (validate_cgal.cpp,
// repair.cpp, remesh.cpp): the kernel, CGAL's Surface_mesh, and conversions to and from
// TriangleMesh. Epick: exact predicates, inexact constructions (enough for soup repair,
// remeshing and measures; no GMP number types in the hot paths).
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>

#include <optional>
#include <vector>

#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh::detail {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using SurfaceMesh = CGAL::Surface_mesh<Point>;
using Polygon = std::vector<std::size_t>;

inline Point to_point(const Eigen::Vector3d& p) { return {p.x(), p.y(), p.z()}; }

// Builds a Surface_mesh with vertex i = mesh vertex i and face i = mesh triangle i. Returns
// nothing when the triangles do not form a polygon mesh (non-manifold, repeated vertices).
inline std::optional<SurfaceMesh> to_surface_mesh(const TriangleMesh& mesh) {
  SurfaceMesh sm;
  sm.reserve(static_cast<SurfaceMesh::size_type>(mesh.vertex_count()),
             static_cast<SurfaceMesh::size_type>(3 * mesh.triangle_count() / 2),
             static_cast<SurfaceMesh::size_type>(mesh.triangle_count()));
  for (const auto& p : mesh.vertices) sm.add_vertex(to_point(p));
  for (const Triangle& t : mesh.triangles) {
    const auto f =
        sm.add_face(SurfaceMesh::Vertex_index(t[0]), SurfaceMesh::Vertex_index(t[1]), SurfaceMesh::Vertex_index(t[2]));
    if (f == SurfaceMesh::null_face()) return std::nullopt;
  }
  return sm;
}

// Back to a TriangleMesh: live faces in index order, vertices renumbered by first use.
inline TriangleMesh from_surface_mesh(const SurfaceMesh& sm) {
  TriangleMesh mesh;
  constexpr std::uint32_t unused = ~std::uint32_t{0};
  std::vector<std::uint32_t> index(sm.number_of_vertices() + sm.number_of_removed_vertices(), unused);
  mesh.triangles.reserve(sm.number_of_faces());
  mesh.vertices.reserve(sm.number_of_vertices());
  for (const auto f : sm.faces()) {
    Triangle t{};
    int k = 0;
    for (const auto v : CGAL::vertices_around_face(sm.halfedge(f), sm)) {
      if (k == 3) break;
      std::uint32_t& i = index[static_cast<std::size_t>(v)];
      if (i == unused) {
        const Point& p = sm.point(v);
        i = static_cast<std::uint32_t>(mesh.vertices.size());
        mesh.vertices.emplace_back(p.x(), p.y(), p.z());
      }
      t[static_cast<std::size_t>(k++)] = i;
    }
    mesh.triangles.push_back(t);
  }
  return mesh;
}

}  // namespace pneuma::mesh::detail
