// CGAL answers for the runner: per-frame area, self-intersection, closest-point transfer; and
// for the field, the rays from the vertices to the face across (surface_hits.h).
#include "pneuma/mesh/geometry/surface_queries.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/box_intersection_d.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <optional>

#include "face_box_tree.h"
#include "pneuma/core/error.h"
#include "pneuma/core/tsan.h"
#include "pneuma/mesh/cgal/cgal_surface_mesh.h"
#include "pneuma/mesh/geometry/surface_hits.h"

namespace pneuma::mesh {
namespace {

// Slabs of the parallel self-intersection test (a fixed number: more than the cores of a usual
// machine, for balance; the answer does not depend on it).
constexpr std::size_t kSlabs = 16;

using detail::Kernel;
using detail::Point;
using detail::SurfaceMesh;
using detail::to_point;
namespace PMP = CGAL::Polygon_mesh_processing;

// Vertex i of `mesh` becomes vertex i of the Surface_mesh (indices are kept).
SurfaceMesh polygon_mesh_or_throw(const TriangleMesh& mesh) {
  std::optional<SurfaceMesh> sm = detail::to_surface_mesh(mesh);
  if (!sm) throw ValueError("the surface is not a polygon mesh (non-manifold edges or vertices); repair it first");
  return std::move(*sm);
}

// An AABB tree over the mesh's faces; the face a primitive stands for is its index in `triangles`.
// Built in place and never moved: the tree holds iterators into `triangles`.
struct FaceTree {
  using Triangle3 = Kernel::Triangle_3;
  using Iterator = std::vector<Triangle3>::const_iterator;
  using Primitive = CGAL::AABB_triangle_primitive<Kernel, Iterator>;
  using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;

  explicit FaceTree(const TriangleMesh& mesh) : triangles(soup(mesh)), tree(triangles.begin(), triangles.end()) {}
  FaceTree(const FaceTree&) = delete;
  FaceTree& operator=(const FaceTree&) = delete;

  std::size_t face(Iterator primitive) const { return static_cast<std::size_t>(primitive - triangles.begin()); }

  const std::vector<Triangle3> triangles;
  Tree tree;

