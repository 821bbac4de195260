// Test graphs for the paper's evaluation and the traced Shot/UnShot (Proposed_Santhanam).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>

#include "comparators_internal.h"
#include "pneuma/core/error.h"
#include "pneuma/core/stopwatch.h"
#include "pneuma/paper/comparators.h"

namespace pneuma::paper {

// ---- Test graphs -------------------------------------------------------------------------------

LinkGraph square_lattice(std::uint32_t side) {
  if (side < 2) throw ValueError("lattice side must be at least 2, got " + std::to_string(side));
  LinkGraph g;
  g.positions.reserve(static_cast<std::size_t>(side) * side);
  for (std::uint32_t row = 0; row < side; ++row) {
    for (std::uint32_t col = 0; col < side; ++col)
      g.positions.emplace_back(static_cast<double>(col), static_cast<double>(row), 0.0);
  }
  // Links in (a, b) order: for each vertex its right neighbour (a + 1) comes before its upper
  // one (a + side), so the list is sorted.
  for (std::uint32_t row = 0; row < side; ++row) {
    for (std::uint32_t col = 0; col < side; ++col) {
      const std::uint32_t v = row * side + col;
      if (col + 1 < side) g.links.push_back({v, v + 1});
      if (row + 1 < side) g.links.push_back({v, v + side});
    }
  }
  return g;
}

LinkGraph remove_links(const LinkGraph& graph, double probability, std::uint64_t seed) {
  if (!(probability >= 0.0 && probability <= 1.0)) throw ValueError("link removal probability must lie in [0, 1]");
  std::vector<std::uint32_t> degree(graph.vertex_count(), 0);
  for (const auto& l : graph.links) {
    ++degree[l[0]];
    ++degree[l[1]];
  }
  detail::SplitMix64 random(seed);
  LinkGraph out;
  out.positions = graph.positions;
  for (const auto& l : graph.links) {
    // One draw per link, always, so the draws do not depend on earlier decisions.
    const bool remove = random.uniform() < probability;
    if (remove && degree[l[0]] > 1 && degree[l[1]] > 1) {
      --degree[l[0]];
      --degree[l[1]];
      continue;
    }
    out.links.push_back(l);
  }
  return out;
}

mesh::TriangleMesh link_mesh(const LinkGraph& graph) {
  mesh::TriangleMesh m;
  m.vertices = graph.positions;
  m.triangles.reserve(graph.links.size());
  for (const auto& l : graph.links) m.triangles.push_back({l[0], l[1], l[1]});
  return m;
}

std::vector<std::uint32_t> lattice_border(std::uint32_t side) {
  std::vector<std::uint32_t> out;
  for (std::uint32_t row = 0; row < side; ++row) {
    for (std::uint32_t col = 0; col < side; ++col) {
      if (row == 0 || col == 0 || row + 1 == side || col + 1 == side) out.push_back(row * side + col);
    }
  }
  return out;
}

// ---- Proposed_Santhanam -----------------------------------------------------------------------

Proposed_Santhanam::Proposed_Santhanam(std::shared_ptr<const field::TransferOperator> op) : op_(std::move(op)) {
  if (!op_) throw ValueError("Proposed_Santhanam: no transfer operator");
}

// The production loop of field::ShotUnshot_Santhanam (field::detail::shoot_until_below, one copy), so the
// shots come in the same order and the result is bit-identical; only the trace is added.
ComparatorResult Proposed_Santhanam::solve(std::span<const double> vertex_load, const ComparatorOptions& o) const {
  const auto start = Clock::now();
  const field::TransferOperator& op = *op_;
  const double max_f = field::detail::check_load(vertex_load, op.mass_count);
  ComparatorResult out;
  out.method = name();
  out.displacement.assign(op.mass_count, 0.0);
  if (max_f == 0.0) return out;
  const double threshold = o.tolerance * max_f;
  std::vector<double> unshot(op.node_count, 0.0), shot(op.node_count, 0.0);
  std::copy(vertex_load.begin(), vertex_load.end(), unshot.begin());
  detail::TraceSampler sampler;
  field::OperationCounts c;
  std::uint64_t steps = 0;
  auto record = [&](double residual) {
    const double probe = o.probe_vertex >= 0 ? shot[static_cast<std::size_t>(o.probe_vertex)] : 0.0;
    sampler.record(out.trace, steps, c.additions + c.multiplications, residual / max_f, probe);
  };
  record(max_f);
  // The residual is the largest UnShot: the heap's top, or (once the heap is empty) at most
  // the threshold; the exact value is computed for the last record below.
  steps = field::detail::shoot_until_below<true>(
      op, unshot, shot, threshold, o.step_limit, c,
      [&](std::uint64_t step, const field::detail::IndexedMaxHeap& heap, const std::vector<double>& u) {
        steps = step;
        if (!heap.empty() && sampler.due(step)) record(u[heap.top()]);
      });
  double max_unshot = 0.0;
  for (double u : unshot) max_unshot = std::max(max_unshot, u);
  sampler.force_next();
  record(max_unshot);
  std::copy(shot.begin(), shot.begin() + op.mass_count, out.displacement.begin());
  out.steps = steps;
  out.counts = c;
  out.residual = max_unshot / max_f;
  out.seconds = seconds_since(start);
  return out;
}

}  // namespace pneuma::paper
