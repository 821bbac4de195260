#include "pneuma/field/tissue.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "pneuma/core/error.h"

namespace pneuma::field {
namespace {

// The surface's anatomical regions in the tissue's body axes (mesh::find_regions).
mesh::SurfaceRegions regions_of(const Tissue& tissue, const mesh::TriangleMesh& mesh,
                                const mesh::SurfaceProxy* proxy = nullptr) {
  mesh::RegionOptions options;
  options.axes = body_axes(tissue);
  return mesh::find_regions(mesh, options, proxy);
}

// Each vertex's height along the posture's dependent direction (metres), and their range.
struct Heights {
  std::vector<double> at_m;
  double lo_m = 0.0, hi_m = 0.0;
};
Heights dependent_heights(const Tissue& tissue, const mesh::TriangleMesh& mesh) {
  const Eigen::Vector3d d = dependent_direction(tissue);
  Heights h{std::vector<double>(mesh.vertices.size()), std::numeric_limits<double>::infinity(),
            -std::numeric_limits<double>::infinity()};
  for (std::size_t i = 0; i < h.at_m.size(); ++i) {
    h.at_m[i] = d.dot(mesh.vertices[i]);
    h.lo_m = std::min(h.lo_m, h.at_m[i]);
    h.hi_m = std::max(h.hi_m, h.at_m[i]);
  }
  return h;
}

// 0 at the most non-dependent vertex, 1 at the most dependent (all 0 if flat).
std::vector<double> dependent_position(Heights h) {
  for (double& v : h.at_m) v = h.hi_m > h.lo_m ? (v - h.lo_m) / (h.hi_m - h.lo_m) : 0.0;
  return std::move(h.at_m);
}

}  // namespace

Eigen::Vector3d dependent_direction(const Tissue& tissue) {
  switch (tissue.posture) {
    case Posture::upright: return -tissue.up;
    case Posture::supine: return -tissue.anterior;
    case Posture::prone: return tissue.anterior;
  }
  return -tissue.up;
}

std::vector<double> dependent_position(const Tissue& tissue, const mesh::TriangleMesh& mesh) {
  return dependent_position(dependent_heights(tissue, mesh));
}

std::vector<double> shear_modulus_per_vertex(const Tissue& tissue, const mesh::TriangleMesh& mesh,
                                             const mesh::SurfaceRegions* known_regions) {
  const std::size_t n = mesh.vertices.size();
  auto check_count = [n](std::size_t got, const std::string& source, const char* what) {
    if (got != n)
      throw InputError(source + ": expected " + std::to_string(n) + " " + what + " (one per mesh vertex), got " +
                       std::to_string(got));
  };
  if (const auto* g = std::get_if<GradientStiffness>(&tissue.stiffness)) {
    const std::vector<double> position = dependent_position(tissue, mesh);
    std::vector<double> mu(n);
    for (std::size_t i = 0; i < n; ++i) {
      const double x = position[i];
      mu[i] = g->profile == GradientStiffness::Profile::linear
                  ? g->nondependent_pa + x * (g->dependent_pa - g->nondependent_pa)
                  : g->nondependent_pa * std::pow(g->dependent_pa / g->nondependent_pa, x);
      for (const StiffnessBand& b : g->bands) {
        if (x >= b.from && x <= b.to) mu[i] = b.shear_modulus_pa;
      }
    }
    return mu;
  }
  if (const auto* p = std::get_if<PerVertexStiffness>(&tissue.stiffness)) {
    check_count(p->shear_modulus_pa.size(), p->source, "values");
    return p->shear_modulus_pa;
  }
  const auto& r = std::get<RegionStiffness>(tissue.stiffness);
  std::vector<double> mu(n);
  if (r.anatomical) {
    std::optional<mesh::SurfaceRegions> found;  // only where none were given: no copy of given ones
    if (known_regions) mesh::require_regions_of(*known_regions, mesh, body_axes(tissue), "shear_modulus_per_vertex");
    const mesh::SurfaceRegions& regions = known_regions ? *known_regions : found.emplace(regions_of(tissue, mesh));
    std::array<double, mesh::kRegionCount> log_mu{};
    for (mesh::Region region : mesh::kRegions)
      log_mu[static_cast<std::size_t>(region)] =
          std::log(r.shear_modulus_pa.at(std::string(mesh::region_name(region))));
    for (std::size_t i = 0; i < n; ++i) {
      double sum = 0.0;
      for (std::size_t k = 0; k < mesh::kRegionCount; ++k) sum += regions.weight[i][k] * log_mu[k];
      mu[i] = std::exp(sum);
    }
  } else {
    check_count(r.labels.size(), r.source, "labels");
    for (std::size_t i = 0; i < n; ++i) mu[i] = r.shear_modulus_pa.at(r.labels[i]);
  }
  if (r.gravity_nondependent != 1.0 || r.gravity_dependent != 1.0) {
    const std::vector<double> factor =
        gravity_factor(tissue, mesh, r.gravity_nondependent, r.gravity_dependent, r.gravity_depth_m);
    for (std::size_t i = 0; i < n; ++i) {
      if (!(factor[i] > 0.0))
        throw InputError(tissue.name +
                         ": stiffness.gravity.depth: the lung is too deep for these factors (the "
                         "modulus reaches 0 at its " +
                         (r.gravity_dependent < r.gravity_nondependent ? "dependent" : "non-dependent") + " end)");
      mu[i] *= factor[i];
    }
  }
  return mu;
}

std::vector<double> gravity_factor(const Tissue& tissue, const mesh::TriangleMesh& mesh, double a, double b,
                                   double depth_m) {
  Heights heights = dependent_heights(tissue, mesh);
  const double lo = heights.lo_m, hi = heights.hi_m;
  std::vector<double> factor = dependent_position(std::move(heights));
  if (!(depth_m > 0.0)) {
    for (double& x : factor) x = a + x * (b - a);
    return factor;
  }
  // The same gradient per metre on any lung: its depth along the axis scales the span a..b.
  const double span = hi > lo ? (hi - lo) / depth_m : 0.0;
  for (double& x : factor) x = std::max(0.0, 0.5 * (a + b) + (x - 0.5) * span * (b - a));
  return factor;
}

std::vector<double> load_gravity_factor(const Tissue& tissue, const mesh::TriangleMesh& mesh) {
  return gravity_factor(tissue, mesh, tissue.load_nondependent, tissue.load_dependent, tissue.load_gravity_depth_m);
}

mesh::BodyAxes body_axes(const Tissue& tissue) {
  mesh::BodyAxes axes;
  axes.up = tissue.up;
  axes.anterior = tissue.anterior;
  return axes;
}

FieldOptions with_tissue(FieldOptions options, const Tissue& tissue, const mesh::TriangleMesh& mesh) {
  options.direction = tissue.direction;
  options.direction_smoothing = tissue.direction_smoothing_m;
  options.magnitude_smoothing = tissue.magnitude_smoothing_m;
  options.axes = body_axes(tissue);
  options.sliding = tissue.sliding;
  options.heart = tissue.heart;
  const auto* stiffness = std::get_if<RegionStiffness>(&tissue.stiffness);
  const bool needs_regions = tissue.regional_load || (stiffness && stiffness->anatomical) ||
                             tissue.direction == DirectionKind::anatomical || tissue.sliding.active() ||
                             tissue.heart.active();
  // A fine surface is read at several millimetres through its proxy (#50): built once here for
  // the regions and the field's smoothed normals and thin-lung rays.
  options.proxy = needs_regions || tissue.direction != DirectionKind::vertex_normal ? mesh::proxy_for(mesh) : nullptr;
  options.regions = needs_regions
                        ? std::make_shared<const mesh::SurfaceRegions>(regions_of(tissue, mesh, options.proxy.get()))
                        : nullptr;
  if (tissue.regional_load) {
    options.load = mesh::regional_load(mesh, *options.regions, *tissue.regional_load, tissue.dome_load);
    const std::vector<double> factor = load_gravity_factor(tissue, mesh);
    for (std::size_t i = 0; i < options.load.size(); ++i) options.load[i] *= factor[i];
  }
  return options;
}

TissueFieldInputs tissue_field_inputs(const mesh::TriangleMesh& mesh, const Tissue& tissue, const FieldOptions& given) {
  TissueFieldInputs inputs{tissue.name, with_tissue(given, tissue, mesh), {}};
  inputs.shear_modulus_pa = shear_modulus_per_vertex(tissue, mesh, inputs.options.regions.get());
  return inputs;
}

ElastostaticField compute_field(const mesh::TriangleMesh& mesh, const TissueFieldInputs& inputs) {
  return compute_field(mesh, inputs.shear_modulus_pa, inputs.options);
}

}  // namespace pneuma::field
