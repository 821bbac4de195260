#include "pneuma/field/field.h"

#include <chrono>
#include <cmath>
#include <memory>

#include "pneuma/core/error.h"
#include "pneuma/core/parameters.h"
#include "pneuma/core/stopwatch.h"
#include "pneuma/field/thin_lung.h"

namespace pneuma::field {

const char* direction_name(DirectionKind kind) {
  switch (kind) {
    case DirectionKind::vertex_normal: return "vertex_normal";
    case DirectionKind::smoothed_normal: return "smoothed_normal";
    case DirectionKind::anatomical: return "anatomical";
  }
  return "vertex_normal";
}

DirectionKind parse_direction_kind(const std::string& name) {
  for (DirectionKind k : {DirectionKind::vertex_normal, DirectionKind::smoothed_normal, DirectionKind::anatomical}) {
    if (name == direction_name(k)) return k;
  }
  throw ValueError("unknown displacement direction '" + name + "'");
}

namespace {

// The surface's regions for these options: the ones given (checked), else found here.
std::shared_ptr<const mesh::SurfaceRegions> regions_for(const mesh::TriangleMesh& mesh, const FieldOptions& options,
                                                        const char* who, const mesh::SurfaceProxy* proxy) {
  if (options.regions) {
    mesh::require_regions_of(*options.regions, mesh, options.axes, who);
    return options.regions;
  }
  mesh::RegionOptions regions;
  regions.axes = options.axes;
  return std::make_shared<const mesh::SurfaceRegions>(mesh::find_regions(mesh, regions, proxy));
}

// The directions from the normals smoothed at options.direction_smoothing, when computed already.
std::vector<Eigen::Vector3d> directions_from(const mesh::TriangleMesh& mesh, const FieldOptions& options,
                                             const std::vector<Eigen::Vector3d>& smoothed,
                                             const mesh::SurfaceProxy* proxy) {
  switch (options.direction) {
    case DirectionKind::vertex_normal: return mesh::vertex_normals(mesh);
    case DirectionKind::smoothed_normal: return smoothed;
    case DirectionKind::anatomical:
      return mesh::anatomical_directions(mesh, *regions_for(mesh, options, "displacement_directions", proxy), smoothed);
  }
  return mesh::vertex_normals(mesh);
}

}  // namespace

std::vector<Eigen::Vector3d> displacement_directions(const mesh::TriangleMesh& mesh, const FieldOptions& options) {
  if (options.direction == DirectionKind::vertex_normal) return mesh::vertex_normals(mesh);
  return directions_from(mesh, options, mesh::smoothed_normals(mesh, options.proxy.get(), options.direction_smoothing),
                         options.proxy.get());
}

std::pair<std::vector<Eigen::Vector3d>, double> normalise_displacement(const mesh::TriangleMesh& mesh,
                                                                       std::span<const double> force,
                                                                       double area_unit) {
  const std::vector<Eigen::Vector3d> normal = mesh::vertex_normals(mesh);
  return normalise_displacement(mesh, force, normal, area_unit);
}

namespace {
// normalise_displacement() with the area gradient given (compute_field reads it twice).
std::pair<std::vector<Eigen::Vector3d>, double> normalised_along(std::span<const double> force,
                                                                 std::span<const Eigen::Vector3d> normal,
                                                                 double area_unit,
                                                                 const std::vector<Eigen::Vector3d>& gradient) {
  double area_rate = 0.0;  // dA/ds of x + s F n
  for (std::size_t i = 0; i < normal.size(); ++i) area_rate += force[i] * gradient[i].dot(normal[i]);
  if (!(area_rate > 0.0) || !std::isfinite(area_rate))
    throw UnsupportedError("mesh: pushing every vertex outward along its displacement direction does not increase "
                           "the surface area (is the mesh oriented with its normals outward?)");
  const double scale = area_unit / area_rate;
  std::vector<Eigen::Vector3d> u(normal.size());
  for (std::size_t i = 0; i < normal.size(); ++i) u[i] = (scale * force[i]) * normal[i];
  return {std::move(u), scale};
}
}  // namespace

std::pair<std::vector<Eigen::Vector3d>, double> normalise_displacement(const mesh::TriangleMesh& mesh,
                                                                       std::span<const double> force,
                                                                       std::span<const Eigen::Vector3d> normal,
                                                                       double area_unit) {
  return normalised_along(force, normal, area_unit, mesh::area_gradient(mesh));
}

ElastostaticField compute_field(const mesh::TriangleMesh& mesh, std::span<const double> shear_modulus_pa,
                                const FieldOptions& options) {
  const auto start = Clock::now();
  // The rules every door (YAML, CLI, Python) applies, from the one table (core/parameters.h).
  if (const auto why = parameters::kFieldTolerance.check(options.tolerance))
    throw ValueError("field tolerance: " + *why);
  if (const auto why = parameters::kAreaUnit.check(options.area_unit)) throw ValueError("field area unit: " + *why);
  if (!(options.direction_smoothing > 0.0)) throw ValueError("field direction smoothing must be positive");
  if (!(options.magnitude_smoothing >= 0.0) || !std::isfinite(options.magnitude_smoothing))
    throw ValueError("field magnitude smoothing must be zero or positive");
  const auto shared_graph = std::make_shared<const FieldGraph>(mesh, shear_modulus_pa);
  const FieldGraph& graph = *shared_graph;
  std::shared_ptr<const TransferOperator> op;  // null: one hop
  if (options.clique_hops != 1) {
    if (options.solver == SolverKind::cg)
      throw UnsupportedError("the cg solver needs a clique of 1 hop; use shot, sweep or direct for larger cliques");
    op = std::make_shared<const TransferOperator>(clique_operator(graph, options.clique_hops, options.path_rule));
  }
  const SolveOptions solve_options{options.tolerance};
  const std::unique_ptr<FieldSolver> solver = make_field_solver(options.solver, shared_graph, op, solve_options);
  ElastostaticField field;
  field.mass_nodes = graph.mass_count();
  field.spring_nodes = graph.spring_count();
  field.graph_seconds = seconds_since(start);

  // The pressure load: the same force on every mass node (paper section 5), none on springs.
  std::vector<double> load(options.solver == SolverKind::cg ? graph.mass_count() : graph.node_count(), 0.0);
  if (options.load.empty()) {
    std::fill(load.begin(), load.begin() + graph.mass_count(), 1.0);
  } else {
    if (options.load.size() != graph.mass_count()) throw ValueError("field load: one value per vertex");
    std::copy(options.load.begin(), options.load.end(), load.begin());
  }
  SolveResult result = solver->solve(load);
  field.report = std::move(result.report);
  field.force.assign(result.shot.begin(), result.shot.begin() + graph.mass_count());
  if (options.magnitude_smoothing > 0.0)
    field.force = mesh::blurred_in_space(mesh, field.force, options.magnitude_smoothing);
  // The normals smoothed at the direction smoothing, computed once for every rule that reads them
  // (the directions, the slide, the heart's descent): each computed its own before (#50).
  const bool realistic = options.sliding.active() || options.heart.active();
  const bool smooth = options.direction != DirectionKind::vertex_normal || realistic;
  // A fine surface's proxy (with_tissue's, else built here): where those rules read the surface.
  std::shared_ptr<const mesh::SurfaceProxy> proxy = options.proxy;
  if (proxy && proxy->group.size() != mesh.vertices.size())
    throw ValueError("compute_field: the proxy given is of another surface");
  if (!proxy && smooth) proxy = mesh::proxy_for(mesh);
  const std::vector<Eigen::Vector3d> smoothed =
      smooth ? mesh::smoothed_normals(mesh, proxy.get(), options.direction_smoothing) : std::vector<Eigen::Vector3d>{};
  const std::vector<Eigen::Vector3d> direction = directions_from(mesh, options, smoothed, proxy.get());
  const std::vector<Eigen::Vector3d> gradient = mesh::area_gradient(mesh);
  auto [u, scale] = normalised_along(field.force, direction, options.area_unit, gradient);
  if (realistic) {
    // The slide and the heart's descent in units of this field's own diaphragm descent, so they
    // follow the load; then the whole field scaled back to one area unit.
    const auto regions = regions_for(mesh, options, "compute_field", proxy.get());
    const double descent = mesh::diaphragm_descent(mesh, *regions, u);
    if (options.sliding.active()) {
      const std::vector<Eigen::Vector3d> slide = mesh::sliding_field(mesh, *regions, options.sliding, smoothed);
      for (std::size_t i = 0; i < u.size(); ++i) u[i] += descent * slide[i];
    }
    if (options.heart.active()) {
      const std::vector<Eigen::Vector3d> heart = heart_descent_field(mesh, *regions, options.heart, smoothed);
      for (std::size_t i = 0; i < u.size(); ++i) u[i] += descent * heart[i];
      // The 3 mm normals, computed once for the recess rule and the thin lung's rays.
      const std::vector<Eigen::Vector3d> face_normal = mesh::smoothed_normals(mesh, proxy.get(), kFaceNormalSigma);
      // With a slide the costal face at the margin already descends with the diaphragm.
      follow_the_diaphragm_over(mesh, *regions, u, options.sliding.active() ? Margin::kept : Margin::moved,
                                face_normal);
      // The diaphragm's faces (and the heart's) move by their own rules; where the lung between
      // two of them is thin it is not stretched across its thickness more than the lung breathes.
      if (proxy) limit_the_stretch_across_thin_lung(mesh, *proxy, u, {}, face_normal);
      else limit_the_stretch_across_thin_lung(mesh, u, {}, face_normal);
    }
    double area_rate = 0.0;
    for (std::size_t i = 0; i < u.size(); ++i) area_rate += gradient[i].dot(u[i]);
    if (!(area_rate > 0.0) || !std::isfinite(area_rate))
      throw UnsupportedError("mesh: the field with the lung's slide does not increase the surface area");
    const double again = options.area_unit / area_rate;
    for (Eigen::Vector3d& v : u) v *= again;
    scale *= again;
  }
  field.unit_displacement = std::move(u);
  field.normalisation = scale;
  return field;
}

}  // namespace pneuma::field
