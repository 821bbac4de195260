// The depth of points below the convex hull of a point set (CGAL convex_hull_3).
#include <CGAL/AABB_face_graph_triangle_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/convex_hull_3.h>

#include <algorithm>
#include <array>
#include <limits>

#include "pneuma/mesh/anatomy/regions.h"

namespace pneuma::mesh {

std::vector<double> depth_below_convex_hull(const std::vector<Eigen::Vector3d>& points,
                                            const std::vector<Eigen::Vector3d>& queries) {
  using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Point = Kernel::Point_3;
  std::vector<Point> cgal_points;
  cgal_points.reserve(points.size());
  for (const auto& p : points) cgal_points.emplace_back(p.x(), p.y(), p.z());
  CGAL::Surface_mesh<Point> hull;
  CGAL::convex_hull_3(cgal_points.begin(), cgal_points.end(), hull);
  // Outward unit normal and offset of every hull face. Inside a convex polytope the depth,
  // min over faces of (offset - n.x), is the distance to the nearest face, whose plane gives it:
  // so the nearest face is found with an AABB tree (log of the faces per point, where a loop over
  // every plane took minutes at 10^5 points: a fine, mostly convex surface has 10^5 hull faces).
  using Hull = CGAL::Surface_mesh<Point>;
  using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, CGAL::AABB_face_graph_triangle_primitive<Hull>>>;
  // A degenerate face keeps the zero plane: the depth below it is 0 (the point is on the surface).
  std::vector<std::pair<Eigen::Vector3d, double>> planes(hull.number_of_faces(), {Eigen::Vector3d::Zero(), 0.0});
  for (auto f : hull.faces()) {
    std::array<Eigen::Vector3d, 3> v;
    int k = 0;
    for (auto vertex : CGAL::vertices_around_face(hull.halfedge(f), hull)) {
      if (k < 3) {
        const Point& q = hull.point(vertex);
        v[static_cast<std::size_t>(k)] = Eigen::Vector3d(q.x(), q.y(), q.z());
      }
      ++k;
    }
    // CGAL lists a face's vertices from any of the three: start from the lexicographically
    // smallest (orientation kept), so a face's plane is the same bits whatever the hull's
    // internal order, and so is every depth.
    const auto first = std::min_element(v.begin(), v.end(), [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
      return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
    });
    std::rotate(v.begin(), first, v.end());
    const Eigen::Vector3d n = (v[1] - v[0]).cross(v[2] - v[0]);
    const double len = n.norm();
    if (len == 0.0) continue;
    planes[f.idx()] = {n / len, n.dot(v[0]) / len};
  }
  std::vector<double> depth(queries.size(), 0.0);
  if (hull.number_of_faces() == 0) return depth;
  // The hull's vertices are input points (copies): their depth is 0, no query needed. On a fine,
  // mostly convex surface that is most of them.
  std::vector<std::array<double, 3>> corners;
  corners.reserve(hull.number_of_vertices());
  for (auto v : hull.vertices()) corners.push_back({hull.point(v).x(), hull.point(v).y(), hull.point(v).z()});
  std::sort(corners.begin(), corners.end());
  Tree tree(faces(hull).first, faces(hull).second, hull);
  tree.accelerate_distance_queries();
  for (std::size_t i = 0; i < queries.size(); ++i) {
    const Eigen::Vector3d& q = queries[i];
    if (std::binary_search(corners.begin(), corners.end(), std::array<double, 3>{q.x(), q.y(), q.z()})) continue;
    const auto face = tree.closest_point_and_primitive(Point(q.x(), q.y(), q.z())).second;
    const auto& [n, offset] = planes[face.idx()];
    depth[i] = std::max(0.0, offset - n.dot(q));
  }
  return depth;
}

}  // namespace pneuma::mesh
