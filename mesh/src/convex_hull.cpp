// The depth of points below the convex hull of a point set (CGAL convex_hull_3).
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/convex_hull_3.h>

#include <algorithm>
#include <limits>

#include "pneuma/mesh/regions.h"

namespace pneuma::mesh {

std::vector<double> depth_below_convex_hull(const std::vector<Eigen::Vector3d>& points) {
  using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Point = Kernel::Point_3;
  std::vector<Point> cgal_points;
  cgal_points.reserve(points.size());
  for (const auto& p : points) cgal_points.emplace_back(p.x(), p.y(), p.z());
  CGAL::Surface_mesh<Point> hull;
  CGAL::convex_hull_3(cgal_points.begin(), cgal_points.end(), hull);
  // Outward unit normal and offset of every hull face: inside, depth = min over faces (offset - n.x).
  std::vector<std::pair<Eigen::Vector3d, double>> planes;
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
    // internal order, and so is every depth (a min over the planes).
    const auto first = std::min_element(v.begin(), v.end(), [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
      return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
    });
    std::rotate(v.begin(), first, v.end());
    const Eigen::Vector3d n = (v[1] - v[0]).cross(v[2] - v[0]);
    const double len = n.norm();
    if (len == 0.0) continue;
    planes.emplace_back(n / len, n.dot(v[0]) / len);
  }
  std::vector<double> depth(points.size(), 0.0);
  if (planes.empty()) return depth;
  for (std::size_t i = 0; i < points.size(); ++i) {
    double d = std::numeric_limits<double>::infinity();
    for (const auto& [n, offset] : planes) d = std::min(d, offset - n.dot(points[i]));
    depth[i] = std::max(0.0, d);
  }
  return depth;
}

}  // namespace pneuma::mesh
