// repair(): index-preserving soup cleaning, then CGAL (orient_polygon_soup, stitch_borders,
// remove_degenerate_faces, triangulate_refine_and_fair_hole), then a final validation.
#include <CGAL/Polygon_mesh_processing/border.h>
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/repair_degeneracies.h>
#include <CGAL/Polygon_mesh_processing/stitch_borders.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <fmt/format.h>

#include <algorithm>
#include <iterator>
#include <map>

#include "cgal_surface_mesh.h"
#include "pneuma/core/error.h"
#include "pneuma/mesh/repair.h"
#include "pneuma/mesh/validate.h"

namespace PMP = CGAL::Polygon_mesh_processing;

namespace pneuma::mesh {
namespace {

using detail::Point;
using detail::Polygon;
using detail::SurfaceMesh;

bool starts_with(const std::string& s, const char* prefix) { return s.rfind(prefix, 0) == 0; }

// The problems repair does not touch, in the validator's words (input indices).
void refuse_unrepairable(const ValidationReport& report, const std::string& name) {
  for (const std::string& p : report.problems) {
    const bool unrepairable = p.find("non-manifold") != std::string::npos || starts_with(p, "non-orientable") ||
                              starts_with(p, "self-intersection");
    if (unrepairable) throw InputError(name + ": cannot repair: " + p);
  }
}

std::string count_of(std::size_t n, const char* one, const char* many) {
  return fmt::format("{} {}", n, n == 1 ? one : many);
}

}  // namespace

std::vector<std::string> RepairReport::actions() const {
  std::vector<std::string> a;
  if (merged_vertices) a.push_back("merged " + count_of(merged_vertices, "vertex", "vertices") + " at identical positions");
  if (removed_degenerate_faces) a.push_back("removed " + count_of(removed_degenerate_faces, "degenerate face", "degenerate faces"));
  if (removed_duplicated_faces) a.push_back("removed " + count_of(removed_duplicated_faces, "duplicated face", "duplicated faces"));
  if (flipped_faces) a.push_back("flipped " + count_of(flipped_faces, "face", "faces") + " to match their neighbours");
  if (stitched_edges) a.push_back("stitched " + count_of(stitched_edges, "pair of border edges", "pairs of border edges"));
  if (filled_holes) a.push_back("filled " + count_of(filled_holes, "hole", "holes") + " with " + count_of(added_faces, "face", "faces"));
  if (reversed_components) a.push_back("reversed " + count_of(reversed_components, "inside-out component", "inside-out components"));
  if (dropped_vertices) a.push_back("dropped " + count_of(dropped_vertices, "unused vertex", "unused vertices"));
  return a;
}

RepairResult repair(const TriangleMesh& mesh, const std::string& name, const RepairOptions& options) {
  const ValidationReport before = validate(mesh);
  refuse_unrepairable(before, name);
  RepairResult result;
  RepairReport& rep = result.report;

  // 1. Soup cleaning that keeps the input's vertex numbering (so messages can name vertices):
  //    a vertex at the position of an earlier one becomes that one.
  std::vector<Point> points;
  points.reserve(mesh.vertex_count());
  std::vector<std::size_t> same_as(mesh.vertex_count());
  {
    std::map<std::array<double, 3>, std::size_t> first_at;
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
      const auto& p = mesh.vertices[v];
      const auto [it, inserted] = first_at.try_emplace({p.x(), p.y(), p.z()}, v);
      same_as[v] = it->second;
      rep.merged_vertices += !inserted;
      points.push_back(detail::to_point(p));
    }
  }
  std::vector<Polygon> polygons;
  polygons.reserve(mesh.triangle_count());
  {
    std::map<std::array<std::size_t, 3>, std::size_t> seen;
    for (const Triangle& t : mesh.triangles) {
      const std::array<std::size_t, 3> v{same_as[t[0]], same_as[t[1]], same_as[t[2]]};
      if (v[0] == v[1] || v[1] == v[2] || v[2] == v[0]) {
        ++rep.removed_degenerate_faces;
        continue;
      }
      auto key = v;
      std::sort(key.begin(), key.end());
      if (!seen.try_emplace(key, polygons.size()).second) {
        ++rep.removed_duplicated_faces;
        continue;
      }
      polygons.push_back({v[0], v[1], v[2]});
    }
  }

