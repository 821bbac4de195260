// The depth of points below the convex hull of a point set (CGAL convex_hull_3).
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/convex_hull_3.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>

#include "pneuma/core/tsan.h"
#include "pneuma/mesh/anatomy/regions.h"

namespace pneuma::mesh {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Face = std::array<std::size_t, 3>;

// The convex hull of a few points: its vertices (copies) and outward faces.
void hull_of(const std::vector<Point>& points, std::vector<Point>& vertices, std::vector<Face>& faces) {
  vertices.clear();
  faces.clear();
  if (points.empty()) return;
  // Into index arrays (no halfedge graph, no hash maps), with the traits that filter the plane
  // tests on point triples (CGAL's default for an indexed output constructs inexact planes).
  CGAL::Convex_hull_3::internal::Indexed_triangle_set<std::vector<Point>, std::vector<Face>> out(vertices, faces);
  CGAL::convex_hull_3(points.begin(), points.end(), out,
                      CGAL::Convex_hull_traits_3<Kernel, CGAL::Default, CGAL::Tag_true>());
}

// The points that can be corners of the hull (Akl-Toussaint): the hull of the points extreme
// along a fixed set of directions is a polytope inside the whole hull, so a point strictly
// inside it (by more than any rounding of the test) is no corner and is left out of the hull.
// On a lung surface that drops the concave faces' points; the convex ones stay (they are the
// hull's corners). The hull of the rest is the same hull, so every depth is the same.
std::vector<Point> possible_corners(const std::vector<Eigen::Vector3d>& points) {
  constexpr std::size_t kDirections = 64;  // a Fibonacci sphere
  std::vector<Eigen::Vector3d> direction(kDirections);
  for (std::size_t k = 0; k < kDirections; ++k) {
    const double z = 1.0 - (2.0 * static_cast<double>(k) + 1.0) / static_cast<double>(kDirections);
    const double r = std::sqrt(1.0 - z * z), phi = 2.399963229728653 * static_cast<double>(k);
    direction[k] = Eigen::Vector3d(r * std::cos(phi), r * std::sin(phi), z);
  }
  // The most extreme point along each direction, the lowest index on a tie (any split of the
  // range gives the same answer).
  using Best = std::array<std::pair<double, std::size_t>, kDirections>;
  Best none;
  none.fill({-std::numeric_limits<double>::infinity(), 0});
  const tsan::Region extremes;  // TBB's own synchronisation, told to ThreadSanitizer (core/tsan.h)
  const Best best =
      tbb::parallel_reduce(tbb::blocked_range<std::size_t>(0, points.size(), 4096), none,
                           extremes.wrap([&](const tbb::blocked_range<std::size_t>& range, Best b) {
                             for (std::size_t i = range.begin(); i < range.end(); ++i) {
                               for (std::size_t k = 0; k < kDirections; ++k) {
                                 const double d = direction[k].dot(points[i]);
                                 if (d > b[k].first) b[k] = {d, i};
                               }
                             }
                             return b;
                           }),
                           extremes.wrap([](Best a, const Best& b) {
                             for (std::size_t k = 0; k < kDirections; ++k) {
                               if (b[k].first > a[k].first || (b[k].first == a[k].first && b[k].second < a[k].second))
                                 a[k] = b[k];
                             }
                             return a;
                           }));
  extremes.join();
  std::vector<std::size_t> extreme;
  for (const auto& [value, index] : best) extreme.push_back(index);
  std::sort(extreme.begin(), extreme.end());
  extreme.erase(std::unique(extreme.begin(), extreme.end()), extreme.end());
  std::vector<Point> seeds;
  seeds.reserve(extreme.size());
  for (std::size_t i : extreme) seeds.emplace_back(points[i].x(), points[i].y(), points[i].z());
  std::vector<Point> corners;
  std::vector<Face> faces;
  hull_of(seeds, corners, faces);
  // Outward unit planes of the inner polytope, and a margin far above the rounding of n.x - c
  // (coordinates of a lung in metres: rounding ~1e-17 m) and far below any mesh spacing.
  std::vector<std::pair<Eigen::Vector3d, double>> planes;
  double scale = 0.0;
  for (const auto& p : points) scale = std::max(scale, p.cwiseAbs().maxCoeff());
  for (const Face& f : faces) {
    auto at = [&](std::size_t k) {
      const Point& q = corners[f[k]];
      return Eigen::Vector3d(q.x(), q.y(), q.z());
    };
    const Eigen::Vector3d n = (at(1) - at(0)).cross(at(2) - at(0));
    if (n.norm() > 0.0) planes.emplace_back(n.normalized(), n.normalized().dot(at(0)));
  }
  const double margin = 1e-9 * std::max(scale, 1.0);
  // A flat inner polytope (the seeds in one plane) has no inside: keep every point.
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const Point& q : corners) centre += Eigen::Vector3d(q.x(), q.y(), q.z());
  centre /= static_cast<double>(std::max<std::size_t>(corners.size(), 1));
  const bool solid = planes.size() >= 4 && std::all_of(planes.begin(), planes.end(), [&](const auto& plane) {
                       return plane.first.dot(centre) - plane.second < -margin;
                     });
  std::vector<char> keep(points.size(), 1);
  if (solid) {
    const tsan::Region region;  // TBB's own synchronisation, told to ThreadSanitizer (core/tsan.h)
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 4096),
                      region.wrap([&](const tbb::blocked_range<std::size_t>& range) {
                        for (std::size_t i = range.begin(); i < range.end(); ++i) {
                          bool inside = true;
                          for (const auto& [n, offset] : planes) {
                            if (n.dot(points[i]) - offset > -margin) {
                              inside = false;
                              break;
                            }
                          }
                          keep[i] = inside ? 0 : 1;
                        }
                      }));
    region.join();
  }
  std::vector<Point> out;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (keep[i]) out.emplace_back(points[i].x(), points[i].y(), points[i].z());
  }
  return out;
}

}  // namespace

