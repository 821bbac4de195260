#pragma once
// The lung's inside: a displacement field on a tetrahedral mesh that equals the surface field on
// the boundary and solves a documented problem inside (METHOD.md, "Interior motion"; #31).
//
// elastic   homogeneous isotropic linear elasticity without body force, P1 tetrahedra:
//           div(sigma) = 0, sigma = lambda tr(eps) I + 2 mu eps, u = g on the boundary. With the
//           boundary prescribed everywhere only Poisson's ratio matters (Young's modulus scales
//           out); the default 0.4 is in the range measured for lung parenchyma (0.3-0.45).
// harmonic  each component harmonic (Laplace, P1): the smoothest extension, for comparison.
// Both reproduce any linear field exactly (a ball whose surface moves by c x moves inside by
// c x), and both are linear in the boundary data, so the field of a unit breath is computed once
// and frame k's interior is s_k * U, like the surface.
//
// Solved by block-Jacobi preconditioned conjugate gradients on the free nodes (the boundary
// eliminated), in parallel over fixed blocks with reductions in block order: the same bits at
// any thread count.
#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "pneuma/mesh/geometry/tet_mesh.h"

namespace pneuma::field {

enum class InteriorModel { elastic, harmonic };

// "elastic", "harmonic"
std::string interior_model_name(InteriorModel model);

struct InteriorOptions {
  InteriorModel model = InteriorModel::elastic;
  double poisson_ratio = 0.4;  // elastic only; in [0, 0.5)
  double tolerance = 1e-10;    // on |K u - f| / |f| (2-norms over the free nodes)
  std::size_t max_iterations = 20000;
  // Where the elastic field folds a tetrahedron by a breath up to this volume above rest (of this
  // lung), its free nodes are moved until no tetrahedron folds (field/untangle.h), and a folded
  // tetrahedron with all four nodes on the surface is left out of the mesh. 0: neither.
  double unfold_volume_m3 = 1e-3;
  // The same for a breath down to this volume below rest (a scan above FRC, model::compile sets it
  // from the breath): tetrahedra that fold as the lung deflates. 0: none.
  double unfold_deflation_m3 = 0.0;
};

struct InteriorReport {
  std::size_t free_nodes = 0, boundary_nodes = 0;
  std::size_t iterations = 0;
  double relative_residual = 0.0;
  // The unfolding (InteriorOptions::unfold_volume_m3): nodes moved, and the tetrahedra with all
  // four nodes on the surface left out because they fold (and their rest volume).
  std::size_t unfolded_nodes = 0, dropped_tets = 0;
  double dropped_volume_m3 = 0.0;
};

struct InteriorSolution {
  std::vector<Eigen::Vector3d> displacement;  // per node of the mesh; the boundary's as given
  InteriorReport report;
};

// `boundary_nodes` (ascending or not, without repeats) take `boundary_displacement` (same
// length). Throws ValueError for sizes that do not match, a node index out of range, a repeated
// boundary node, a Poisson ratio outside [0, 0.5), a degenerate tetrahedron, or no boundary at
// all; Error(failure) when the iteration limit is reached.
InteriorSolution solve_interior(const mesh::TetMesh& mesh, std::span<const std::uint32_t> boundary_nodes,
                                std::span<const Eigen::Vector3d> boundary_displacement,
                                const InteriorOptions& options = {});

// The gradient of a P1 displacement on one tetrahedron (du_a / dx_b at [a][b]): constant on it.
Eigen::Matrix3d tet_displacement_gradient(const mesh::TetMesh& mesh, std::size_t tet,
                                          const std::vector<Eigen::Vector3d>& displacement);

}  // namespace pneuma::field
