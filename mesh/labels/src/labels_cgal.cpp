// The 0.5 level set of a smoothed label mask, meshed by CGAL Mesh_3 (Delaunay refinement of
// an implicit surface with manifold topology criteria). The only translation unit that
// includes Mesh_3 (slow to compile). Sequential and seeded (the domain's random generator is
// CGAL::Random(0)): deterministic.
#include <CGAL/Labeled_mesh_domain_3.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/facets_in_complex_3_to_triangle_mesh.h>
#include <CGAL/make_mesh_3.h>

#include <cmath>

#include "pneuma/mesh/cgal/cgal_surface_mesh.h"
#include "pneuma/mesh/labels/labels.h"

namespace pneuma::mesh::detail {
namespace {

using K = Kernel;
using Domain = CGAL::Labeled_mesh_domain_3<K>;
using Tr = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr>;
using Criteria = CGAL::Mesh_criteria_3<Tr>;

// Mesh_3 works in millimetres (criteria and error bounds of order 1); the grid maps metres.
constexpr double kMm = 1e-3;

// f(p) < 0 inside: 0.5 minus the trilinear interpolation of the field (0 outside the grid).
class LevelSet {
 public:
  explicit LevelSet(const ScalarGrid& grid) : grid_(grid), to_index_(grid.lps_to_index) {
    to_index_.block<3, 3>(0, 0) *= kMm;  // points arrive in mm
  }
  double operator()(const K::Point_3& p) const {
    const Eigen::Vector4d q = to_index_ * Eigen::Vector4d(p.x(), p.y(), p.z(), 1.0);
    return 0.5 - sample(q.x(), q.y(), q.z());
  }

 private:
  double sample(double x, double y, double z) const {
    const auto& n = grid_.size;
    if (!(x >= 0.0 && y >= 0.0 && z >= 0.0)) return 0.0;
    const double fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
    const auto i = static_cast<std::size_t>(fx), j = static_cast<std::size_t>(fy), k = static_cast<std::size_t>(fz);
    if (i + 1 >= n[0] || j + 1 >= n[1] || k + 1 >= n[2]) return 0.0;  // the border of the crop is background
    const double tx = x - fx, ty = y - fy, tz = z - fz;
    const float* v = grid_.values.data() + i + n[0] * (j + n[1] * k);
    const std::size_t sy = n[0], sz = n[0] * n[1];
    auto lerp = [](double a, double b, double t) { return a + (b - a) * t; };
    const double c00 = lerp(v[0], v[1], tx), c10 = lerp(v[sy], v[sy + 1], tx);
    const double c01 = lerp(v[sz], v[sz + 1], tx), c11 = lerp(v[sz + sy], v[sz + sy + 1], tx);
    return lerp(lerp(c00, c10, ty), lerp(c01, c11, ty), tz);
  }

  const ScalarGrid& grid_;
  Eigen::Matrix4d to_index_;
};

}  // namespace

TriangleMesh mesh_level_set(const ScalarGrid& grid, double edge_length_m, double max_distance_m) {
  // The bounding sphere: around the crop's box (in mm), where the field is 0 (outside).
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector4d ijk((c & 1) ? static_cast<double>(grid.size[0] - 1) : 0.0,
                              (c & 2) ? static_cast<double>(grid.size[1] - 1) : 0.0,
                              (c & 4) ? static_cast<double>(grid.size[2] - 1) : 0.0, 1.0);
    const Eigen::Vector3d p = (grid.index_to_lps * ijk).head<3>() / kMm;
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  const double radius = 0.5 * (hi - lo).norm() + 1.0;

  CGAL::Random rng(0);
  Domain domain = Domain::create_implicit_mesh_domain(
      LevelSet(grid), K::Sphere_3(K::Point_3(centre.x(), centre.y(), centre.z()), radius * radius),
      CGAL::parameters::relative_error_bound = 1e-6, CGAL::parameters::p_rng = &rng);
  Criteria criteria(CGAL::parameters::facet_angle = 30.0, CGAL::parameters::facet_size = edge_length_m / kMm,
                    CGAL::parameters::facet_distance = max_distance_m / kMm,
                    CGAL::parameters::facet_topology = CGAL::FACET_VERTICES_ON_SURFACE);
  const C3t3 c3t3 = CGAL::make_mesh_3<C3t3>(domain, criteria, CGAL::parameters::no_perturb(),
                                            CGAL::parameters::no_exude(), CGAL::parameters::manifold());
  SurfaceMesh sm;
  CGAL::facets_in_complex_3_to_triangle_mesh(c3t3, sm);
  TriangleMesh mesh = from_surface_mesh(sm);
  for (auto& v : mesh.vertices) v *= kMm;
  return mesh;
}

}  // namespace pneuma::mesh::detail
