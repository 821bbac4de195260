#pragma once
// Solvers of the field's fixed point (paper eq. 4.3 - 4.7; METHOD.md section 3).
//
// A load f (one value per node: the applied force on mass nodes, 0 on spring nodes) spreads
// through the transfer operator P (P[k][n] = t(k -> n)). R, the total a node ever shoots,
// satisfies R = f + P^T R, and the field is Shot = t(k -> k) * R. The residual of an estimate
// R is r = f + P^T R - R: exactly Shot/UnShot's UnShot vector. Every solver stops when
//     max_k |r_k| <= tolerance * max_k f_k
// so all of them carry the same error bound, |Shot - Shot*| <= max|r| * max_k (T (I - P^T)^-1 1)_k
// with T = diag(t(k -> k)) (every entry of (I - P^T)^-1 is >= 0).
//
// Each solver does its expensive work (matrix assembly, factorisation) in its constructor
// and answers solve() for any load afterwards. Names follow the method and its source.
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/field/field_graph.h"

namespace pneuma::field {

struct SolveOptions {
  double tolerance = 1e-6;  // on max |residual| / max f
};
inline const SolveOptions default_solve_options{};

struct SolveReport {
  std::string method;
  std::uint64_t shots = 0;       // Shot/UnShot and sweeps: node shots taken
  std::uint64_t iterations = 0;  // sweeps, Krylov iterations (0 for a direct solve)
  double residual = 0.0;         // max |r| / max f at the end
  double seconds = 0.0;          // wall time of solve() (not in any output file: not deterministic)
  OperationCounts counts;        // Shot/UnShot only: additions and multiplications of the shots
};

struct SolveResult {
  std::vector<double> shot;  // per node: F for mass nodes (spring nodes: their own Shot)
  SolveReport report;
};

class FieldSolver {
 public:
  virtual ~FieldSolver() = default;
  virtual std::string name() const = 0;
  // `load` has one value per node, >= 0. Throws ValueError for a wrong size or a
  // negative value, Error(failure) if the iteration limit is reached (it never is for the
  // operators built here, whose shares leave every shot a positive self share).
  virtual SolveResult solve(std::span<const double> load) const = 0;
};

// The paper's Shot/UnShot (eq. 4.5 - 4.7): repeatedly shoot the node with the largest UnShot,
// found with an indexed binary max-heap (increase-key as UnShot grows, removal when shot).
// Works for any clique operator. With count_operations, counts every addition and
// multiplication of the shots (Table 1); off by default because the counters cost time.
class ShotUnshot_Santhanam final : public FieldSolver {
 public:
  explicit ShotUnshot_Santhanam(std::shared_ptr<const TransferOperator> op,
                                const SolveOptions& options = default_solve_options, bool count_operations = false);
  std::string name() const override { return "shot"; }
  SolveResult solve(std::span<const double> load) const override;

 private:
  std::shared_ptr<const TransferOperator> op_;
  SolveOptions options_;
  bool count_;
};

// Gauss-Seidel sweeps: the same shots in node order, sweep after sweep (Shot/UnShot with a
// cyclic instead of a greedy order; identical to Gauss-Seidel on (I - P^T) R = f).
class Sweep_GaussSeidel final : public FieldSolver {
 public:
  explicit Sweep_GaussSeidel(std::shared_ptr<const TransferOperator> op,
                             const SolveOptions& options = default_solve_options);
  std::string name() const override { return "sweep"; }
  SolveResult solve(std::span<const double> load) const override;

 private:
  std::shared_ptr<const TransferOperator> op_;
  SolveOptions options_;
};

// Reference: (I - P^T) R = f with Eigen. Below `lu_node_limit` nodes a sparse LU
// factorisation (exact to rounding; factorised in the constructor), above it BiCGSTAB with a
// diagonal preconditioner, asked for ||r||_2 <= tol * max f (which bounds max |r| the same way).
class Direct_Eigen final : public FieldSolver {
 public:
  static constexpr std::uint32_t default_lu_node_limit = 200'000;
  explicit Direct_Eigen(std::shared_ptr<const TransferOperator> op, const SolveOptions& options = default_solve_options,
                        std::uint32_t lu_node_limit = default_lu_node_limit);
  ~Direct_Eigen() override;
  std::string name() const override { return "direct"; }
  SolveResult solve(std::span<const double> load) const override;

 private:
  struct Impl;
  std::shared_ptr<const TransferOperator> op_;
  SolveOptions options_;
  std::unique_ptr<Impl> impl_;
};

// The fastest correct method found (see BENCHMARKS.md, "Field"), M = 1 only. With y = R / Z the
// fixed point becomes the symmetric system (diag(Z/S) - G) y = f / S, G the symmetric matrix of
// distance factors; it is a nonsingular M-matrix, hence positive definite. The spring nodes
// (no load) are eliminated exactly, leaving a V x V SPD system with the sparsity of the mesh
// (a weighted graph Laplacian plus a positive diagonal), solved by conjugate gradients with a
// Jacobi preconditioner. Parallel (TBB) and bit-identical at any thread count: every row is
// summed in a fixed order, and dot products add fixed blocks in a fixed order.
class ConjugateGradient_Schur final : public FieldSolver {
 public:
  explicit ConjugateGradient_Schur(std::shared_ptr<const FieldGraph> graph,
                                   const SolveOptions& options = default_solve_options);
  ~ConjugateGradient_Schur() override;
  std::string name() const override { return "cg"; }
  // The load of spring nodes must be 0 (they are eliminated); `load` may also hold only the
  // mass_count mass-node values, and the result then holds mass nodes only.
  SolveResult solve(std::span<const double> load) const override;

 private:
  struct Impl;
  SolveOptions options_;
  std::unique_ptr<Impl> impl_;
};

enum class SolverKind { shot, sweep, direct, cg };
// "shot", "sweep", "direct", "cg".
const char* solver_name(SolverKind kind);
// All names, in the order above (for messages and --help).
const std::vector<std::string>& solver_names();
// Throws ValueError for an unknown name.
SolverKind parse_solver_kind(const std::string& name);
// Whether `kind` solves with cliques of `hops` (1 <= hops <= kMaxCliqueHops): cg takes 1 only.
bool solver_takes_clique(SolverKind kind, int hops);

// Builds the solver of `kind` on `graph` with the transfer operator `op` (null: the one-hop
// operator, built here unless `kind` is cg, which works on the graph itself and supports
// M = 1 only: for another `op` it throws UnsupportedError).
std::unique_ptr<FieldSolver> make_field_solver(SolverKind kind, std::shared_ptr<const FieldGraph> graph,
                                               std::shared_ptr<const TransferOperator> op = nullptr,
                                               const SolveOptions& options = default_solve_options);

}  // namespace pneuma::field
