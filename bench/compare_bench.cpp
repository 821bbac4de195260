// Wall time of the paper's comparison (figure 7's set-up): the proposed Shot/UnShot against
// Witkin's mass-spring with explicit Euler and Hauth's exponential sweeps, on a side x side
// lattice pushed at its centre, tolerance 1e-6. Results go in BENCHMARKS.md, never in tests.
#include <benchmark/benchmark.h>

#include "pneuma/field/field_graph.h"
#include "pneuma/paper/comparators.h"

using namespace pneuma::field;
using namespace pneuma::paper;

namespace {

struct Setup {
  LinkGraph graph;
  std::vector<double> mu, load;
  explicit Setup(std::uint32_t side)
      : graph(square_lattice(side)), mu(graph.vertex_count(), 1e3), load(graph.vertex_count(), 0.0) {
    load[(side / 2) * side + side / 2] = 1.0;
  }
};

void BM_Proposed(benchmark::State& state) {
  const Setup s(static_cast<std::uint32_t>(state.range(0)));
  const FieldGraph fg(link_mesh(s.graph), s.mu);
  const Proposed_Santhanam method(std::make_shared<const TransferOperator>(one_hop_operator(fg)));
  for (auto _ : state) benchmark::DoNotOptimize(method.solve(s.load, ComparatorOptions{}).steps);
}

void BM_MassSpringClamped(benchmark::State& state) {
  const auto side = static_cast<std::uint32_t>(state.range(0));
  const Setup s(side);
  const MassSpring_Witkin method(clamped_network(s.graph, s.mu, lattice_border(side)));
  for (auto _ : state) benchmark::DoNotOptimize(method.solve(s.load, ComparatorOptions{}).steps);
}

void BM_MassSpringMatched(benchmark::State& state) {
  const Setup s(static_cast<std::uint32_t>(state.range(0)));
  const MassSpring_Witkin method(matched_network(FieldGraph(link_mesh(s.graph), s.mu)));
  for (auto _ : state) benchmark::DoNotOptimize(method.solve(s.load, ComparatorOptions{}).steps);
}

void BM_ExponentialHauth(benchmark::State& state) {
  const Setup s(static_cast<std::uint32_t>(state.range(0)));
  const Exponential_Hauth method(s.graph, s.mu);
  for (auto _ : state) benchmark::DoNotOptimize(method.solve(s.load, ComparatorOptions{}).steps);
}

}  // namespace

BENCHMARK(BM_Proposed)->Arg(21)->Arg(41)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_MassSpringClamped)->Arg(21)->Arg(41)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_MassSpringMatched)->Arg(21)->Arg(41)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ExponentialHauth)->Arg(21)->Arg(41)->Unit(benchmark::kMicrosecond);

BENCHMARK_MAIN();