using Iterator = std::vector<Kernel::Triangle_3>::const_iterator;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, CGAL::AABB_triangle_primitive<Kernel, Iterator>>>;

struct ConvexHullDepth::Impl {
  std::vector<Kernel::Triangle_3> triangles;
  std::vector<std::pair<Eigen::Vector3d, double>> planes;  // per face: outward unit normal, offset
  std::vector<std::array<double, 3>> corners;              // the hull's vertices, sorted
  std::unique_ptr<Tree> tree;                              // null: no hull (flat or empty)
};

ConvexHullDepth::ConvexHullDepth(const std::vector<Eigen::Vector3d>& points) : impl_(std::make_unique<Impl>()) {
  std::vector<Point> hull_points;
  std::vector<Face> hull_faces;
  hull_of(possible_corners(points), hull_points, hull_faces);
  if (hull_faces.empty()) return;
  // Outward unit normal and offset of every hull face. Inside a convex polytope the depth,
  // min over faces of (offset - n.x), is the distance to the nearest face, whose plane gives it:
  // so the nearest face is found with an AABB tree (log of the faces per point, where a loop over
  // every plane took minutes at 10^5 points: a fine, mostly convex surface has 10^5 hull faces).
  // A degenerate face keeps the zero plane: the depth below it is 0 (the point is on the surface).
  auto& planes = impl_->planes;
  auto& triangles = impl_->triangles;
  planes.assign(hull_faces.size(), {Eigen::Vector3d::Zero(), 0.0});
  triangles.reserve(hull_faces.size());
  for (std::size_t f = 0; f < hull_faces.size(); ++f) {
    const Face& face = hull_faces[f];
    triangles.emplace_back(hull_points[face[0]], hull_points[face[1]], hull_points[face[2]]);
    std::array<Eigen::Vector3d, 3> v;
    for (std::size_t k = 0; k < 3; ++k) {
      const Point& q = hull_points[face[k]];
      v[k] = Eigen::Vector3d(q.x(), q.y(), q.z());
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
    planes[f] = {n / len, n.dot(v[0]) / len};
  }
  // The hull's vertices are input points (copies): their depth is 0, no query needed. On a fine,
  // mostly convex surface that is most of them.
  impl_->corners.reserve(hull_points.size());
  for (const Point& p : hull_points) impl_->corners.push_back({p.x(), p.y(), p.z()});
  std::sort(impl_->corners.begin(), impl_->corners.end());
  impl_->tree = std::make_unique<Tree>(triangles.cbegin(), triangles.cend());
  impl_->tree->accelerate_distance_queries();  // built here: queries from several threads only read it
}

ConvexHullDepth::~ConvexHullDepth() = default;

std::vector<double> ConvexHullDepth::depth(const std::vector<Eigen::Vector3d>& queries) const {
  std::vector<double> depth(queries.size(), 0.0);
  if (!impl_->tree) return depth;
  const Impl& h = *impl_;
  const tsan::Region region;
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, queries.size(), 256),
      region.wrap([&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t i = range.begin(); i < range.end(); ++i) {
          const Eigen::Vector3d& q = queries[i];
          if (std::binary_search(h.corners.begin(), h.corners.end(), std::array<double, 3>{q.x(), q.y(), q.z()}))
            continue;
          const Iterator face = h.tree->closest_point_and_primitive(Point(q.x(), q.y(), q.z())).second;
          const auto& [n, offset] = h.planes[static_cast<std::size_t>(face - h.triangles.cbegin())];
          depth[i] = std::max(0.0, offset - n.dot(q));
        }
      }));
  region.join();
  return depth;
}

std::vector<double> depth_below_convex_hull(const std::vector<Eigen::Vector3d>& points,
                                            const std::vector<Eigen::Vector3d>& queries) {
  return ConvexHullDepth(points).depth(queries);
}

}  // namespace pneuma::mesh
