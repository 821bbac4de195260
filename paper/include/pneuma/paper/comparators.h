#pragma once
// The methods the paper compares itself with (section 5; METHOD.md section 7), behind one small
// interface, each named after its source:
//
//   Proposed_Santhanam   the paper's Shot/UnShot (eq. 4.5 - 4.7) on the field's transfer operator,
//                        traced shot by shot (the production field::ShotUnshot_Santhanam, instrumented)
//   MassSpring_Witkin    Witkin's particle system: linear springs, masses, damping, explicit
//                        Euler on (x, v) to steady state, with the step derived from the spectrum
//   Exponential_Hauth    Hauth et al.'s precomputation: the same cumulative summation, but the
//                        transfer to a neighbour falls off as a negative exponential of distance
//                        scaled by the neighbour's Lame (shear) modulus; all nodes at once per step
//
// Every comparator takes one load value per graph vertex (mass node) and returns one scalar
// displacement per vertex (along the push), the steps it took, counted operations, and a
// convergence trace. The test graphs are link graphs: vertices and links (a grid's lines), so
// that links can be removed (figure 2) without caring about triangles.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/field/field_graph.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::paper {

// ---- Test graphs -------------------------------------------------------------------------------

struct LinkGraph {
  std::vector<Eigen::Vector3d> positions;           // metres (any unit: only ratios matter)
  std::vector<std::array<std::uint32_t, 2>> links;  // a < b, sorted, each once
  std::uint32_t vertex_count() const { return static_cast<std::uint32_t>(positions.size()); }
};

// A square lattice of side x side vertices, spacing 1, in the z = 0 plane, numbered row-wise
// (vertex = row * side + column), linked to its 4 lattice neighbours. Throws
// ValueError unless side >= 2.
LinkGraph square_lattice(std::uint32_t side);

// The same graph with each link removed independently with `probability` (paper section 3,
// figure 2), except that a link whose removal would leave one of its ends without any link is
// kept (an isolated vertex is a separate mesh, not a different tessellation). The random
// numbers come from splitmix64 seeded with `seed`, so the result is the same on every platform.
LinkGraph remove_links(const LinkGraph& graph, double probability, std::uint64_t seed);

// The graph as a TriangleMesh that field::FieldGraph accepts: one degenerate triangle {a, b, b} per
// link. field::FieldGraph builds its edges from triangle sides and skips sides whose ends coincide, so
// its edges are exactly the links (tests/compare checks this). Only for the field graph: the
// mesh has no area and no normals.
mesh::TriangleMesh link_mesh(const LinkGraph& graph);

// The vertex on the lattice's border (row or column 0 or side - 1).
std::vector<std::uint32_t> lattice_border(std::uint32_t side);

// ---- The comparator interface -----------------------------------------------------------------

// Convergence, sampled at roughly logarithmically spaced steps (and always at the last step).
struct ConvergenceTrace {
  std::vector<std::uint64_t> step;        // the method's own step: a shot, or one Euler step, or a sweep
  std::vector<std::uint64_t> operations;  // additions + multiplications up to that step
  std::vector<double> residual;           // the method's own residual / max load (see each method)
  std::vector<double> probe;              // the displacement of the probe vertex at that step
};

struct ComparatorOptions {
  double tolerance = 1e-6;                // stop when residual <= tolerance (relative to max load)
  std::int64_t probe_vertex = -1;         // vertex whose displacement the trace follows (-1: none)
  std::uint64_t step_limit = 50'000'000;  // Error(failure) beyond
};
inline const ComparatorOptions default_comparator_options{};

struct ComparatorResult {
  std::string method;
  std::vector<double> displacement;  // per vertex, along the load
  std::uint64_t steps = 0;
  field::OperationCounts counts;
  double residual = 0.0;
  double seconds = 0.0;  // wall time (never written to a file: not deterministic)
  ConvergenceTrace trace;
};

