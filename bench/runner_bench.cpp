// Per-frame update of the scenario runner: positions = rest + s * u with V(s) and A(s)
// (model::advance, the fused mesh::DeformedSurface kernel), in vertices per second, against
// memory-bandwidth baselines measured in the same run:
//   copy (BM_CopyRest): std::copy of the rest positions into the frame buffer
//     (24 B read + 24 B written per vertex);
//   copy rest and u (BM_CopyRestAndField): std::copy of the rest positions into the frame buffer
//     and of u into a second buffer of the same size (48 B read + 48 B written per vertex).
// The update reads rest and u and writes positions (48 B read + 24 B written per vertex), between
// the two, as run_scenario does it.
// Meshes: the phantom, both lungs, at edge lengths that give ~100k and ~1M vertices. The field is
// synthetic (the rest normals times 5 mm): the update's cost does not depend on its values, and the
// real field at 1M vertices would cost seconds of set-up per size.
// Argument: 0 = ~100k vertices, 1 = ~1M vertices. Results: BENCHMARKS.md, "Runner".
#include <benchmark/benchmark.h>

#include <algorithm>
#include <map>
#include <memory>
#include <vector>

#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/mesh/geometry/surface_queries.h"
#include "pneuma/model/frame.h"

namespace {

using namespace pneuma;

// Mean edge lengths: 1.30 mm gives 100,844 vertices, 0.411 mm 1,003,704 (both lungs).
constexpr double kEdge[] = {1.30e-3, 0.411e-3};

struct Case {
  model::Model model;
  std::vector<Eigen::Vector3d> positions;
  std::vector<Eigen::Vector3d> scratch;  // the second destination of "copy rest and u"
};

Case& test_case(std::int64_t size) {
  static std::map<std::int64_t, std::unique_ptr<Case>> cases;
  auto& slot = cases[size];
  if (!slot) {
    mesh::TriangleMesh rest =
        mesh::make_lung_phantom({.lung = mesh::kBothLungs, .edge_length_m = kEdge[static_cast<std::size_t>(size)]});
    const std::vector<Eigen::Vector3d> normals = mesh::vertex_normals(rest);
    std::vector<Eigen::Vector3d> u(normals.size());
    for (std::size_t i = 0; i < u.size(); ++i) u[i] = 5e-3 * normals[i];
    slot = std::make_unique<Case>(Case{model::Model(model::make_model(std::move(rest), std::move(u), 1e-4)), {}, {}});
    const std::size_t n = slot->model.vertex_count();
    slot->positions.assign(n, Eigen::Vector3d::Zero());  // touched once, outside the timing
    slot->scratch.assign(n, Eigen::Vector3d::Zero());
  }
  return *slot;
}

void report(benchmark::State& state, const Case& c, double bytes_per_vertex) {
  const auto n = static_cast<std::int64_t>(c.model.vertex_count());
  state.SetItemsProcessed(state.iterations() * n);  // items = vertices
  state.SetBytesProcessed(static_cast<std::int64_t>(static_cast<double>(state.iterations() * n) * bytes_per_vertex));
  state.counters["vertices"] = static_cast<double>(n);
}

void BM_CopyRest(benchmark::State& state) {
  Case& c = test_case(state.range(0));
  for (auto _ : state) {
    std::copy(c.model.lungs[0].rest.vertices.begin(), c.model.lungs[0].rest.vertices.end(), c.positions.begin());
    benchmark::DoNotOptimize(c.positions.data());
    benchmark::ClobberMemory();
  }
  report(state, c, 48.0);
}

void BM_CopyRestAndField(benchmark::State& state) {
  Case& c = test_case(state.range(0));
  for (auto _ : state) {
    std::copy(c.model.lungs[0].rest.vertices.begin(), c.model.lungs[0].rest.vertices.end(), c.positions.begin());
    std::copy(c.model.lungs[0].unit_displacement.begin(), c.model.lungs[0].unit_displacement.end(), c.scratch.begin());
    benchmark::DoNotOptimize(c.positions.data());
    benchmark::DoNotOptimize(c.scratch.data());
    benchmark::ClobberMemory();
  }
  report(state, c, 96.0);
}

// What run_scenario does per frame before the outputs: model::advance (positions, V(s), A(s)).
void BM_FrameUpdate(benchmark::State& state) {
  Case& c = test_case(state.range(0));
  model::Frame frame(c.model);
  double s = 0.5;
  std::size_t k = 0;
  for (auto _ : state) {
    model::advance(c.model, {k++, 0.0, 0.0, {s}}, frame);
    benchmark::DoNotOptimize(frame.lungs[0].area_m2);
    s = s > 1.0 ? 0.5 : s + 1e-3;
  }
  report(state, c, 72.0);
}

double minimum(const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); }

}  // namespace

// Interleaved per size, so a baseline and the update compared with it run close together.
// Medians and minima of 10 repetitions (3 for the whole frame update).
#define PNEUMA_RUNNER_BENCH(fn, size, reps) \
  BENCHMARK(fn)                             \
      ->Arg(size)                           \
      ->Unit(benchmark::kMicrosecond)       \
      ->Repetitions(reps)                   \
      ->ReportAggregatesOnly(true)          \
      ->ComputeStatistics("min", minimum)
PNEUMA_RUNNER_BENCH(BM_CopyRest, 0, 10);
PNEUMA_RUNNER_BENCH(BM_CopyRestAndField, 0, 10);
PNEUMA_RUNNER_BENCH(BM_FrameUpdate, 0, 3);
PNEUMA_RUNNER_BENCH(BM_CopyRest, 1, 10);
PNEUMA_RUNNER_BENCH(BM_CopyRestAndField, 1, 10);
PNEUMA_RUNNER_BENCH(BM_FrameUpdate, 1, 3);

BENCHMARK_MAIN();
