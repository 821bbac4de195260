#pragma once
// The elastostatic field: per-vertex displacement for one unit of surface-area increase
// (paper section 5; METHOD.md section 4).
//
//   load:        the same force f = 1 on every mass node (pressure), 0 on spring nodes
//   solve:       F = Shot (eq. 4.3 - 4.7) with the chosen solver and clique size
//   direction:   d_i, by default n_i, the outward area-weighted vertex normal (the paper's reading);
//                or the normal of the surface smoothed in space, or the anatomical direction field
//                (mesh/regions.h, docs/realism.md), which cannot close a crease
//   normalise:   u_i = c F_i n_i with c such that sum_i dA/dx_i . u_i = one area unit, i.e. the
//                first-order surface-area increase of x + s u is s area units.
//   slide:       optionally (FieldOptions::sliding), plus D_c * slide_i (mesh::sliding_field),
//                D_c the diaphragm's mean descent of c F d; and optionally (FieldOptions::heart)
//                plus D_c * heart_i, the face on the heart descending with it, and a face
//                under the diaphragm's slope (and, without a slide, a thin costophrenic margin)
//                moving with the surface around it (field/heart.h); all scaled again to one
//                area unit.
// Only relative moduli matter: multiplying every mu by a constant leaves u unchanged.
#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/field/field_graph.h"
#include "pneuma/field/field_solver.h"
#include "pneuma/field/heart.h"
#include "pneuma/mesh/anatomy/regions.h"
#include "pneuma/mesh/anatomy/sliding.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::field {

// The direction each vertex moves in (docs/realism.md).
enum class DirectionKind {
  vertex_normal,    // the area-weighted vertex normal (METHOD.md section 4, the reference)
  smoothed_normal,  // the outward normal blurred in space by a Gaussian (mesh::smoothed_normals)
  anatomical,       // diaphragm down, rib cage out, apex and mediastinum along the smoothed normal
};
const char* direction_name(DirectionKind kind);
// "vertex_normal", "smoothed_normal", "anatomical"; throws ValueError otherwise.
DirectionKind parse_direction_kind(const std::string& name);

struct FieldOptions {
  SolverKind solver = SolverKind::cg;  // the fastest (BENCHMARKS.md); `shot` is the paper's
  double tolerance = 1e-6;             // max |UnShot| <= tolerance * max f
  int clique_hops = 1;                 // M (cg supports 1 only)
  CliquePathRule path_rule = CliquePathRule::sum_of_shortest_paths;
  double area_unit = 1e-4;  // in the mesh's length unit squared: 1 cm^2 for a mesh in metres
  DirectionKind direction = DirectionKind::vertex_normal;
  double direction_smoothing = 0.02;  // Gaussian sigma of the smoothed normals, mesh units (20 mm)
  // Gaussian sigma (mesh units) of the force blurred in space before it is turned into a
  // displacement (mesh::blurred_in_space); 0: none, the paper's. Bounds the field's gradient in
  // space at any edge length, so a deep breath cannot crumple the surface (docs/realism.md).
  double magnitude_smoothing = 0.0;
  mesh::BodyAxes axes;  // up and anterior, for the anatomical directions
  // The lung sliding along the chest wall (mesh/sliding.h): a tangential field added to the
  // normalised displacement, in units of the diaphragm's mean descent; none by default.
  mesh::Sliding sliding;
  // The lung's face on the heart descends with it (field/heart.h), as far as it looks down onto
  // it, in units of the diaphragm's mean descent, and a face under the diaphragm's slope moves
  // with the surface around it; none by default.
  HeartDescent heart;
  std::vector<double> load;  // per vertex (>= 0, not all 0); empty: 1 everywhere (the paper)
  // The surface's regions in `frame`, when already found (with_tissue finds them once per
  // surface: seconds on a fine one); the anatomical direction finds them itself otherwise.
  std::shared_ptr<const mesh::SurfaceRegions> regions;
  // The surface's proxy (mesh::proxy_for: null where its mean edge is 1.5 mm or more), when
  // already built: the realistic rules that read the surface at several millimetres (the
  // smoothed normals, the thin lung's rays) read it there (#50). compute_field builds it
  // itself for a realistic field otherwise.
  std::shared_ptr<const mesh::SurfaceProxy> proxy;
};
inline const FieldOptions default_field_options{};

struct ElastostaticField {
  std::vector<Eigen::Vector3d> unit_displacement;  // u per vertex, mesh units per area unit
  std::vector<double> force;                       // F per vertex for f = 1 (before normalisation; blurred
                                                   // in space when options.magnitude_smoothing > 0)
  double normalisation = 0.0;  // c: unit_displacement_i = c * force_i * d_i (not the breathing scale s),
                               // plus the slide and the heart's descent when active
  std::uint32_t mass_nodes = 0, spring_nodes = 0;
  SolveReport report;
  double graph_seconds = 0.0;  // building the graph and the solver (report.seconds: solving)
};

// Computes the field. Throws InputError for a bad mesh or modulus (FieldGraph),
// UnsupportedError when a uniform outward load does not increase the area (an inward-facing
// or degenerate mesh) or the solver cannot take the clique size.
ElastostaticField compute_field(const mesh::TriangleMesh& mesh, std::span<const double> shear_modulus_pa,
                                const FieldOptions& options = default_field_options);

// The displacement for one area unit from a per-vertex force (the last step above, exposed
// for the comparators and tests): returns {displacement, scale}.
std::pair<std::vector<Eigen::Vector3d>, double> normalise_displacement(const mesh::TriangleMesh& mesh,
                                                                       std::span<const double> force, double area_unit);
// The same along given unit directions (one per vertex): u_i = c F_i d_i, dA/ds = one area unit.
std::pair<std::vector<Eigen::Vector3d>, double> normalise_displacement(const mesh::TriangleMesh& mesh,
                                                                       std::span<const double> force,
                                                                       std::span<const Eigen::Vector3d> direction,
                                                                       double area_unit);
// The unit direction of every vertex for these options. Throws ValueError when options.regions
// is set but is not of `mesh` in options.axes (mesh::require_regions_of).
std::vector<Eigen::Vector3d> displacement_directions(const mesh::TriangleMesh& mesh, const FieldOptions& options);

}  // namespace pneuma::field
