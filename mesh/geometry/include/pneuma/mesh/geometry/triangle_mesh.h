#pragma once
// An indexed triangle surface in metres, the currency of every module that handles geometry.
// Triangles are counter-clockwise seen from outside, so a closed surface encloses a positive
// volume. Plain Eigen code only (no CGAL here): this header is on the per-frame path.
#include <Eigen/Core>
#include <Eigen/Geometry>  // cross products on Vector3d, which every user of a mesh needs
#include <array>
#include <cstdint>
#include <vector>

namespace pneuma::mesh {

using Triangle = std::array<std::uint32_t, 3>;

struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;  // metres
  std::vector<Triangle> triangles;

  std::size_t vertex_count() const { return vertices.size(); }
  std::size_t triangle_count() const { return triangles.size(); }
};

// The area of one triangle (m^2): the one formula every area in pneuma is summed from, except
// the fused frame kernel (deformed_surface.h: vectorised, the same value to rounding) and the
// shader.
inline double triangle_area(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  return 0.5 * (b - a).cross(c - a).norm();
}
// Total surface area (m^2): the sum of triangle_area() in triangle order.
double surface_area(const TriangleMesh& mesh);
double surface_area(const std::vector<Eigen::Vector3d>& positions, const std::vector<Triangle>& triangles);
// The most vertices pneuma makes a surface of (remeshing, a label map's surface): the field, the
// frames and the outputs grow with it, and a 0.3 mm mesh of a real lung (about 1.5 million
// vertices) is already finer than any CT it comes from. Documented in README.md (limits).
inline constexpr double kMaxSurfaceVertices = 2e6;
// About how many vertices a surface of `area_m2` has at edge `edge_m` (equilateral triangles,
// two per vertex, each sqrt(3)/4 edge^2).
double vertex_count_at_edge(double area_m2, double edge_m);
// Enclosed volume (m^3) as a sum of signed tetrahedra against the origin; positive for a
// closed, outward-oriented surface.
double enclosed_volume(const TriangleMesh& mesh);
double enclosed_volume(const std::vector<Eigen::Vector3d>& positions, const std::vector<Triangle>& triangles);
// Area-weighted vertex normals (unit length, zero for an isolated vertex).
std::vector<Eigen::Vector3d> vertex_normals(const TriangleMesh& mesh);
// dV/dx_i: the sum over incident triangles of (b - a) x (c - a) / 6, i.e. a third of the
// area-weighted normal. sum_i volume_gradient_i . u_i is the first-order volume change.
std::vector<Eigen::Vector3d> volume_gradient(const TriangleMesh& mesh);
// dA/dx_i: the sum over incident triangles of n x (opposite edge) / 2. sum_i
// area_gradient_i . u_i is the first-order area change dA/ds of x + s u at s = 0.
std::vector<Eigen::Vector3d> area_gradient(const TriangleMesh& mesh);
// The undirected edges (a < b), sorted, each once.
std::vector<std::array<std::uint32_t, 2>> unique_edges(const std::vector<Triangle>& triangles);
// Each face's component, faces joined through shared vertices; numbered 0, 1, ... in the order
// of each component's first face. Returns the component count.
std::size_t face_components(const TriangleMesh& mesh, std::vector<std::uint32_t>& component_of_face);
// Axis-aligned bounds: {min, max}.
std::array<Eigen::Vector3d, 2> bounding_box(const std::vector<Eigen::Vector3d>& positions);

// Renumbers vertices in the order of their first use by the triangles and drops unused ones:
// the canonical numbering that read_mesh() (mesh/io) produces.
void renumber_vertices_by_first_use(TriangleMesh& mesh);

// An icosphere: the icosahedron subdivided `subdivisions` times and projected on the sphere
// (20 * 4^k triangles). Deterministic; used as an analytic test shape.
TriangleMesh make_icosphere(double radius_m, int subdivisions);

}  // namespace pneuma::mesh