  // 2. Consistent orientation (the surface is manifold and orientable, so no point is split).
  const std::vector<Polygon> unoriented = polygons;
  PMP::orient_polygon_soup(points, polygons);
  if (points.size() != mesh.vertex_count()) {
    throw InputError(name + ": cannot repair: the surface is not manifold once duplicates are merged");
  }
  for (std::size_t i = 0; i < polygons.size(); ++i) rep.flipped_faces += polygons[i] != unoriented[i];

  SurfaceMesh sm;
  PMP::polygon_soup_to_polygon_mesh(points, polygons, sm);

  // 3. Borders that coincide, then zero-area faces (collinear vertices, exact predicate).
  rep.stitched_edges = PMP::stitch_borders(sm);
  const std::size_t faces_before = sm.number_of_faces();
  PMP::remove_degenerate_faces(sm);
  rep.removed_degenerate_faces += faces_before - sm.number_of_faces();

  // 4. Holes: refuse the large ones before filling any.
  std::vector<SurfaceMesh::Halfedge_index> holes;
  PMP::extract_boundary_cycles(sm, std::back_inserter(holes));
  for (const auto h : holes) {
    std::size_t edges = 0;
    std::size_t lowest_vertex = ~std::size_t{0};
    for (const auto e : CGAL::halfedges_around_face(h, sm)) {
      ++edges;
      lowest_vertex = std::min(lowest_vertex, static_cast<std::size_t>(sm.target(e)));
    }
    if (edges > options.max_hole_edges) {
      throw InputError(fmt::format("{}: cannot repair: hole of {} boundary edges at vertex {} is larger than the {} edges "
                                   "repair fills",
                                   name, edges, lowest_vertex, options.max_hole_edges));
    }
  }
  for (const auto h : holes) {
    std::vector<SurfaceMesh::Face_index> patch;
    std::vector<SurfaceMesh::Vertex_index> added;
    PMP::triangulate_refine_and_fair_hole(sm, h, std::back_inserter(patch), std::back_inserter(added));
    ++rep.filled_holes;
    rep.added_faces += patch.size();
  }

  // 5. Outward orientation, component by component (no nesting of lungs is expected).
  if (CGAL::is_closed(sm)) {
    auto component = sm.add_property_map<SurfaceMesh::Face_index, std::size_t>("f:pneuma_component", 0).first;
    const std::size_t count = PMP::connected_components(sm, component);
    std::vector<double> six_volume(count, 0.0);
    for (const auto f : sm.faces()) {
      const auto h = sm.halfedge(f);
      const Point& a = sm.point(sm.source(h));
      const Point& b = sm.point(sm.target(h));
      const Point& c = sm.point(sm.target(sm.next(h)));
      six_volume[component[f]] += CGAL::determinant(a.x(), a.y(), a.z(), b.x(), b.y(), b.z(), c.x(), c.y(), c.z());
    }
    for (std::size_t k = 0; k < count; ++k) {
      if (six_volume[k] >= 0.0) continue;
      std::vector<SurfaceMesh::Face_index> faces;
      for (const auto f : sm.faces()) {
        if (component[f] == k) faces.push_back(f);
      }
      PMP::reverse_face_orientations(faces, sm);
      ++rep.reversed_components;
    }
    sm.remove_property_map(component);
  }

  result.mesh = detail::from_surface_mesh(sm);
  rep.dropped_vertices = before.isolated_vertex_count;

  const ValidationReport after = validate(result.mesh);
  if (!after.valid()) throw InputError(name + ": cannot repair: after repair, " + after.summary());
  if (result.mesh.triangles.empty()) throw InputError(name + ": cannot repair: no faces left");
  return result;
}

}  // namespace pneuma::mesh
