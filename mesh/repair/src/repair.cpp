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
#include <cmath>
#include <iterator>
#include <map>
#include <set>

#include "pneuma/core/error.h"
#include "pneuma/mesh/cgal/cgal_internal.h"
#include "pneuma/mesh/cgal/cgal_surface_mesh.h"
#include "pneuma/mesh/geometry/validate.h"
#include "pneuma/mesh/repair/repair.h"
#include "voxel_rebuild.h"

namespace PMP = CGAL::Polygon_mesh_processing;

namespace pneuma::mesh {
namespace {

using detail::Point;
using detail::Polygon;
using detail::SurfaceMesh;

bool starts_with(const std::string& s, const char* prefix) { return s.rfind(prefix, 0) == 0; }

// The first problem no face-by-face repair mends, in the validator's words (input indices).
std::string unrepairable_problem(const ValidationReport& report) {
  for (const std::string& p : report.problems) {
    if (p.find("non-manifold") != std::string::npos || starts_with(p, "non-orientable")) return p;
  }
  return {};
}

void refuse_unrepairable(const std::string& problem, const std::string& name, bool tried_rebuild) {
  throw InputError(name + ": cannot repair: " + problem +
                   (tried_rebuild ? " (and the surface is open, so it cannot be rebuilt from its inside: "
                                  : " (no safe automatic repair: ") +
                   "re-export the surface, or rebuild it from its label map with 'pneuma mesh from-labels')");
}

void record_rebuild(RepairReport& rep, const detail::ComponentsRebuild& rebuilt, std::string why) {
  rep.rebuilt_components = rebuilt.rebuilt;
  rep.rebuilt_for = std::move(why);
  rep.rebuilt_voxel_m = rebuilt.voxel_m;
  rep.rebuilt_edge_m = rebuilt.edge_m;
  rep.rebuilt_volume_before_m3 = rebuilt.volume_before_m3;
  rep.rebuilt_volume_after_m3 = rebuilt.volume_after_m3;
  rep.handles_removed = std::max(0, rebuilt.genus_before - rebuilt.genus_after);
}

// One pass: soup cleaning (without the faces in `remove`), small components, orientation,
// stitching, degenerate faces, holes, outward orientation. No verdict.
RepairResult repair_pass(const TriangleMesh& mesh, const std::string& name, const RepairOptions& options,
                         const std::vector<char>& remove, std::size_t isolated_vertices) {
  RepairResult result;
  RepairReport& rep = result.report;
  rep.min_component_fraction = options.min_component_fraction;

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
    for (std::size_t f = 0; f < mesh.triangle_count(); ++f) {
      if (!remove.empty() && remove[f]) continue;
      const Triangle& t = mesh.triangles[f];
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

  // Small components (islands of a segmentation, stray fragments): by area, against the largest.
  if (options.min_component_fraction > 0.0 && !polygons.empty()) {
    std::vector<std::size_t> parent(points.size());
    for (std::size_t v = 0; v < parent.size(); ++v) parent[v] = v;
    auto find = [&](std::size_t x) {
      while (parent[x] != x) x = parent[x] = parent[parent[x]];
      return x;
    };
    for (const Polygon& p : polygons) {
      for (std::size_t c = 1; c < 3; ++c) {
        const std::size_t a = find(p[0]), b = find(p[c]);
        if (a != b) parent[std::max(a, b)] = std::min(a, b);
      }
    }
    std::map<std::size_t, double> area;
    std::vector<double> face_area(polygons.size());
    for (std::size_t f = 0; f < polygons.size(); ++f) {
      const auto& p = polygons[f];
      face_area[f] = triangle_area(mesh.vertices[p[0]], mesh.vertices[p[1]], mesh.vertices[p[2]]);
      area[find(p[0])] += face_area[f];
    }
    double largest = 0.0;
    for (const auto& [root, a] : area) largest = std::max(largest, a);
    std::vector<Polygon> kept;
    kept.reserve(polygons.size());
    for (std::size_t f = 0; f < polygons.size(); ++f) {
      const std::size_t root = find(polygons[f][0]);
      if (area[root] < options.min_component_fraction * largest) {
        ++rep.dropped_component_faces;
        rep.dropped_component_area_m2 += face_area[f];
        continue;
      }
      kept.push_back(polygons[f]);
    }
    for (const auto& [root, a] : area) rep.dropped_components += a < options.min_component_fraction * largest;
    polygons = std::move(kept);
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
      throw InputError(
          fmt::format("{}: cannot repair: hole of {} boundary edges at vertex {} is larger than the {} edges "
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
  rep.dropped_vertices = isolated_vertices;
  return result;
}

// Faces in the intersecting pairs and their `rings` rings of neighbours (through vertices).
std::vector<char> around_intersections(const TriangleMesh& mesh,
                                       const std::vector<std::pair<std::size_t, std::size_t>>& pairs, int rings) {
  std::vector<char> face(mesh.triangle_count(), 0), vertex(mesh.vertex_count(), 0);
  for (const auto& [a, b] : pairs) face[a] = face[b] = 1;
  for (int r = 0; r < rings; ++r) {
    for (std::size_t f = 0; f < face.size(); ++f) {
      if (face[f])
        for (std::uint32_t v : mesh.triangles[f]) vertex[v] = 1;
    }
    for (std::size_t f = 0; f < face.size(); ++f) {
      const Triangle& t = mesh.triangles[f];
      if (vertex[t[0]] || vertex[t[1]] || vertex[t[2]]) face[f] = 1;
    }
  }
  return face;
}

void accumulate(RepairReport& into, const RepairReport& pass) {
  into.removed_degenerate_faces += pass.removed_degenerate_faces;
  into.removed_duplicated_faces += pass.removed_duplicated_faces;
  into.flipped_faces += pass.flipped_faces;
  into.stitched_edges += pass.stitched_edges;
  into.filled_holes += pass.filled_holes;
  into.added_faces += pass.added_faces;
  into.reversed_components += pass.reversed_components;
  into.dropped_components += pass.dropped_components;
  into.dropped_component_faces += pass.dropped_component_faces;
  into.dropped_component_area_m2 += pass.dropped_component_area_m2;
}

std::vector<std::size_t> all_checkable_faces(const TriangleMesh& mesh) {
  std::vector<char> skip(mesh.triangle_count(), 0);
  for (std::size_t f : detail::collinear_faces(mesh)) skip[f] = 1;
  std::vector<std::size_t> faces;
  std::set<std::array<std::uint32_t, 3>> seen;
  for (std::size_t f = 0; f < mesh.triangle_count(); ++f) {
    Triangle t = mesh.triangles[f];
    if (skip[f] || t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
    std::sort(t.begin(), t.end());
    if (seen.insert(t).second) faces.push_back(f);
  }
  return faces;
}

}  // namespace

RepairResult repair_unchecked(const TriangleMesh& mesh, const std::string& name, const RepairOptions& options,
                              ValidationReport* after) {
  const ValidationReport before = validate(mesh);
  if (const std::string problem = unrepairable_problem(before); !problem.empty()) {
    if (options.rebuild_through_voxels) {
      const auto rebuilt = detail::rebuild_components(mesh, name, detail::rebuild_edge_for(mesh), false);
      if (!rebuilt.open) {
        RepairResult result;
        result.mesh = rebuilt.mesh;
        record_rebuild(result.report, rebuilt, problem);
        if (after != nullptr) *after = validate(result.mesh);
        return result;
      }
    }
    refuse_unrepairable(problem, name, options.rebuild_through_voxels);
  }
  // Self-intersections of the input: the faces involved and one ring around them are removed,
  // and the holes refilled; a refill that still intersects is redone with a wider ring.
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  if (options.remove_self_intersections && before.self_intersection_count.value_or(0) > 0) {
    pairs = detail::self_intersecting_pairs(mesh, all_checkable_faces(mesh), 100000);
  }
  std::vector<char> remove = pairs.empty() ? std::vector<char>{} : around_intersections(mesh, pairs, 1);
  RepairResult result = repair_pass(mesh, name, options, remove, before.isolated_vertex_count);
  RepairReport& rep = result.report;
  if (!pairs.empty()) {
    rep.self_intersecting_pairs = pairs.size();
    rep.first_intersecting_faces = {pairs[0].first, pairs[0].second};
    rep.removed_intersecting_faces = static_cast<std::size_t>(std::count(remove.begin(), remove.end(), 1));
    rep.rounds = 1;
  }
  ValidationReport check = validate(result.mesh);
  for (int round = 2; options.remove_self_intersections && round <= options.max_self_intersection_rounds &&
                      check.self_intersection_count.value_or(0) > 0 && rep.rounds > 0;
       ++round) {
    const auto again = detail::self_intersecting_pairs(result.mesh, all_checkable_faces(result.mesh), 100000);
    const std::vector<char> wider = around_intersections(result.mesh, again, round);
    RepairResult next = repair_pass(result.mesh, name, options, wider, 0);
    accumulate(next.report, rep);
    next.report.self_intersecting_pairs = rep.self_intersecting_pairs;
    next.report.first_intersecting_faces = rep.first_intersecting_faces;
    next.report.removed_intersecting_faces =
        rep.removed_intersecting_faces + static_cast<std::size_t>(std::count(wider.begin(), wider.end(), 1));
    next.report.rounds = round;
    next.report.merged_vertices = rep.merged_vertices;
    next.report.dropped_vertices = rep.dropped_vertices;
    result = std::move(next);
    check = validate(result.mesh);
  }
  // Handles (a lung has none): the components that have them are rebuilt; kept when too wide.
  if (check.valid() && check.genus.value_or(0) > 0) {
    const int genus = *check.genus;
    if (options.rebuild_through_voxels) {
      auto rebuilt = detail::rebuild_components(result.mesh, name, detail::rebuild_edge_for(result.mesh), true);
      const double change =
          rebuilt.volume_before_m3 > 0.0 ? rebuilt.volume_after_m3 / rebuilt.volume_before_m3 - 1.0 : 0.0;
      if (rebuilt.open || rebuilt.genus_after >= rebuilt.genus_before) {
        rep.handles_kept_because = "wider than the closing that removes small ones";
      } else if (std::abs(change) > options.max_handle_volume_change) {
        rep.handles_kept_because = fmt::format("removing them would change the enclosed volume by {:+.1f} % (more than "
                                               "{:g} %: not a small defect)",
                                               100.0 * change, 100.0 * options.max_handle_volume_change);
      } else if (ValidationReport rebuilt_check = validate(rebuilt.mesh); rebuilt_check.valid()) {
        result.mesh = std::move(rebuilt.mesh);
        record_rebuild(rep, rebuilt, genus == 1 ? "1 handle" : std::to_string(genus) + " handles");
        check = std::move(rebuilt_check);
      } else {
        rep.handles_kept_because = "the rebuilt surface was not valid: " + rebuilt_check.summary();
      }
    } else {
      rep.handles_kept_because = "rebuilding is off";
    }
    rep.handles_kept = check.genus.value_or(0);
  }
  if (after != nullptr) *after = std::move(check);
  return result;
}

RepairResult repair(const TriangleMesh& mesh, const std::string& name, const RepairOptions& options) {
  ValidationReport after;
  RepairResult result = repair_unchecked(mesh, name, options, &after);
  if (result.mesh.triangles.empty()) throw InputError(name + ": cannot repair: no faces left");
  if (!after.valid()) {
    const bool only_intersections = after.problems.size() == 1 && starts_with(after.problems[0], "self-intersection");
    throw InputError(name + ": cannot repair: after repair, " + after.summary() +
                     (only_intersections ? " (try 'pneuma mesh remesh " + name +
                                               " --edge 2mm -o OUT', which remeshes before the verdict)"
                                         : ""));
  }
  return result;
}

RepairRemeshResult repair_and_remesh(const TriangleMesh& mesh, const std::string& name,
                                     const RepairOptions& repair_options, const RemeshOptions& remesh_options) {
  ValidationReport after;
  RepairResult repaired = repair_unchecked(mesh, name, repair_options, &after);
  if (repaired.mesh.triangles.empty()) throw InputError(name + ": cannot repair: no faces left");
  for (const std::string& p : after.problems) {
    if (!starts_with(p, "self-intersection"))
      throw InputError(name + ": cannot repair: after repair, " + after.summary());
  }
  RepairRemeshResult out;
  out.repair = repaired.report;
  out.remesh = remesh_isotropic(repaired.mesh, remesh_options);
  const ValidationReport final_check = validate(out.remesh.mesh);
  if (!final_check.valid()) {
    throw InputError(fmt::format("{}: cannot repair: after repair and remeshing at {:.3g} mm, {}", name,
                                 remesh_options.target_edge_length_m * 1e3, final_check.summary()));
  }
  if (!after.valid()) {
    out.repair.remeshed_edge_m = remesh_options.target_edge_length_m;
    out.repair.left_for_remeshing = after.summary();
  }
  return out;
}

}  // namespace pneuma::mesh
