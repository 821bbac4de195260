#pragma once
// Validation of a triangle surface: what the field solver and the renderer need (one closed,
// manifold, consistently and outward oriented, self-intersection-free surface per component)
// and, for everything else, what is wrong and where (face and vertex indices of the mesh).
//
// Topology is checked on the index list in plain C++; exact predicates (zero-area faces) and
// self-intersections use CGAL inside validate_cgal.cpp. Nothing here includes CGAL.
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh {

struct ValidateOptions {
  // CGAL's box-intersection test; by far the most expensive check (seconds for 1M triangles).
  bool check_self_intersections = true;
};

struct ValidationReport {
  // Counts.
  std::size_t vertex_count = 0;
  std::size_t triangle_count = 0;
  std::size_t edge_count = 0;             // distinct undirected edges
  std::size_t component_count = 0;        // faces connected through shared edges
  std::size_t isolated_vertex_count = 0;  // vertices no triangle uses
  // Problems (each 0 for a valid surface).
  std::size_t degenerate_face_count = 0;       // a repeated vertex, or three collinear points (exact)
  std::size_t duplicated_face_count = 0;       // same three vertices as an earlier face, any order
  std::size_t boundary_edge_count = 0;         // edges with one face
  std::size_t hole_count = 0;                  // closed loops of boundary edges
  std::size_t non_manifold_edge_count = 0;     // edges with three or more faces
  std::size_t non_manifold_vertex_count = 0;   // vertices whose faces form more than one fan
  std::size_t misoriented_face_count = 0;      // faces oriented against the rest of their component
  std::size_t inside_out_component_count = 0;  // closed, consistent, negative enclosed volume
  bool orientable = true;
  std::optional<std::size_t> self_intersection_count;  // pairs of faces; unset: not checked
  // Genus (sum over components), when every component is a closed orientable manifold.
  std::optional<int> genus;
  // Geometry.
  double area_m2 = 0.0;
  double volume_m3 = 0.0;
  // One line per kind of problem, naming its first occurrence (face/vertex indices), in a
  // fixed order: degenerate, duplicated, non-manifold edge, non-manifold vertex, hole,
  // orientation, inside out, self-intersection.
  std::vector<std::string> problems;

  bool closed() const { return boundary_edge_count == 0; }
  bool manifold() const { return non_manifold_edge_count == 0 && non_manifold_vertex_count == 0; }
  bool valid() const { return problems.empty(); }
  // All problems in one line ("; "-separated), empty when valid.
  std::string summary() const;
};

ValidationReport validate(const TriangleMesh& mesh, const ValidateOptions& options = {});

// Refuses a surface more than a metre across: not a lung (an adult's is about 0.3 m tall), but a
// file in millimetres read as metres or a damaged vertex far away, whose needle triangles
// remeshing would split for hours or until memory runs out (a damaged STL's vertex at z = 11 km;
// found twice by scripts/mutate, through `run` and `mesh remesh`). Throws InputError "<name>: the
// surface spans ... (is <unit_key> right, or a vertex damaged?)".
void require_lung_sized(const std::string& name, const TriangleMesh& surface, const std::string& unit_key);

// Edge length and angle quality, the figures remeshing reports before and after.
struct MeshQuality {
  double min_edge_m = 0.0, mean_edge_m = 0.0, max_edge_m = 0.0;
  double min_angle_deg = 0.0, max_angle_deg = 0.0;
  double mean_min_angle_deg = 0.0;     // mean over triangles of their smallest angle (60 is ideal)
  double fraction_below_30_deg = 0.0;  // triangles with an angle under 30 degrees
};
MeshQuality measure_quality(const TriangleMesh& mesh);

// Area and enclosed volume computed by CGAL's Polygon_mesh_processing (area(), volume()),
// the independent check of the plain Eigen functions in triangle_mesh.h. The volume needs a
// closed surface; throws ValueError when the mesh is not a closed polygon mesh.
double cgal_surface_area(const TriangleMesh& mesh);
double cgal_enclosed_volume(const TriangleMesh& mesh);

}  // namespace pneuma::mesh
