// Shot/UnShot, Gauss-Seidel sweeps, Eigen's reference solve, and the solver factory.
// (ConjugateGradient_Schur lives in field_solver_cg.cpp.)
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCore>
#include <Eigen/SparseLU>
#include <algorithm>
#include <chrono>
#include <cmath>

#include "pneuma/core/error.h"
#include "pneuma/core/stopwatch.h"
#include "pneuma/field/field_solver.h"
#include "pneuma/field/shot_unshot_loop.h"

namespace pneuma::field {

namespace detail {

double check_load(std::span<const double> load, std::size_t node_count) {
  if (load.size() != node_count)
    throw ValueError("load: expected " + std::to_string(node_count) + " values, got " + std::to_string(load.size()));
  double max_f = 0.0;
  for (double f : load) {
    if (!(f >= 0.0) || !std::isfinite(f)) throw ValueError("load: expected finite values >= 0");
    max_f = std::max(max_f, f);
  }
  return max_f;
}

}  // namespace detail

namespace {

using detail::check_load;

template <bool Count>
SolveResult shot_unshot(const TransferOperator& op, std::span<const double> load, double tolerance) {
  const auto start = Clock::now();
  const double max_f = check_load(load, op.node_count);
  SolveResult out;
  out.report.method = "shot";
  out.shot.assign(op.node_count, 0.0);
  if (max_f == 0.0) return out;
  const double threshold = tolerance * max_f;
  std::vector<double> unshot(load.begin(), load.end());
  OperationCounts c;
  const std::uint64_t shot_limit = 100'000ULL * std::max<std::uint64_t>(op.node_count, 1);
  const std::uint64_t shots = detail::shoot_until_below<Count>(op, unshot, out.shot, threshold, shot_limit, c,
                                                               [](std::uint64_t, const auto&, const auto&) {});
  double max_unshot = 0.0;
  for (double u : unshot) max_unshot = std::max(max_unshot, u);
  out.report.shots = shots;
  out.report.residual = max_unshot / max_f;
  out.report.counts = c;
  out.report.seconds = seconds_since(start);
  return out;
}

}  // namespace

// ---- Shot/UnShot -----------------------------------------------------------------------------

ShotUnshot_Santhanam::ShotUnshot_Santhanam(std::shared_ptr<const TransferOperator> op, const SolveOptions& options,
                                           bool count_operations)
    : op_(std::move(op)), options_(options), count_(count_operations) {}

SolveResult ShotUnshot_Santhanam::solve(std::span<const double> load) const {
  return count_ ? shot_unshot<true>(*op_, load, options_.tolerance)
                : shot_unshot<false>(*op_, load, options_.tolerance);
}

// ---- Gauss-Seidel sweeps ---------------------------------------------------------------------

Sweep_GaussSeidel::Sweep_GaussSeidel(std::shared_ptr<const TransferOperator> op, const SolveOptions& options)
    : op_(std::move(op)), options_(options) {}

SolveResult Sweep_GaussSeidel::solve(std::span<const double> load) const {
  const auto start = Clock::now();
  const TransferOperator& op = *op_;
  const double max_f = check_load(load, op.node_count);
  SolveResult out;
  out.report.method = "sweep";
  out.shot.assign(op.node_count, 0.0);
  if (max_f == 0.0) return out;
  const double threshold = options_.tolerance * max_f;
  std::vector<double> unshot(load.begin(), load.end());
  double max_unshot = max_f;
  std::uint64_t sweeps = 0, shots = 0;
  while (max_unshot > threshold) {
    if (++sweeps > 100'000) throw Error(ExitCode::failure, "Gauss-Seidel sweeps did not converge");
    for (std::uint32_t k = 0; k < op.node_count; ++k) {
      const double u = unshot[k];
      if (u == 0.0) continue;
      unshot[k] = 0.0;
      out.shot[k] += u * op.self_share[k];
      for (std::uint64_t j = op.offset[k]; j < op.offset[k + 1]; ++j) unshot[op.target[j]] += u * op.share[j];
      ++shots;
    }
    max_unshot = 0.0;
    for (double u : unshot) max_unshot = std::max(max_unshot, u);
  }
  out.report.shots = shots;
  out.report.iterations = sweeps;
  out.report.residual = max_unshot / max_f;
  out.report.seconds = seconds_since(start);
  return out;
}

// ---- Eigen reference -------------------------------------------------------------------------

struct Direct_Eigen::Impl {
  using Matrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;
  Matrix a;  // I - P^T: column k holds 1 at row k and -t(k -> n) at rows n
  std::unique_ptr<Eigen::SparseLU<Matrix, Eigen::COLAMDOrdering<int>>> lu;
  std::unique_ptr<Eigen::BiCGSTAB<Matrix, Eigen::DiagonalPreconditioner<double>>> bicgstab;
};

Direct_Eigen::Direct_Eigen(std::shared_ptr<const TransferOperator> op, const SolveOptions& options,
                           std::uint32_t lu_node_limit)
    : op_(std::move(op)), options_(options), impl_(std::make_unique<Impl>()) {
  const TransferOperator& p = *op_;
  const auto n = static_cast<int>(p.node_count);
  const std::uint64_t nnz = p.entry_count() + p.node_count;
  if (nnz > static_cast<std::uint64_t>(std::numeric_limits<int>::max()))
    throw UnsupportedError("the direct solver handles at most 2^31 matrix entries");
  // The column-major storage of I - P^T is P's CSR with the unit diagonal slotted in: built
  // in place, no triplets. The targets of a row are sorted, as Eigen needs.
  Impl::Matrix& a = impl_->a;
  a.resize(n, n);
  a.resizeNonZeros(static_cast<Eigen::Index>(nnz));
  int* outer = a.outerIndexPtr();
  int* inner = a.innerIndexPtr();
  double* value = a.valuePtr();
  std::uint64_t w = 0;
  for (std::uint32_t k = 0; k < p.node_count; ++k) {
    outer[k] = static_cast<int>(w);
    bool diagonal_done = false;
    for (std::uint64_t j = p.offset[k]; j < p.offset[k + 1]; ++j) {
      if (!diagonal_done && p.target[j] > k) {
        inner[w] = static_cast<int>(k);
        value[w++] = 1.0;
        diagonal_done = true;
      }
      inner[w] = static_cast<int>(p.target[j]);
      value[w++] = -p.share[j];
    }
    if (!diagonal_done) {
      inner[w] = static_cast<int>(k);
      value[w++] = 1.0;
    }
  }
  outer[n] = static_cast<int>(w);
  if (p.node_count <= lu_node_limit) {
    impl_->lu = std::make_unique<Eigen::SparseLU<Impl::Matrix, Eigen::COLAMDOrdering<int>>>();
    impl_->lu->compute(a);
    if (impl_->lu->info() != Eigen::Success) throw Error(ExitCode::failure, "sparse LU factorisation failed");
  } else {
    impl_->bicgstab = std::make_unique<Eigen::BiCGSTAB<Impl::Matrix, Eigen::DiagonalPreconditioner<double>>>();
    impl_->bicgstab->compute(a);
  }
}

Direct_Eigen::~Direct_Eigen() = default;

SolveResult Direct_Eigen::solve(std::span<const double> load) const {
  const auto start = Clock::now();
  const TransferOperator& p = *op_;
  const double max_f = check_load(load, p.node_count);
  SolveResult out;
  out.report.method = "direct";
  out.shot.assign(p.node_count, 0.0);
  if (max_f == 0.0) return out;
  const Eigen::Map<const Eigen::VectorXd> f(load.data(), static_cast<Eigen::Index>(load.size()));
  Eigen::VectorXd r_total;
  double max_residual = 0.0;
  if (impl_->lu) {
    r_total = impl_->lu->solve(f);
    max_residual = (f - impl_->a * r_total).cwiseAbs().maxCoeff();
  } else {
    // ||r||_inf <= ||r||_2 <= tol * max f: Eigen's relative 2-norm tolerance for that.
    const double threshold = options_.tolerance * max_f;
    auto& solver = *impl_->bicgstab;
    solver.setTolerance(threshold / f.norm());
    solver.setMaxIterations(10'000);
    r_total = solver.solve(f);
    max_residual = (f - impl_->a * r_total).cwiseAbs().maxCoeff();
    std::uint64_t iterations = static_cast<std::uint64_t>(solver.iterations());
    // BiCGSTAB's own residual is a recurrence; continue from the answer until the true one meets it.
    for (int restart = 0; restart < 5 && max_residual > threshold; ++restart) {
      r_total = solver.solveWithGuess(f, r_total);
      iterations += static_cast<std::uint64_t>(solver.iterations());
      max_residual = (f - impl_->a * r_total).cwiseAbs().maxCoeff();
    }
    if (max_residual > threshold) throw Error(ExitCode::failure, "BiCGSTAB did not converge");
    out.report.iterations = iterations;
  }
  for (std::uint32_t k = 0; k < p.node_count; ++k) out.shot[k] = p.self_share[k] * r_total[k];
  out.report.residual = max_residual / max_f;
  out.report.seconds = seconds_since(start);
  return out;
}

// ---- Names and the factory -------------------------------------------------------------------

const char* solver_name(SolverKind kind) {
  switch (kind) {
    case SolverKind::shot: return "shot";
    case SolverKind::sweep: return "sweep";
    case SolverKind::direct: return "direct";
    case SolverKind::cg: return "cg";
  }
  return "?";
}

const std::vector<std::string>& solver_names() {
  static const std::vector<std::string> names{"shot", "sweep", "direct", "cg"};
  return names;
}

SolverKind parse_solver_kind(const std::string& name) {
  for (SolverKind k : {SolverKind::shot, SolverKind::sweep, SolverKind::direct, SolverKind::cg}) {
    if (name == solver_name(k)) return k;
  }
  throw ValueError("unknown solver '" + name + "' (expected shot, sweep, direct or cg)");
}

bool solver_takes_clique(SolverKind kind, int hops) {
  return hops >= 1 && hops <= kMaxCliqueHops && (kind != SolverKind::cg || hops == 1);
}

std::unique_ptr<FieldSolver> make_field_solver(SolverKind kind, std::shared_ptr<const FieldGraph> graph,
                                               std::shared_ptr<const TransferOperator> op,
                                               const SolveOptions& options) {
  if (kind == SolverKind::cg) {
    if (op && op->clique_hops != 1)
      throw UnsupportedError("the cg solver needs a clique of 1 hop; use shot, sweep or direct for larger cliques");
    return std::make_unique<ConjugateGradient_Schur>(std::move(graph), options);
  }
  if (!op) op = std::make_shared<const TransferOperator>(one_hop_operator(*graph));
  switch (kind) {
    case SolverKind::shot: return std::make_unique<ShotUnshot_Santhanam>(std::move(op), options);
    case SolverKind::sweep: return std::make_unique<Sweep_GaussSeidel>(std::move(op), options);
    case SolverKind::direct: return std::make_unique<Direct_Eigen>(std::move(op), options);
    case SolverKind::cg: break;
  }
  throw ValueError("unknown solver kind");
}

}  // namespace pneuma::field
