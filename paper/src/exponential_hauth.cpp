// Hauth et al.'s exponential precomputation (Exponential_Hauth) and the synchronous cumulative
// summation it uses (CumulativeSweeps).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "comparators_internal.h"
#include "pneuma/core/error.h"
#include "pneuma/paper/comparators.h"

namespace pneuma::paper {

// ---- CumulativeSweeps ---------------------------------------------------------------------------

CumulativeSweeps::CumulativeSweeps(std::shared_ptr<const field::TransferOperator> op, std::string name)
    : op_(std::move(op)), name_(std::move(name)) {
  if (!op_) throw ValueError("CumulativeSweeps: no transfer operator");
}

ComparatorResult CumulativeSweeps::solve(std::span<const double> vertex_load, const ComparatorOptions& o) const {
  const auto start = Clock::now();
  const field::TransferOperator& op = *op_;
  const double max_f = field::detail::check_load(vertex_load, op.mass_count);
  ComparatorResult out;
  out.method = name_;
  out.displacement.assign(op.mass_count, 0.0);
  if (max_f == 0.0) return out;
  std::vector<double> held(op.node_count, 0.0), next(op.node_count, 0.0), shot(op.node_count, 0.0);
  std::copy(vertex_load.begin(), vertex_load.end(), held.begin());
  detail::TraceSampler sampler;
  field::OperationCounts c;
  std::uint64_t steps = 0;
  double residual = 0.0;
  while (true) {
    residual = *std::max_element(held.begin(), held.end()) / max_f;
    const bool done = residual <= o.tolerance;
    if (done) sampler.force_next();
    if (sampler.due(steps)) {
      const double probe = o.probe_vertex >= 0 ? shot[static_cast<std::size_t>(o.probe_vertex)] : 0.0;
      sampler.record(out.trace, steps, c.additions + c.multiplications, residual, probe);
    }
    if (done) break;
    if (steps >= o.step_limit) throw Error(ExitCode::failure, name_ + ": sweeps did not converge");
    std::fill(next.begin(), next.end(), 0.0);
    for (std::uint32_t k = 0; k < op.node_count; ++k) {
      const double u = held[k];
      if (u == 0.0) continue;  // nothing to shoot: no work
      shot[k] += u * op.self_share[k];
      ++c.multiplications;
      ++c.additions;
      for (std::uint64_t j = op.offset[k]; j < op.offset[k + 1]; ++j) next[op.target[j]] += u * op.share[j];
      c.multiplications += op.offset[k + 1] - op.offset[k];
      c.additions += op.offset[k + 1] - op.offset[k];
    }
    held.swap(next);
    ++steps;
  }
  std::copy(shot.begin(), shot.begin() + op.mass_count, out.displacement.begin());
  out.steps = steps;
  out.counts = c;
  out.residual = residual;
  out.seconds = seconds_since(start);
  return out;
}

// ---- Exponential_Hauth ---------------------------------------------------------------------------

namespace {

std::shared_ptr<const field::TransferOperator> exponential_operator(const LinkGraph& graph,
                                                                    std::span<const double> mu) {
  const std::uint32_t v = graph.vertex_count();
  if (mu.size() != v) throw ValueError("exponential: expected one shear modulus per vertex");
  if (graph.links.empty()) throw ValueError("exponential: no links");
  double mean_mu = 0.0, mean_length = 0.0;
  for (double m : mu) {
    if (!(m > 0.0 && std::isfinite(m))) throw ValueError("exponential: shear moduli must be positive");
    mean_mu += m;
  }
  mean_mu /= static_cast<double>(v);
  for (const auto& l : graph.links) mean_length += (graph.positions[l[1]] - graph.positions[l[0]]).norm();
  mean_length /= static_cast<double>(graph.links.size());
  // Neighbours in ascending order (CSR).
  std::vector<std::uint64_t> offset(static_cast<std::size_t>(v) + 1, 0);
  for (const auto& l : graph.links) {
    ++offset[l[0] + 1];
    ++offset[l[1] + 1];
  }
  for (std::uint32_t i = 0; i < v; ++i) offset[i + 1] += offset[i];
  std::vector<std::uint32_t> target(offset.back());
  {
    std::vector<std::uint64_t> fill(offset.begin(), offset.end() - 1);
    for (const auto& l : graph.links) {
      target[fill[l[0]]++] = l[1];
      target[fill[l[1]]++] = l[0];
    }
  }
  auto op = std::make_shared<field::TransferOperator>();
  op->clique_hops = 1;
  op->mass_count = v;
  op->node_count = v;
  op->offset = offset;
  op->target.resize(target.size());
  op->share.resize(target.size());
  op->self_share.resize(v);
  for (std::uint32_t k = 0; k < v; ++k) {
    std::sort(target.begin() + static_cast<std::ptrdiff_t>(offset[k]),
              target.begin() + static_cast<std::ptrdiff_t>(offset[k + 1]));
    double total = 1.0;  // w(k -> k) = exp(0)
    for (std::uint64_t j = offset[k]; j < offset[k + 1]; ++j) {
      const std::uint32_t n = target[j];
      const double distance = (graph.positions[n] - graph.positions[k]).norm() / mean_length;
      op->target[j] = n;
      op->share[j] = std::exp(-distance * (mu[n] / mean_mu));
      total += op->share[j];
    }
    for (std::uint64_t j = offset[k]; j < offset[k + 1]; ++j) op->share[j] /= total;
    op->self_share[k] = 1.0 / total;
  }
  return op;
}

}  // namespace

Exponential_Hauth::Exponential_Hauth(const LinkGraph& graph, std::span<const double> mu)
    : op_(exponential_operator(graph, mu)) {}

ComparatorResult Exponential_Hauth::solve(std::span<const double> load, const ComparatorOptions& o) const {
  ComparatorResult r = CumulativeSweeps(op_, name()).solve(load, o);
  return r;
}

}  // namespace pneuma::paper
