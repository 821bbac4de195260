// The CGAL half of validation: exact collinearity, self-intersections, area and volume.
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>

#include <algorithm>
#include <iterator>

#include "pneuma/core/error.h"
#include "pneuma/mesh/cgal/cgal_internal.h"
#include "pneuma/mesh/cgal/cgal_surface_mesh.h"
#include "pneuma/mesh/geometry/validate.h"

namespace PMP = CGAL::Polygon_mesh_processing;

namespace pneuma::mesh {
namespace detail {
namespace {

// Where the soup had to be split at non-manifold edges and vertices, CGAL no longer sees the
// faces around them as neighbours and reports them as touching. Decide on the input's own
// adjacency, as CGAL does for neighbours: faces sharing an edge intersect only when they fold
// onto each other; faces sharing a vertex only when an edge of one crosses the other.
bool intersect_beyond_shared_vertices(const TriangleMesh& mesh, const Triangle& f, const Triangle& g) {
  std::vector<std::uint32_t> shared, only_f, only_g;
  for (std::uint32_t v : f) (std::find(g.begin(), g.end(), v) != g.end() ? shared : only_f).push_back(v);
  for (std::uint32_t v : g) {
    if (std::find(f.begin(), f.end(), v) == f.end()) only_g.push_back(v);
  }
  auto P = [&](std::uint32_t v) { return to_point(mesh.vertices[v]); };
  const Kernel::Triangle_3 tf(P(f[0]), P(f[1]), P(f[2])), tg(P(g[0]), P(g[1]), P(g[2]));
  if (shared.empty()) return true;  // CGAL's verdict stands
  if (shared.size() == 2) {
    const Point a = P(shared[0]), b = P(shared[1]), c = P(only_f[0]), d = P(only_g[0]);
    return CGAL::coplanar(a, b, c, d) && CGAL::coplanar_orientation(a, b, c, d) == CGAL::POSITIVE;
  }
  if (shared.size() == 1) {
    return CGAL::do_intersect(Kernel::Segment_3(P(only_f[0]), P(only_f[1])), tg) ||
           CGAL::do_intersect(Kernel::Segment_3(P(only_g[0]), P(only_g[1])), tf);
  }
  return false;  // the same three vertices: a duplicate, reported as such
}

}  // namespace

std::vector<std::size_t> collinear_faces(const TriangleMesh& mesh) {
  std::vector<std::size_t> out;
  for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
    const Triangle& t = mesh.triangles[f];
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) continue;
    if (CGAL::collinear(to_point(mesh.vertices[t[0]]), to_point(mesh.vertices[t[1]]), to_point(mesh.vertices[t[2]]))) {
      out.push_back(f);
    }
  }
  return out;
}

std::vector<std::pair<std::size_t, std::size_t>> self_intersecting_pairs(const TriangleMesh& mesh,
                                                                         const std::vector<std::size_t>& faces,
                                                                         std::size_t max_pairs) {
  // Fast path: the faces already form a polygon mesh (the usual, valid case).
  TriangleMesh subset;
  subset.vertices = mesh.vertices;
  subset.triangles.reserve(faces.size());
  for (std::size_t f : faces) subset.triangles.push_back(mesh.triangles[f]);
  std::optional<SurfaceMesh> sm = to_surface_mesh(subset);
  if (!sm) {
    // Split non-manifold edges and vertices (orient_polygon_soup duplicates points there and
    // keeps the polygon order), so that CGAL can look at the geometry anyway.
    std::vector<Point> points;
    points.reserve(mesh.vertex_count());
    for (const auto& p : mesh.vertices) points.push_back(to_point(p));
    std::vector<Polygon> polygons;
    polygons.reserve(faces.size());
    for (const Triangle& t : subset.triangles) polygons.push_back({t[0], t[1], t[2]});
    PMP::orient_polygon_soup(points, polygons);
    sm.emplace();
    PMP::polygon_soup_to_polygon_mesh(points, polygons, *sm);
    if (sm->number_of_faces() != faces.size()) {
      throw std::logic_error("self-intersection check: the soup did not convert face for face");
    }
  }
  std::vector<std::pair<SurfaceMesh::Face_index, SurfaceMesh::Face_index>> found;
  PMP::self_intersections(*sm, std::back_inserter(found),
                          PMP::parameters::maximum_number(static_cast<unsigned>(max_pairs)));
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  pairs.reserve(found.size());
  for (const auto& [a, b] : found) {
    const std::size_t fa = faces[static_cast<std::size_t>(a)], fb = faces[static_cast<std::size_t>(b)];
    if (intersect_beyond_shared_vertices(mesh, mesh.triangles[fa], mesh.triangles[fb])) {
      pairs.emplace_back(std::min(fa, fb), std::max(fa, fb));
    }
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

}  // namespace detail

double cgal_surface_area(const TriangleMesh& mesh) {
  const auto sm = detail::to_surface_mesh(mesh);
  if (!sm) throw ValueError("cgal_surface_area: the triangles do not form a polygon mesh");
  return PMP::area(*sm);
}

double cgal_enclosed_volume(const TriangleMesh& mesh) {
  const auto sm = detail::to_surface_mesh(mesh);
  if (!sm || !CGAL::is_closed(*sm)) throw ValueError("cgal_enclosed_volume: the surface is not closed");
  return PMP::volume(*sm);
}

}  // namespace pneuma::mesh