 private:
  static std::vector<Triangle3> soup(const TriangleMesh& mesh) {
    std::vector<Triangle3> out;
    out.reserve(mesh.triangle_count());
    for (const auto& t : mesh.triangles)
      out.emplace_back(to_point(mesh.vertices[t[0]]), to_point(mesh.vertices[t[1]]), to_point(mesh.vertices[t[2]]));
    return out;
  }
};

// Whether the ray from `o` along `d` surely misses triangle (a, b, c) within `reach` (in units of
// |d|): Moller-Trumbore in doubles with a margin far above their rounding, so that only faces it
// cannot rule out go to CGAL's exact test (which costs several times more). Nearly parallel
// faces are never ruled out here.
bool clearly_missed(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& a,
                    const Eigen::Vector3d& b, const Eigen::Vector3d& c, double reach) {
  constexpr double kMargin = 1e-6;
  const Eigen::Vector3d e1 = b - a, e2 = c - a;
  const Eigen::Vector3d p = d.cross(e2);
  const double det = e1.dot(p);
  if (!(std::abs(det) > kMargin * e1.norm() * e2.norm() * d.norm())) return false;
  const Eigen::Vector3d s = o - a;
  const double u = s.dot(p) / det;
  const Eigen::Vector3d q = s.cross(e1);
  const double v = d.dot(q) / det;
  const double t = e2.dot(q) / det;
  return u < -kMargin || v < -kMargin || u + v > 1.0 + kMargin || t < -kMargin * reach || t > (1.0 + kMargin) * reach;
}

// A face's bounds in doubles (a CGAL Bbox_3's, exactly), for detail::segment_in_box.
struct FaceBox {
  std::array<double, 3> low;
  std::array<double, 3> high;
  FaceBox(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c)
      : low{std::min({a.x(), b.x(), c.x()}), std::min({a.y(), b.y(), c.y()}), std::min({a.z(), b.z(), c.z()})},
        high{std::max({a.x(), b.x(), c.x()}), std::max({a.y(), b.y(), c.y()}), std::max({a.z(), b.z(), c.z()})} {}
};

// The barycentric weights (of b, of c) of p in triangle (a, b, c), unclamped; none where the
// triangle is degenerate.
std::optional<std::array<double, 2>> barycentric_bc(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                                    const Eigen::Vector3d& c, const Eigen::Vector3d& p) {
  const Eigen::Vector3d v0 = b - a, v1 = c - a, v2 = p - a;
  const double d00 = v0.dot(v0), d01 = v0.dot(v1), d11 = v1.dot(v1), d20 = v2.dot(v0), d21 = v2.dot(v1);
  const double denominator = d00 * d11 - d01 * d01;
  if (!(denominator > 0.0)) return std::nullopt;
  return std::array<double, 2>{(d11 * d20 - d01 * d21) / denominator, (d00 * d21 - d01 * d20) / denominator};
}

// Every vertex of `mesh` once, in the order in which `faces` first name it, then those no face names.
std::vector<std::uint32_t> vertices_along(const TriangleMesh& mesh, const std::vector<std::uint32_t>& faces) {
  const std::size_t n = mesh.vertex_count();
  std::vector<std::uint32_t> order;
  order.reserve(n);
  std::vector<bool> placed(n, false);
  for (const std::uint32_t f : faces) {
    for (const std::uint32_t v : mesh.triangles[f]) {
      if (placed[v]) continue;
      placed[v] = true;
      order.push_back(v);
    }
  }
  for (std::size_t v = 0; v < n; ++v) {
    if (!placed[v]) order.push_back(static_cast<std::uint32_t>(v));
  }
  return order;
}

}  // namespace

struct AreaMeter::Impl {
  SurfaceMesh surface;
  std::vector<SurfaceMesh::Vertex_index> vertices;
};

AreaMeter::AreaMeter(const TriangleMesh& mesh) : impl_(std::make_unique<Impl>()) {
  impl_->surface = polygon_mesh_or_throw(mesh);
  for (std::size_t i = 0; i < mesh.vertex_count(); ++i) {
    impl_->vertices.emplace_back(static_cast<SurfaceMesh::size_type>(i));
  }
}

AreaMeter::~AreaMeter() = default;

double AreaMeter::area(const std::vector<Eigen::Vector3d>& positions) {
  for (std::size_t i = 0; i < impl_->vertices.size(); ++i) {
    const auto& p = positions[i];
    impl_->surface.point(impl_->vertices[i]) = Point(p.x(), p.y(), p.z());
  }
  return PMP::area(impl_->surface);
}

bool self_intersects(const TriangleMesh& mesh, Concurrency concurrency) {
  const SurfaceMesh surface = polygon_mesh_or_throw(mesh);
  if (concurrency == Concurrency::serial || mesh.triangle_count() < 2 * kSlabs) {
    return PMP::does_self_intersect<CGAL::Sequential_tag>(surface);
  }
  // Parallel: the faces are cut into kSlabs slabs along x (boundaries at quantiles of the face
  // centres, so the slabs hold about as many faces each); a face goes into every slab its x range
  // touches. Two intersecting faces overlap in x, so they share a slab, and CGAL's serial test
  // over that slab's faces (does_self_intersect on a face range; shared edges and vertices are
  // judged on the whole mesh) finds them. The slabs are tested in parallel; the first that finds
  // an intersection stops the others. The same yes/no answer as the serial test, with ~1x its
  // work in total (CGAL's own Parallel_tag version does several times the work: it shuffles the
  // boxes and intersects every pair of quarter ranges; measured slower on 2 cores).
  const std::size_t n = mesh.triangle_count();
  std::vector<double> low(n), high(n), centres(n);
  for (std::size_t f = 0; f < n; ++f) {
    const auto& t = mesh.triangles[f];
    const double a = mesh.vertices[t[0]].x(), b = mesh.vertices[t[1]].x(), c = mesh.vertices[t[2]].x();
    low[f] = std::min({a, b, c});
    high[f] = std::max({a, b, c});
    centres[f] = 0.5 * (low[f] + high[f]);
  }
  std::sort(centres.begin(), centres.end());
  std::array<double, kSlabs - 1> bounds;  // slab k holds x in [bounds[k-1], bounds[k]]
  for (std::size_t k = 1; k < kSlabs; ++k) bounds[k - 1] = centres[k * n / kSlabs];
  const auto slab = [&](double x) {
    return static_cast<std::size_t>(std::upper_bound(bounds.begin(), bounds.end(), x) - bounds.begin());
  };
  std::array<std::vector<SurfaceMesh::Face_index>, kSlabs> faces;
  for (std::size_t f = 0; f < n; ++f) {
    const SurfaceMesh::Face_index face(static_cast<SurfaceMesh::size_type>(f));
    for (std::size_t k = slab(low[f]), last = slab(high[f]); k <= last; ++k) faces[k].push_back(face);
  }
  std::atomic<bool> found{false};
  const tsan::Region region;
  tbb::parallel_for(std::size_t{0}, kSlabs, region.wrap([&](std::size_t k) {
    if (found.load(std::memory_order_relaxed)) return;
    if (PMP::does_self_intersect<CGAL::Sequential_tag>(faces[k], surface)) found.store(true);
  }));
  region.join();
  return found.load();
}

bool surfaces_intersect(const TriangleMesh& a, const TriangleMesh& b) {
  using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, std::size_t>;
  const auto face_box = [](const TriangleMesh& mesh, std::size_t f) {
    const auto& t = mesh.triangles[f];
    const Eigen::Vector3d lo = mesh.vertices[t[0]].cwiseMin(mesh.vertices[t[1]]).cwiseMin(mesh.vertices[t[2]]);
    const Eigen::Vector3d hi = mesh.vertices[t[0]].cwiseMax(mesh.vertices[t[1]]).cwiseMax(mesh.vertices[t[2]]);
    return CGAL::Bbox_3(lo.x(), lo.y(), lo.z(), hi.x(), hi.y(), hi.z());
  };
  const auto mesh_box = [&](const TriangleMesh& mesh) {
    CGAL::Bbox_3 box;  // empty
    for (std::size_t f = 0; f < mesh.triangle_count(); ++f) box += face_box(mesh, f);
    return box;
  };
  const CGAL::Bbox_3 box_a = mesh_box(a), box_b = mesh_box(b);
  // The faces that can meet the other surface: those whose box meets its box (closed boxes).
  const auto near = [&](const TriangleMesh& mesh, const CGAL::Bbox_3& other) {
    std::vector<Box> boxes;
    for (std::size_t f = 0; f < mesh.triangle_count(); ++f) {
      const CGAL::Bbox_3 box = face_box(mesh, f);
      if (CGAL::do_overlap(box, other)) boxes.emplace_back(box, f);
    }
    return boxes;
  };
  std::vector<Box> near_a = near(a, box_b), near_b = near(b, box_a);
  if (near_a.empty() || near_b.empty()) return false;
  const auto triangle = [](const TriangleMesh& mesh, std::size_t f) {
    const auto& t = mesh.triangles[f];
    const auto point = [&](std::uint32_t v) {
      return Point(mesh.vertices[v].x(), mesh.vertices[v].y(), mesh.vertices[v].z());
    };
    return Kernel::Triangle_3(point(t[0]), point(t[1]), point(t[2]));
  };
  struct Found {};  // stops the box intersection at the first pair
  try {
    CGAL::box_intersection_d(near_a.begin(), near_a.end(), near_b.begin(), near_b.end(),
                             [&](const Box& x, const Box& y) {
                               if (CGAL::do_intersect(triangle(a, x.info()), triangle(b, y.info()))) throw Found{};
                             });
  } catch (const Found&) {
    return true;
  }
  return false;
}

std::vector<Eigen::Vector3d> transfer_vertex_field(const TriangleMesh& source,
                                                   const std::vector<Eigen::Vector3d>& field,
                                                   const std::vector<Eigen::Vector3d>& targets) {
  FaceTree faces(source);
  faces.tree.accelerate_distance_queries();

  std::vector<Eigen::Vector3d> out(targets.size());
  for (std::size_t i = 0; i < targets.size(); ++i) {
    const auto [closest, primitive] = faces.tree.closest_point_and_primitive(to_point(targets[i]));
    const auto& t = source.triangles[faces.face(primitive)];
    // Barycentric coordinates of the closest point in its triangle (it lies in the triangle).
    const Eigen::Vector3d p(closest.x(), closest.y(), closest.z());
    const auto [wb, wc] = barycentric_bc(source.vertices[t[0]], source.vertices[t[1]], source.vertices[t[2]], p)
                              .value_or(std::array<double, 2>{0.0, 0.0});
    out[i] = (1.0 - wb - wc) * field[t[0]] + wb * field[t[1]] + wc * field[t[2]];
  }
  return out;
}

std::vector<SurfaceHit> first_hits_from_vertices(const TriangleMesh& mesh,
                                                 const std::vector<Eigen::Vector3d>& direction, double reach) {
  if (direction.size() != mesh.vertex_count()) throw ValueError("first_hits_from_vertices: one direction per vertex");
  if (!(reach > 0.0)) throw ValueError("first_hits_from_vertices: expected a positive reach");
  const detail::FaceBoxTree tree(mesh);

  // A ray's first crossing is looked for only among the faces whose boxes, grown by kMargin (far
  // above the rounding), a segment of the reach meets (a little longer, for rounding), and of
  // those only the ones a test in doubles cannot rule out; each crossing is CGAL's intersection
  // of the ray with that face, the nearest wins (on a tie, the lower face). The tree's leaves
  // come nearest first, and once a crossing is found the boxes the segment enters beyond it
  // (by more than kBeyond) are skipped: their faces cross farther, so they could not win.
  constexpr double kMargin = 1e-9;  // metres
  constexpr double kBeyond = 1e-9;  // metres, far above the rounding of a crossing's distance
  const double reach_looked = reach * (1.0 + 1e-9);
  std::vector<SurfaceHit> hits(mesh.vertex_count());
  // One ray: its segment and the nearest meeting so far.
  struct Ray {
    std::size_t i = 0;
    double reach_along = 0.0;  // in units of |direction[i]|
    Kernel::Ray_3 ray{Point(0, 0, 0), Point(1, 0, 0)};
    double nearest = std::numeric_limits<double>::infinity();
    Point crossing{0, 0, 0};
    bool crosses = false;  // false where the nearest meeting is along a face (the ray in its plane)
    std::size_t crossed = 0;
    double limit = 1.0;
  };
  using Packet = std::array<Eigen::Vector3d, detail::FaceBoxTree::kPacket>;
  // Ray from vertex i into lane r of a packet; false where it has no direction.
  const auto start = [&](Ray& r, std::size_t i, Eigen::Vector3d& from, Eigen::Vector3d& inverse) {
    const double length = direction[i].norm();
    if (!(length > 0.0)) return false;
    r = Ray{};
    r.i = i;
    from = mesh.vertices[i];
    r.reach_along = reach_looked / length;
    const Eigen::Vector3d along = r.reach_along * direction[i];
    for (int k = 0; k < 3; ++k) inverse[k] = 1.0 / along[k];  // +-inf along an axis it does not move
    r.ray = Kernel::Ray_3(to_point(from), to_point(from + direction[i]));
    r.crossing = r.ray.source();
    return true;
  };
  // Face f met by ray r's walk: the walk's new limit.
  const auto meet = [&](Ray& r, const Eigen::Vector3d& from, const Eigen::Vector3d& inverse, std::uint32_t f) {
    const std::size_t i = r.i;
    const auto& t = mesh.triangles[f];
    if (t[0] == i || t[1] == i || t[2] == i) return r.limit;  // the faces around this vertex
    const Eigen::Vector3d &a = mesh.vertices[t[0]], &b = mesh.vertices[t[1]], &c = mesh.vertices[t[2]];
    const FaceBox box(a, b, c);
    const auto [enter, leave] = detail::segment_in_box(box, from, inverse, 1.0, kMargin);
    if (enter > leave || clearly_missed(from, direction[i], a, b, c, r.reach_along)) return r.limit;
    const auto meeting = CGAL::intersection(r.ray, Kernel::Triangle_3(to_point(a), to_point(b), to_point(c)));
    if (!meeting) return r.limit;
    if (const Point* p = boost::get<Point>(&*meeting)) {
      const double d = CGAL::squared_distance(r.ray.source(), *p);
      if (d < r.nearest || (d == r.nearest && f < r.crossed)) {
        r.nearest = d;
        r.crossing = *p;
        r.crosses = true;
        r.crossed = f;
      }
    } else if (const auto* s = boost::get<Kernel::Segment_3>(&*meeting)) {
      const double d = std::min(CGAL::squared_distance(r.ray.source(), s->source()),
                                CGAL::squared_distance(r.ray.source(), s->target()));
      if (d < r.nearest) {
        r.nearest = d;
        r.crosses = false;
      }
    }
    r.limit = std::min(r.limit, (std::sqrt(r.nearest) + kBeyond) / reach_looked);
    return r.limit;
  };
  const auto finish = [&](const Ray& r) {
    if (!r.crosses) return;
    const std::size_t i = r.i;
    const Eigen::Vector3d p(r.crossing.x(), r.crossing.y(), r.crossing.z());
    const double distance = (p - mesh.vertices[i]).norm();
    if (distance > reach) return;
    const auto& t = mesh.triangles[r.crossed];
    const Eigen::Vector3d a = mesh.vertices[t[0]], b = mesh.vertices[t[1]], c = mesh.vertices[t[2]];
    const Eigen::Vector3d area_normal = (b - a).cross(c - a);
    if (!(area_normal.dot(direction[i]) > 0.0)) return;  // entering the surface: it started outside
    const auto weights = barycentric_bc(a, b, c, p);
    if (!weights) return;
    const double wb = std::clamp((*weights)[0], 0.0, 1.0);
    const double wc = std::clamp((*weights)[1], 0.0, 1.0 - wb);
    hits[i] = SurfaceHit{.found = true,
                         .distance = distance,
                         .face = static_cast<std::uint32_t>(r.crossed),
                         .weights = {1.0 - wb - wc, wb, wc}};
  };
  // The rays cast in the order of the tree's curve (each vertex where its first face comes), so
  // that consecutive rays walk the same nodes while they are in cache (the CT mesh's vertices
  // are in Mesh_3's order, scattered in space), kPacket neighbours walked together. Each ray's
  // answer is its own (the nearest meeting over the faces its segment's boxes reach, whatever
  // the order they come in): the packets and the thread count change no bit.
  const std::vector<std::uint32_t> order = vertices_along(mesh, tree.faces_along_curve());
  const auto cast = [&](std::size_t begin, std::size_t end) {
    std::array<Ray, detail::FaceBoxTree::kPacket> ray;
    Packet from, inverse;
    std::size_t next = begin;
    while (next < end) {
      std::size_t count = 0;
      while (count < detail::FaceBoxTree::kPacket && next < end) {
        if (start(ray[count], order[next++], from[count], inverse[count])) ++count;
      }
      tree.walk_packet(from, inverse, count, kMargin,
                       [&](std::size_t r, std::uint32_t f) { return meet(ray[r], from[r], inverse[r], f); });
      for (std::size_t r = 0; r < count; ++r) finish(ray[r]);
    }
  };
  const tsan::Region region;
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, order.size(), 1024),
      region.wrap([&](const tbb::blocked_range<std::size_t>& range) { cast(range.begin(), range.end()); }));
  region.join();
  return hits;
}

}  // namespace pneuma::mesh