class DeformationComparator {
 public:
  virtual ~DeformationComparator() = default;
  virtual std::string name() const = 0;
  // `load`: one value >= 0 per vertex. Throws ValueError for a wrong size or a
  // negative value, Error(failure) when the step limit is reached.
  virtual ComparatorResult solve(std::span<const double> load,
                                 const ComparatorOptions& options = default_comparator_options) const = 0;
};

// ---- The proposed method, traced ---------------------------------------------------------------

// Shot/UnShot on `op` (built on a field::FieldGraph of the same vertices: mass nodes first). The load
// goes on the mass nodes; displacement is Shot of the mass nodes; residual is max UnShot /
// max load (the production solver's stopping rule, so the result equals field::ShotUnshot_Santhanam's).
// Operations counted exactly as field::ShotUnshot_Santhanam counts them.
class Proposed_Santhanam final : public DeformationComparator {
 public:
  explicit Proposed_Santhanam(std::shared_ptr<const field::TransferOperator> op);
  std::string name() const override { return "proposed"; }
  ComparatorResult solve(std::span<const double> load, const ComparatorOptions& options) const override;

 private:
  std::shared_ptr<const field::TransferOperator> op_;
};

// The same cumulative summation in synchronous (Jacobi) sweeps on any transfer operator: every
// node shoots what it holds at once, Shot += t(k->k) U, U <- P^T U, until max U <= tolerance *
// max load. Steps are sweeps. Used for Hauth's kernel, and for the proposed kernel to tell the
// effect of the transfer function from that of the greedy (largest UnShot first) order.
class CumulativeSweeps final : public DeformationComparator {
 public:
  CumulativeSweeps(std::shared_ptr<const field::TransferOperator> op, std::string name);
  std::string name() const override { return name_; }
  ComparatorResult solve(std::span<const double> load, const ComparatorOptions& options) const override;

 private:
  std::shared_ptr<const field::TransferOperator> op_;
  std::string name_;
};

// ---- Witkin's mass-spring ----------------------------------------------------------------------

// Linear springs between vertices, an optional anchor spring tying each vertex to its rest
// position, and clamped vertices (displacement held at 0). The scalar displacement u along
// the push obeys m u'' = b - K u - c u', with K = the springs' Laplacian + diag(anchor).
// For a flat grid pushed out of its plane this is exactly the out-of-plane part of a
// pretensioned (or zero-rest-length) spring net linearised about its rest shape.
struct SpringNetwork {
  std::uint32_t vertex_count = 0;
  std::vector<std::array<std::uint32_t, 2>> springs;
  std::vector<double> stiffness;      // per spring, > 0
  std::vector<double> anchor;         // per vertex, >= 0
  std::vector<double> mass;           // per vertex, > 0
  std::vector<std::uint8_t> clamped;  // per vertex, 1: held at 0
  // The load applied to vertex i is load_scale[i] * load[i]; the reported displacement is
  // output_scale[i] * u[i]. Both 1 except for the network matched to the field (below).
  std::vector<double> load_scale, output_scale;
};

// An independent physical model: a spring per link with stiffness (m_a + m_b) / 2 / (length /
// mean length) (m = mu / mean mu, as in the field), unit masses, the listed vertices clamped
// (the rim of a membrane pushed at its centre), no anchors.
SpringNetwork clamped_network(const LinkGraph& graph, std::span<const double> shear_modulus,
                              std::span<const std::uint32_t> clamped_vertices);

// The mass-spring with the proposed method's own fixed point: with y = R / Z the field's
// equation R = f + P^T R is symmetric, (diag(Z/S) - G) y = f / S; eliminating the spring nodes
// leaves, on the vertices, springs c_e = g_e^2 S_e / Z_e and anchors Z_i / S_i - 2 sum_{e at i} c_e
// (what the row keeps beyond its springs). The load on vertex i is f_i / S_i. Its steady state times S_i is the
// proposed field F_i exactly, so the two methods can be compared step for step on the same answer. Throws
// UnsupportedError if an anchor would be negative (never for the graphs here).
SpringNetwork matched_network(const field::FieldGraph& graph);

