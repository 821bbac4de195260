// remesh(): CGAL isotropic_remeshing on a Surface_mesh, with an optional deviation measure.
#include <CGAL/AABB_face_graph_triangle_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/Polygon_mesh_processing/remesh.h>

#include <cmath>

#include "pneuma/core/error.h"
#include "pneuma/mesh/cgal/cgal_surface_mesh.h"
#include "pneuma/mesh/repair/remesh.h"

namespace PMP = CGAL::Polygon_mesh_processing;

namespace pneuma::mesh {
namespace {

using detail::Kernel;
using detail::SurfaceMesh;

double max_distance_to(const SurfaceMesh& reference, const TriangleMesh& mesh) {
  using Primitive = CGAL::AABB_face_graph_triangle_primitive<SurfaceMesh>;
  using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;
  Tree tree(faces(reference).first, faces(reference).second, reference);
  tree.accelerate_distance_queries();
  double max_sq = 0.0;
  for (const auto& p : mesh.vertices) max_sq = std::max(max_sq, tree.squared_distance(detail::to_point(p)));
  for (const Triangle& t : mesh.triangles) {
    const Eigen::Vector3d c = (mesh.vertices[t[0]] + mesh.vertices[t[1]] + mesh.vertices[t[2]]) / 3.0;
    max_sq = std::max(max_sq, tree.squared_distance(detail::to_point(c)));
  }
  return std::sqrt(max_sq);
}

}  // namespace

RemeshResult remesh_isotropic(const TriangleMesh& mesh, const RemeshOptions& options) {
  if (!(options.target_edge_length_m > 0.0) || !std::isfinite(options.target_edge_length_m)) {
    throw ValueError("remesh: the target edge length must be positive");
  }
  std::optional<SurfaceMesh> input = detail::to_surface_mesh(mesh);
  if (!input) throw ValueError("remesh: the input is not a manifold triangle mesh");
  RemeshResult result;
  result.before = measure_quality(mesh);
  SurfaceMesh sm = *input;
  // Borders (there are none on a valid, closed input) would be kept in place.
  PMP::isotropic_remeshing(
      faces(sm), options.target_edge_length_m, sm,
      PMP::parameters::number_of_iterations(options.iterations).protect_constraints(false).relax_constraints(false));
  result.mesh = detail::from_surface_mesh(sm);
  result.after = measure_quality(result.mesh);
  if (options.measure_deviation) result.max_deviation_m = max_distance_to(*input, result.mesh);
  return result;
}

}  // namespace pneuma::mesh