// How the explicit Euler step and the damping were chosen (all rates in 1/s, unit time scale).
struct EulerStepChoice {
  double lambda_min = 0.0, lambda_max = 0.0;  // extreme eigenvalues of M^-1/2 K M^-1/2 (free vertices)
  double gershgorin_max = 0.0;                // Gershgorin bound on lambda_max: max_i sum_j |K_ij| / m_i
  bool exact_spectrum = false;                // dense eigen-decomposition (else power iterations)
  double damping = 0.0;                       // gamma = c / m
  double stable_step = 0.0;                   // the largest stable step for this damping
  double gershgorin_step = 0.0;               // the largest step provably stable from Gershgorin alone
  double step = 0.0;                          // the step used (<= stable_step)
  double contraction = 0.0;                   // spectral radius of one Euler step (< 1)
  double predicted_steps = 0.0;               // ln(tolerance) / ln(contraction)
};

// Witkin, "Physically Based Modeling: Particle System Dynamics" (SIGGRAPH course notes):
// forces accumulated per particle, explicit Euler on the phase-space state (x, v).
// The damping gamma and the step dt are chosen to make the mass-spring converge as fast as it
// can (a fair comparison): explicit Euler is stable iff every mode's |1 + dt s| < 1, which
// gives dt < gamma / lambda for an underdamped mode and dt < 4 / (gamma + sqrt(gamma^2 -
// 4 lambda)) for an overdamped one; gamma and dt minimise the largest |1 + dt s| over the
// spectrum [lambda_min, lambda_max] (a 2-D search; see massspring_witkin.cpp).
// Residual: max_i |b_i - (K u)_i| / max_i |b_i| over free vertices, so the steady state meets
// K u = b to that tolerance. Each Euler step counts its additions and multiplications.
class MassSpring_Witkin final : public DeformationComparator {
 public:
  // `tolerance` only sets predicted_steps. Throws ValueError for an inconsistent network.
  explicit MassSpring_Witkin(SpringNetwork network, double tolerance = default_comparator_options.tolerance);
  std::string name() const override { return "mass-spring"; }
  ComparatorResult solve(std::span<const double> load, const ComparatorOptions& options) const override;
  const EulerStepChoice& step_choice() const { return choice_; }
  const SpringNetwork& network() const { return network_; }

 private:
  SpringNetwork network_;
  EulerStepChoice choice_;
};

// ---- Hauth et al.'s exponential precomputation --------------------------------------------------

// Hauth, Etzmuss, Eberhardt, Klein, Sarlette, Sattler, Dogan, Strasser (2003): the response to
// a force spreads by repeated local transfers whose weights fall off as a negative exponential
// (paper section 2.2: "a negative exponential function of the Lame constants of its
// neighboring elements"). Our reading, on the vertices and links alone (no spring nodes):
//   w(k -> n) = exp(-(d(k, n) / l) * m_n),  l = mean link length,  m = mu / mean mu
//   t(k -> n) = w(k -> n) / (1 + sum_l w(k -> l)),  t(k -> k) = 1 / (1 + sum_l w(k -> l))
// and the cumulative summation runs in Jacobi sweeps: every vertex shoots what it holds at
// once, Shot += t(k->k) U, U <- P^T U, until max U <= tolerance * max load.
// Steps are sweeps; residual is max U / max load.
class Exponential_Hauth final : public DeformationComparator {
 public:
  Exponential_Hauth(const LinkGraph& graph, std::span<const double> shear_modulus);
  std::string name() const override { return "exponential"; }
  ComparatorResult solve(std::span<const double> load, const ComparatorOptions& options) const override;
  // The transfer operator (vertices only), e.g. for field::Direct_Eigen as its exact answer.
  std::shared_ptr<const field::TransferOperator> transfer() const { return op_; }

 private:
  std::shared_ptr<const field::TransferOperator> op_;
};

}  // namespace pneuma::paper
